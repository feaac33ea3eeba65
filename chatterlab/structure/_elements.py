"""Element matrices of the plane RDFEM: Timoshenko beams (DFE), rigid bodies
(RFE), and the kinematics of points on them.

Every coordinate triple in chatterlab is ``(u, v, theta)``: displacement along
global X, along global Y (m) and rotation about Z (rad, counter-clockwise).

The beam is the two-node Timoshenko element with *interdependent
interpolation* (shape functions that solve the homogeneous static Timoshenko
equations exactly), so its stiffness matrix is exact for end-loaded beams and
its consistent mass matrix includes translational and rotary inertia.

References
----------
.. [1] Z. Friedman, J. B. Kosmatka, "An improved two-node Timoshenko beam
   finite element", Computers & Structures 47(3), 473-481, 1993.
.. [2] W. Gawroński, J. Kruszewski, W. Ostachowicz, J. Tarnowski,
   E. Wittbrodt, *Metoda elementów skończonych w dynamice konstrukcji*,
   Arkady, Warszawa 1984 (the RDFEM; cited as [5] in the seed paper).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

__all__ = [
    "beam_local_stiffness",
    "beam_local_mass",
    "beam_shape",
    "beam_rotation",
    "beam_matrices",
    "beam_point_matrix",
    "rigid_point_matrix",
    "rotation3",
]

# 4-point Gauss-Legendre rule on [0, 1]: exact for polynomials of degree 7,
# the mass integrand is at most degree 6.
_GX, _GW = np.polynomial.legendre.leggauss(4)
_GX = 0.5 * (_GX + 1.0)
_GW = 0.5 * _GW


def rotation3(angle: float) -> FloatArray:
    """Matrix R with columns the element axes in global axes, for a plane
    triple (u, v, theta): ``global = R @ local``.  Shape (3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def shear_parameter(E: float, I: float, kappa: float, G: float, A: float, L: float) -> float:
    """phi = 12 E I / (kappa G A L^2), the ratio of shear to bending flexibility."""
    return 12.0 * E * I / (kappa * G * A * L * L)


def beam_shape(xi: FloatArray | float, L: float, phi: float, order: int = 0) -> FloatArray:
    """Transverse-displacement shape functions of the Timoshenko element.

    Parameters
    ----------
    xi : float or array, shape (m,)
        Position along the element as a fraction of its length, 0..1.
    L : float
        Element length, m.
    phi : float
        Shear parameter 12EI/(kappa G A L^2).
    order : {0, 1, 2}
        Derivative order with respect to the *physical* axial coordinate x.

    Returns
    -------
    N : array, shape (m, 4)
        Functions multiplying (v1, theta1, v2, theta2).
    """
    x = np.atleast_1d(np.asarray(xi, dtype=float))
    f = 1.0 / (1.0 + phi)
    if order == 0:
        n1 = f * (2 * x**3 - 3 * x**2 - phi * x + 1 + phi)
        n2 = f * L * (x**3 - (2 + phi / 2) * x**2 + (1 + phi / 2) * x)
        n3 = -f * (2 * x**3 - 3 * x**2 - phi * x)
        n4 = f * L * (x**3 - (1 - phi / 2) * x**2 - (phi / 2) * x)
    elif order == 1:
        n1 = f * (6 * x**2 - 6 * x - phi) / L
        n2 = f * (3 * x**2 - (4 + phi) * x + (1 + phi / 2))
        n3 = -f * (6 * x**2 - 6 * x - phi) / L
        n4 = f * (3 * x**2 - (2 - phi) * x - phi / 2)
    elif order == 2:
        n1 = f * (12 * x - 6) / L**2
        n2 = f * (6 * x - (4 + phi)) / L
        n3 = -f * (12 * x - 6) / L**2
        n4 = f * (6 * x - (2 - phi)) / L
    else:  # pragma: no cover - internal misuse
        raise ValueError("order must be 0, 1 or 2")
    return np.stack([n1, n2, n3, n4], axis=-1)


def beam_rotation(xi: FloatArray | float, L: float, phi: float, order: int = 0) -> FloatArray:
    """Cross-section rotation shape functions (psi), shape (m, 4); ``order``
    is the derivative order with respect to the physical coordinate x."""
    x = np.atleast_1d(np.asarray(xi, dtype=float))
    f = 1.0 / (1.0 + phi)
    if order == 0:
        n1 = 6 * f / L * (x**2 - x)
        n2 = f * (3 * x**2 - (4 + phi) * x + 1 + phi)
        n3 = -6 * f / L * (x**2 - x)
        n4 = f * (3 * x**2 - (2 - phi) * x)
    elif order == 1:
        n1 = 6 * f / L**2 * (2 * x - 1)
        n2 = f * (6 * x - (4 + phi)) / L
        n3 = -6 * f / L**2 * (2 * x - 1)
        n4 = f * (6 * x - (2 - phi)) / L
    elif order == 2:
        n1 = 12 * f / L**3 * np.ones_like(x)
        n2 = 6 * f / L**2 * np.ones_like(x)
        n3 = -12 * f / L**3 * np.ones_like(x)
        n4 = 6 * f / L**2 * np.ones_like(x)
    else:  # pragma: no cover
        raise ValueError("order must be 0, 1 or 2")
    return np.stack([n1, n2, n3, n4], axis=-1)


def beam_local_stiffness(E: float, G: float, A: float, I: float, kappa: float, L: float) -> FloatArray:
    """Local stiffness matrix (6, 6) for (u1, v1, th1, u2, v2, th2).

    Closed form of the interdependent-interpolation element [1]_; exact for a
    beam loaded at its ends.
    """
    phi = shear_parameter(E, I, kappa, G, A, L)
    k = np.zeros((6, 6))
    a = E * A / L
    k[np.ix_([0, 3], [0, 3])] = a * np.array([[1.0, -1.0], [-1.0, 1.0]])
    b = E * I / ((1.0 + phi) * L**3)
    kb = b * np.array(
        [
            [12.0, 6 * L, -12.0, 6 * L],
            [6 * L, (4 + phi) * L**2, -6 * L, (2 - phi) * L**2],
            [-12.0, -6 * L, 12.0, -6 * L],
            [6 * L, (2 - phi) * L**2, -6 * L, (4 + phi) * L**2],
        ]
    )
    idx = [1, 2, 4, 5]
    k[np.ix_(idx, idx)] = kb
    return k


def beam_local_mass(rho: float, A: float, I: float, L: float, phi: float) -> FloatArray:
    """Consistent local mass matrix (6, 6): translational (rho A) and rotary
    (rho I) inertia integrated with the element's own shape functions by a
    Gauss rule that is exact for the polynomial integrands."""
    m = np.zeros((6, 6))
    m[np.ix_([0, 3], [0, 3])] = rho * A * L / 6.0 * np.array([[2.0, 1.0], [1.0, 2.0]])
    Nv = beam_shape(_GX, L, phi)
    Np = beam_rotation(_GX, L, phi)
    mb = rho * A * L * (Nv.T * _GW) @ Nv + rho * I * L * (Np.T * _GW) @ Np
    idx = [1, 2, 4, 5]
    m[np.ix_(idx, idx)] = mb
    return m


def beam_transformation(xy_i: FloatArray, xy_j: FloatArray) -> tuple[float, FloatArray]:
    """Length and (6, 6) transformation T with ``local = T @ global``."""
    d = np.asarray(xy_j, float) - np.asarray(xy_i, float)
    L = float(np.hypot(d[0], d[1]))
    R = rotation3(float(np.arctan2(d[1], d[0])))
    T = np.zeros((6, 6))
    T[:3, :3] = R.T
    T[3:, 3:] = R.T
    return L, T


def beam_matrices(
    xy_i: FloatArray,
    xy_j: FloatArray,
    *,
    E: float,
    G: float,
    A: float,
    I: float,
    kappa: float,
    rho: float,
    eta: float,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Global (M, L, K) of one plane Timoshenko element, each (6, 6).

    The damping matrix models the internal (material) damping of the seed
    paper's Table 2 as Kelvin-Voigt: stress = E strain + eta strain rate, so
    L = (eta / E) K.
    """
    L, T = beam_transformation(xy_i, xy_j)
    phi = shear_parameter(E, I, kappa, G, A, L)
    kl = beam_local_stiffness(E, G, A, I, kappa, L)
    ml = beam_local_mass(rho, A, I, L, phi)
    K = T.T @ kl @ T
    M = T.T @ ml @ T
    return M, (eta / E) * K, K


def beam_point_matrix(
    xy_i: FloatArray,
    xy_j: FloatArray,
    xi: FloatArray | float,
    offset: float,
    *,
    E: float,
    G: float,
    A: float,
    I: float,
    kappa: float,
    order: int = 0,
) -> FloatArray:
    """Map from the element's global nodal coordinates to the global (u, v,
    theta) of a material point of the beam.

    The point lies at fraction ``xi`` of the element length along the axis and
    at transverse distance ``offset`` (m, along the element's local y) from
    it.  It moves with the cross-section: axial displacement
    u(x) - offset * psi(x), transverse v(x), rotation psi(x).

    Parameters
    ----------
    order : {0, 1, 2}
        Derivative of the map with respect to the *distance along the beam*
        (m), for points that travel along the beam.

    Returns
    -------
    P : array, shape (m, 3, 6)
    """
    L, T = beam_transformation(xy_i, xy_j)
    phi = shear_parameter(E, I, kappa, G, A, L)
    x = np.atleast_1d(np.asarray(xi, float))
    Nv = beam_shape(x, L, phi, order)
    Np = beam_rotation(x, L, phi, order)
    m = x.size
    local = np.zeros((m, 3, 6))
    if order == 0:
        local[:, 0, 0] = 1.0 - x
        local[:, 0, 3] = x
    elif order == 1:
        local[:, 0, 0] = -1.0 / L
        local[:, 0, 3] = 1.0 / L
    idx = [1, 2, 4, 5]
    local[:, 0, idx] += -offset * Np
    local[:, 1, idx] = Nv
    local[:, 2, idx] = Np
    R = T[:3, :3].T  # local -> global for a triple
    return np.einsum("ab,mbc,cd->mad", R, local, T)


def rigid_point_matrix(arm: FloatArray) -> FloatArray:
    """Map (3, 3) from a rigid body's (x, y, theta) to the (u, v, theta) of a
    point at global arm ``(ax, ay)`` from its centre (small rotations)."""
    ax, ay = float(arm[0]), float(arm[1])
    return np.array([[1.0, 0.0, -ay], [0.0, 1.0, ax], [0.0, 0.0, 1.0]])
