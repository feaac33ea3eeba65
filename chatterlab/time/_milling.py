"""Milling in the time domain: the Newmark scheme with the rotating cutting
force, the tooth leaving the cut, multiple regeneration and runout.

The structure
-------------
Any matrix-level system ``M q'' + C q' + K q = P^T F`` (n coordinates) with
a 2 x n map ``P`` giving the displacement ``r = (x, y) = P q`` of the tool
relative to the workpiece at the tool point (a 1-DOF, the 2-DOF x/y model, a
modal model, a reduced structural model; or a :class:`FrozenSystem` and the
names of the tool-point coordinates).  ``F`` is the cutting force on the
tool; ``P^T F`` is its generalised force (virtual work).

The cut (:class:`chatterlab.process.Milling`, whose sign convention this
module follows: feed along +x, tooth angle phi measured from +y towards +x,
tooth direction n_j = (sin phi_j, cos phi_j), tangential direction
t_j = (cos phi_j, -sin phi_j))
--------------------------------------------------------------------------
Tooth j carries the forces F_t = K_t a_p h_j + K_te a_p and
F_n = K_n a_p h_j + K_ne a_p, i.e. on the tool

    F = - sum_{j cutting} [ a_p (K_t t_j + K_n n_j) h_j + a_p (K_te t_j + K_ne n_j) ],   (1)

and it cuts when entry < phi_j (mod 2 pi) < exit **and** h_j > 0: a tooth
whose chip would be negative has left the material and carries no force.

Multiple regeneration (the surface a tooth meets).  In the workpiece frame
the material left at the tooth's angle phi is bounded by the innermost of
all previous passes of any tooth at that angle (material is gone wherever
any edge went).  Pass k before the current one (k = 1: the preceding tooth,
k = N: the same tooth one revolution earlier, ...) happened d_jk earlier,
d_jk = (pitch_j + pitch_{j-1} + ... + pitch_{j-k+1}) / Omega, when the tool
centre was v_f d_jk behind in the feed direction (v_f = N f_z Omega / 2 pi the
feed speed, f_z the mean feed per tooth) and displaced by r(t - d_jk); the
radius of the edge that made it was R + rho_{j-k} (runout rho, per tooth).
The chip is therefore the smallest distance to the previous edge positions,

    h_j(t) = min_{k=1..K} [ v_f d_jk sin phi_j + rho_j - rho_{j-k}
                             + n_j . (r(t) - r(t - d_jk)) ],                   (2)

the "minimum over previous passes" of the models with the tool leaving the
cut (Balachandran 2001; Insperger, Mann, Stepan & Bayly 2003, whose
period-doubling solutions are computed with this surface memory; Tlusty &
Ismail 1981, the first time-domain model with the tool leaving the cut).  The arc of the tooth is approximated by a circle about
the current centre (no trochoid), as in those references.  K = 4N
passes (four revolutions) by default; the result reports how often the
deepest pass gave the minimum (a sign that K is too small).

The linearised equation (``nonlinear=False``) drops the feed, the edge
forces, the runout, the leaving of the cut and all passes but the first:

    M q'' + C q' + K q = -a_p P^T sum_j H_j(t) P (q(t) - q(t - tau_j)),          (3)

H_j = g_j (K_t t_j + K_n n_j) n_j^T (:meth:`Milling.directional`), the periodic
delay equation the Floquet methods analyse (Insperger & Stepan 2002, 2004).

The scheme
----------
The run is the Newmark core's (:mod:`chatterlab.time._core`): the cut is
its unilateral coupling (:mod:`._contact`; the teeth are the contacts, the
chip the gap; :mod:`._milling_cut` its data), average acceleration
(gamma = 1/2, beta = 1/4, or the family of ``NewmarkOptions``) on a grid of
``N m`` steps per revolution (``m`` steps per mean tooth period), locked to
the revolution, so the delays of a uniform-pitch cutter fall on the grid
(exact delayed values) and those of a variable-pitch cutter are
interpolated by the core's cubic Hermite interpolation on r and r' (error
O(h^4)).  The force (1) is implicit: with the effective stiffness factored
once per substep length, the new state is a linear map of the previous one
and of F, and the tool point r = r* + Z F with Z the 2 x 2 compliance of
the step; the active teeth and F follow from a 2 x 2 solve, repeated until
the set of teeth with h_j > 0 is consistent (an active-set iteration; it
converges because |Z| ~ beta h^2/m is small).  The screen g_j jumps where a
tooth enters or leaves the arc [entry, exit] (the process's breakpoints):
such instants are substep points of the periodic pattern, with a restart of
the acceleration from the equation of motion with the new screen, so the
scheme stays second order on the piecewise-smooth coefficients (tested:
fitted slope 2).  A tooth that leaves or re-enters the material inside a
step (its active state differs at the two ends) is located by
interpolating h_j linearly to 0, and the step is split there with the old
teeth before and a restart with the new ones after: without edge forces the
force is only kinked there (h_j -> 0), with them it jumps by a_p (K_te,
K_ne), which unlocated would cost one order (tested: slope 2 with runout
and edge forces; without the location the ratio of successive differences
fell to 1.1 in that test).  Cost: a few small matrix-vector products per
step (the delayed values of a whole chunk, up to the shortest delay, are
gathered at once).

Default step (``steps_per_period=None``).  The average-acceleration rule
lengthens the period of a mode of circular frequency w by about
(w h)^2 / 12 (Bathe & Wilson 1976), so (w h)^2/12 <= 1e-3 -- a phase drift
below 2 pi 1e-3 rad per oscillation -- needs w h <= 0.1095, i.e.
m >= w_max tau / 0.1095 with w_max the highest natural frequency of the
structure stiffened by the largest cutting stiffness,
w_max^2 = lambda_max(M^-1 K) + a_p N (K_t^2 + K_n^2)^(1/2) lambda_max(P M^-1 P^T)
(an upper bound); at least 20.

Poincare samples and the verdict
--------------------------------
The tool-point state s_p = (x, y, x'/w_1, y'/w_1) (w_1 the lowest natural
frequency) is sampled once per principal period T of the coefficients (the
tooth period for a uniform pitch without runout, the revolution otherwise).
A forced periodic motion is a fixed point of this map; the differences
d_p = s_{p+1} - s_p then decay like mu^p, mu the critical Floquet multiplier
of the linearised motion.  On the last half of the samples:

* ``growth_per_period``: ln|mu|, mu the dominant eigenvalue of the linear
  map fitted to the delay-embedded deviations (d_p, d_{p+1}) ->
  (d_{p+1}, d_{p+2}) by least squares (Hankel dynamic mode decomposition,
  Schmid 2010; Arbabi & Mezic 2017), each snapshot scaled by its norm,
  singular values below 1e-7 of the largest dropped: exact when the
  deviations are a combination of up to four multipliers (two pairs: the
  x and y modes of a tool); ``growth_error``: its change when fitted to the
  last quarter only; ``growth_slope``: the least-squares slope of ln|d_p|.
* verdict, with D = growth_slope x (number of periods in the window):
  D <= -ln 10 (deviations from the periodic orbit fell tenfold):
  **"stable"**; D >= ln 10 (grew tenfold): **"flip chatter"** when the
  dominant fitted multiplier is real and negative, **"Hopf chatter"** when it
  is complex, "undetermined" when it is real and positive; |D| <= ln 2
  (bounded, neither decaying nor growing: a saturated nonlinear orbit):
  **"stable"** when the differences are below 1e-8 of the samples (a
  converged fixed point); otherwise the chatter frequency f_c -- the
  largest spectral peak of the last half of the vibration farther than two
  resolutions from every harmonic k/T of the forced motion -- decides:
  **"flip chatter"** when f_c is a half harmonic (k + 1/2)/T within two
  resolutions (period doubling: the samples alternate between two points),
  **"Hopf chatter"** otherwise (samples on a closed curve: quasi-periodic);
  "undetermined" without such a peak, and for a linear run there (at the
  limit).  Anything else, or fewer than 20 periods in the window, is
  **"undetermined"** (run longer).  The ratio mean|s_{p+2} - s_p| /
  mean|s_{p+1} - s_p| (0 for an exact period-2 orbit) is reported.

References
----------
.. [1] N. M. Newmark, J. Eng. Mech. Div. ASCE 85(EM3), 67-94, 1959;
   K.-J. Bathe and E. L. Wilson, *Numerical methods in finite element
   analysis*, Prentice Hall 1976 (period error of the trapezoidal rule).
.. [2] B. Balachandran, "Nonlinear dynamics of milling processes",
   Phil. Trans. R. Soc. Lond. A 359 (2001) 793-819 (loss of contact,
   multiple regeneration).
.. [3] T. Insperger, B. P. Mann, G. Stepan, P. V. Bayly, "Stability of
   up-milling and down-milling, part 1: alternative analytical methods",
   Int. J. Mach. Tools Manuf. 43 (2003) 25-34; part 2 (Mann et al.):
   experimental verification, 35-40 (period doubling, the tool leaving the
   cut).
.. [4] T. Insperger, G. Stepan, "Semi-discretization method for delayed
   systems", Int. J. Numer. Meth. Engng 55 (2002) 503-518; "Updated
   semi-discretization method for periodic delay-differential equations
   with discrete delay", 61 (2004) 117-141.
.. [5] Y. Altintas, *Manufacturing Automation*, Cambridge University Press
   2000, ch. 3-4 (the milling force model, runout).
.. [6] P. J. Schmid, "Dynamic mode decomposition of numerical and
   experimental data", J. Fluid Mech. 656 (2010) 5-28; H. Arbabi and
   I. Mezic, "Ergodic theory, dynamic mode decomposition, and computation of
   spectral properties of the Koopman operator", SIAM J. Appl. Dyn. Syst. 16
   (2017) 2096-2126 (the Hankel, delay-embedded variant).
.. [7] J. Tlusty, F. Ismail, "Basic non-linearity in machining chatter",
   Annals of the CIRP 30 (1981) 299-304.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError, check_count, check_nonneg, check_positive, check_speed
from ..model._items import cutting_speed
from ..process._milling import Milling
from ._contact import _Contacts
from ._core import FloatArray, _Stepper, check_options
from ._indentation import ToothFlanks
from ._milling_cut import _MillingCut
from ._milling_result import MillingSimulation, _result
from ._milling_verdict import natural_frequencies
from ._options import Initial, Integration, with_legacy
from ._plan import coupled_plan
from ._simulate import LAND_STEPS

__all__ = ["MillingSimulation", "simulate_milling", "default_steps_per_period"]

#: (w h)^2 / 12 <= 1e-3: the relative period error of the trapezoidal rule
_WH_MAX = math.sqrt(12.0e-3)
#: spindle revolutions of a run when the integration options do not say
DEFAULT_REVOLUTIONS = 50.0


def default_steps_per_period(
    structure: Any,
    milling: Milling,
    rpm: float,
    depth: float,
    *,
    tool_point: Any = None,
    workpiece_point: Any = None,
) -> int:
    """Steps per tooth period m giving a period error (w h)^2/12 <= 1e-3 at the
    highest mode stiffened by the cut (see the module docstring); at least 20."""
    M, _, K, P = _matrices(structure, tool_point, workpiece_point)
    return _default_m(M, K, P, milling, rpm, depth)


# =========================================================================== entry point


def simulate_milling(
    structure: Any,
    milling: Milling,
    rpm: float,
    depth: float,
    *,
    feed: float = 0.0,
    nonlinear: bool = True,
    runout: ArrayLike | None = None,
    passes: int | None = None,
    tool_point: Any = None,
    workpiece_point: Any = None,
    integration: Integration | None = None,
    initial: Initial | None = None,
    C_pd: float | None = None,
    indentation: tuple[float, float, float] | None = None,
    **deprecated: Any,
) -> MillingSimulation:
    """Simulate milling on a structure: vibration, chips, forces, Poincare verdict.

    Parameters
    ----------
    structure : FrozenSystem or (M, C, K)
        The structure: a frozen system (with ``tool_point`` naming the tool
        point's x and y, e.g. ``("tool.x", "tool.y")``, and optionally
        ``workpiece_point``), or mass [kg], damping [N s/m] and stiffness
        [N/m] matrices (n x n) with ``tool_point`` the 2 x n map ``P``,
        ``(x, y) = P q`` (default: ``[[1], [0]]`` for n = 1, the identity for
        n = 2).
    milling : Milling
        Cutter and cut (teeth, pitch, arc, coefficients). Straight teeth only.
    rpm : float
        Spindle speed, rpm.
    depth : float
        Axial depth of cut a_p, m (>= 0).
    feed : float, default 0
        Mean feed per tooth f_z, m (the static chip f_z sin phi).  Only used
        by the nonlinear model.
    nonlinear : bool, default True
        True: Eq. (1)-(2) (feed, edge forces, runout, leaving the cut, multiple
        regeneration).  False: the linear periodic delay equation (3).
    runout : array_like (N,), optional
        Radial offset of each tooth's edge, m (nonlinear model only).
    passes : int, optional
        Previous passes K in Eq. (2); default 4N (four revolutions).
    tool_point, workpiece_point : optional
        See ``structure``.
    integration : Integration, optional
        ``periods``: the duration in spindle revolutions (default 50), or
        ``duration`` in s; ``steps_per_period``: steps m per (mean) tooth
        period, ``N m`` per revolution (default :func:`default_steps_per_period`:
        period error <= 1e-3 at the highest mode); ``scheme``: gamma, beta
        and the divergence limit (|q| beyond it stops the run).
    initial : Initial, optional
        ``q0``, ``v0`` (n,); history zero before t = 0.  Default zero, except
        in a linear run: a 1 µm tool-point displacement in x and y
        (q0 = P^+ (1, 1) µm).
    C_pd : float, optional
        Process damping, N/m (the linear model, docs/process-damping.md Eq.
        4a): each tooth in the cut rubs along its radial direction n_j, the
        tool feeling ``-a_p (C_pd / V) sum_j n_j n_j^T r'``, V the cutting
        speed at the cutter's diameter (``chatterlab.model._items.cutting_speed``).
        None: the ``[process_damping]`` of a FrozenSystem's model (its
        linear C_pd, or its indentation model), else 0.
    indentation : (K_sp, wear_land, clearance), optional
        The indentation model of process damping instead (N/m^3, m, rad;
        docs/process-damping.md Eq. 6a): each tooth in the cut pushes
        ``-K_sp a_p A_j n_j``, A_j the area of material under its flank, the
        penetration ``n_j . r`` and the surface behind the edge the tool's
        path ``n_j . r(t - xi / V)`` (:class:`._indentation.ToothFlanks`).
        The default step puts ``LAND_STEPS`` = 8 steps across the wear land
        (h <= w / (8 V)); a given ``steps_per_period`` must leave 2.  Not
        with ``C_pd``.
    **deprecated
        The 0.2 keywords ``revolutions``, ``steps_per_period``, ``q0``,
        ``v0``, ``options`` (a DeprecationWarning names their place in the
        option objects).

    Returns
    -------
    MillingSimulation

    Raises
    ------
    InputError
        One line naming the argument: non-positive speed, negative depth,
        steps per period not a whole number >= 1, runout of the wrong length,
        a helix angle, bad matrices.

    References
    ----------
    Balachandran (2001); Insperger, Mann, Stepan & Bayly (2003); Insperger &
    Stepan (2002, 2004); Newmark (1959): see the module docstring.
    """
    wall0 = time.perf_counter()
    legacy = ("revolutions", "steps_per_period", "q0", "v0", "options")
    opt = with_legacy("simulate_milling", deprecated, legacy, integration=integration, initial=initial)
    integ, init = opt["integration"], opt["initial"]
    rpm, depth, feed, opts = _checked_cut(milling, rpm, depth, feed, integ)
    rubbing, flanks = _process_damping(
        C_pd, indentation, getattr(structure, "model", None), milling, rpm, depth
    )
    M, C, K, P = _matrices(structure, tool_point, workpiece_point)
    n = M.shape[0]
    if init.history is not None:
        raise InputError(
            "initial.history: a milling run starts on the nominal path (zero history); leave it None"
        )
    try:
        np.linalg.inv(M)
    except np.linalg.LinAlgError:
        raise InputError("structure: the mass matrix M is singular; give a nonsingular M") from None
    m = (
        integ.steps_per_period
        if integ.steps_per_period is not None
        else _default_m(M, K, P, milling, rpm, depth)
    )
    if flanks is not None:
        tau = milling.tooth_period(rpm)
        if integ.steps_per_period is None:
            m = max(m, flanks.steps_per_period(tau, LAND_STEPS))
        else:
            flanks.check_steps(tau, m, "integration.steps_per_period")
    rho, K_pass = _teeth(milling.teeth, runout, passes, nonlinear)
    q_init, v_init = _initial_state(P, n, init.q0, init.v0, nonlinear)
    cut = _MillingCut(milling, rpm, depth, feed, rho, K_pass, nonlinear, m)
    revolutions, n_total = _length(cut, integ, opts)
    contacts = _Contacts(cut, (M, C, K, P), cut.h, opts, n_total, rubbing, flanks)
    a0 = contacts.start(q_init, v_init)
    stepper = _Stepper(
        coupled_plan((M, C, K), contacts, opts, (cut.h, n_total, cut.chunk), (q_init, v_init, a0))
    )
    status, reason, done = stepper.run(integ.progress, None)
    periodic_tooth = milling.uniform and (not np.any(rho) or not nonlinear)
    if flanks is not None:
        damping = flanks.describe()
    elif rubbing:
        damping = f"linear, C_pd = {rubbing * cutting_speed(rpm, milling.diameter) / depth:.6g} N/m"
    else:
        damping = "none"
    run = _MillingRun(
        milling, rpm, depth, feed, nonlinear, m, revolutions, n_total, cut.n_rev if not periodic_tooth else m,
        damping,
    )  # fmt: skip
    return _result(run, contacts, status, reason, done, time.perf_counter() - wall0)


@dataclass(frozen=True)
class _MillingRun:
    """What a milling run was asked: the cut, the grid and its length
    (``per_sample``: steps between Poincare samples)."""

    milling: Milling
    rpm: float
    depth: float
    feed: float
    nonlinear: bool
    steps_per_period: int
    revolutions: float
    n_total: int
    per_sample: int
    process_damping: str = "none"


def _length(cut: _MillingCut, integ: Integration, opts: Any) -> tuple[float, int]:
    """(revolutions, steps of the run), the run's memory checked."""
    if integ.duration is not None:
        n_total = int(round(integ.duration / cut.h))
        revolutions = n_total / cut.n_rev
    else:
        revolutions = float(integ.periods if integ.periods is not None else DEFAULT_REVOLUTIONS)
        n_total = int(round(revolutions * cut.n_rev))
    if n_total < 1:
        raise InputError(f"the run is shorter than one step ({revolutions:g} revolutions); simulate longer")
    N = cut.teeth
    need = 8 * (n_total + 1) * (8 + 2 * N)  # history, forces, chips and the result's copies
    if need > opts.max_output_bytes:
        raise InputError(
            f"revolutions = {revolutions:g} at {cut.n_rev // N} steps per tooth period needs ~{need / 2**30:.3g}"
            f" GiB (limit options.max_output_bytes = {opts.max_output_bytes / 2**30:.3g} GiB); "
            "simulate fewer revolutions or steps"
        )
    return revolutions, n_total


def _checked_cut(
    milling: Milling, rpm: float, depth: float, feed: float, integ: Integration
) -> tuple[float, float, float, Any]:
    """The cut's arguments of :func:`simulate_milling` checked: (rpm, depth, feed, NewmarkOptions)."""
    if not isinstance(milling, Milling):
        raise InputError(f"milling must be a chatterlab Milling (got {type(milling).__name__})")
    if milling.helix != 0.0:
        raise InputError(
            "simulate_milling: helical teeth are not modelled in the time domain (straight teeth only); "
            "set helix = 0"
        )
    rpm = check_speed(rpm, "spindle speed rpm", "rpm")
    depth = check_nonneg(depth, "depth of cut a_p", "m")
    feed = check_nonneg(feed, "feed per tooth f_z", "m")
    return rpm, depth, feed, check_options(integ.scheme)


def _teeth(N: int, runout: ArrayLike | None, passes: int | None, nonlinear: bool) -> tuple[FloatArray, int]:
    """The runout of each tooth (zero in a linear run) and the passes K in the chip (1 in a linear run)."""
    rho = np.zeros(N)
    if runout is not None:
        rho = np.asarray(runout, dtype=float).reshape(-1)
        if rho.size != N or not np.all(np.isfinite(rho)):
            raise InputError(
                f"runout must give one finite radial offset per tooth, {N} values in m (got {rho.size})"
            )
        if not nonlinear:
            rho = np.zeros(N)
    K_pass = 4 * N
    if passes is not None:
        K_pass = check_count(passes, "passes (previous passes in the chip)")
    if not nonlinear:
        K_pass = 1
    return rho, K_pass


def _initial_state(
    P: Any, n: int, q0: ArrayLike | None, v0: ArrayLike | None, nonlinear: bool
) -> tuple[Any, Any]:
    """(q0, v0): zero by default, a 1 µm tool-point displacement in a linear run."""
    if q0 is None and not nonlinear:
        q0 = np.linalg.pinv(P) @ np.array([1e-6, 1e-6])
    q_init = np.zeros(n) if q0 is None else np.asarray(q0, dtype=float).reshape(-1)
    v_init = np.zeros(n) if v0 is None else np.asarray(v0, dtype=float).reshape(-1)
    for name, a in (("q0", q_init), ("v0", v_init)):
        if a.shape != (n,) or not np.all(np.isfinite(a)):
            raise InputError(f"{name} must be a finite vector of {n} values (got shape {a.shape})")
    return q_init, v_init


def model_indentation(model: Any) -> tuple[float, float, float] | None:
    """The ``indentation`` argument of :func:`simulate_milling` from a
    model's ``[process_damping]`` (K_sp, wear_land, clearance), or None
    when the table is absent or gives the linear C_pd."""
    pd = getattr(model, "process_damping", None)
    if pd is None or not pd.indentation:
        return None
    return float(pd.K_sp), float(pd.wear_land), float(pd.clearance)


def _process_damping(
    C_pd: float | None,
    indentation: tuple[float, float, float] | None,
    model: Any,
    milling: Milling,
    rpm: float,
    depth: float,
) -> tuple[float, ToothFlanks | None]:
    """(the rubbing teeth's damping a_p C_pd / V along each tooth's radial
    direction, N s/m, 0: none; the indentation model's flanks or None):
    ``C_pd`` or ``indentation`` given, or the model's table."""
    if C_pd is not None and indentation is not None:
        raise InputError(
            "C_pd and indentation: give one process-damping model, the linear or the indentation"
        )
    if C_pd is None and indentation is None:
        indentation = model_indentation(model)
        if indentation is None:
            pd = getattr(model, "process_damping", None)
            C_pd = 0.0 if pd is None else float(pd.C_pd)
    if indentation is not None:
        try:
            K_sp, w, clearance = (float(x) for x in indentation)
        except (TypeError, ValueError):
            raise InputError("indentation: give (K_sp N/m^3, wear_land m, clearance rad)") from None
        K_sp = check_nonneg(K_sp, "indentation K_sp", "N/m^3")
        w = check_positive(w, "indentation wear_land", "m")
        if not 0.0 < clearance < math.pi / 2:
            raise InputError(f"indentation clearance: must lie in (0, pi/2) rad (got {clearance!r})")
        V = _speed(milling, rpm, "indentation")
        return 0.0, ToothFlanks(float(depth), V, K_sp, w, clearance)
    C_pd = check_nonneg(C_pd, "C_pd", "N/m")
    if C_pd == 0.0:
        return 0.0, None
    return float(depth) * C_pd / _speed(milling, rpm, "C_pd"), None


def _speed(milling: Milling, rpm: float, name: str) -> float:
    """The cutting speed at the cutter's diameter, m/s."""
    if not (math.isfinite(milling.diameter) and milling.diameter > 0):
        raise InputError(f"{name}: the cutting speed needs the cutter's diameter (Milling.diameter, m)")
    return float(cutting_speed(float(rpm), float(milling.diameter)))


# =========================================================================== structure


def _matrices(
    structure: Any, tool_point: Any, workpiece_point: Any
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """(M, C, K, P) from a FrozenSystem (+ names) or a (M, C, K) tuple (+ P)."""
    if hasattr(structure, "dof") and hasattr(structure, "A"):
        M, C, K = (np.asarray(getattr(structure, a), dtype=float) for a in "ABC")
        if tool_point is None or isinstance(tool_point, str) or len(tool_point) != 2:
            raise InputError(
                "simulate_milling on a FrozenSystem: give tool_point=('tool.x', 'tool.y'), the names of "
                "the tool point's x and y (feed along x)"
            )
        P = np.array([structure.dof(str(s)) for s in tool_point], dtype=float)
        if workpiece_point is not None:
            if isinstance(workpiece_point, str) or len(workpiece_point) != 2:
                raise InputError("workpiece_point must name two coordinates, e.g. ('part.x', 'part.y')")
            P = P - np.array([structure.dof(str(s)) for s in workpiece_point], dtype=float)
        return M, C, K, P
    try:
        M, C, K = (np.asarray(a, dtype=float) for a in structure)
    except (TypeError, ValueError):
        raise InputError(
            "structure must be a FrozenSystem or a tuple (M, C, K) of n x n mass, damping and stiffness "
            "matrices"
        ) from None
    M, C, K = (np.atleast_2d(a) for a in (M, C, K))
    n = M.shape[0]
    for name, a in (("M", M), ("C", C), ("K", K)):
        if a.shape != (n, n) or not np.all(np.isfinite(a)):
            raise InputError(
                f"structure {name} must be a finite {n} x {n} matrix like M (got shape {a.shape})"
            )
    if tool_point is None:
        if n > 2:
            raise InputError(
                f"structure has {n} coordinates: give tool_point, the 2 x {n} map P with (x, y) = P q"
            )
        P = np.eye(2)[:, :n]
    else:
        P = np.asarray(tool_point, dtype=float)
        if P.ndim == 1 and n == 1 and P.size == 2:
            P = P.reshape(2, 1)
        if P.shape != (2, n) or not np.all(np.isfinite(P)):
            raise InputError(
                f"tool_point must be a finite 2 x {n} matrix P with (x, y) = P q (got shape {P.shape})"
            )
    return M, C, K, P


def _default_m(
    M: FloatArray, K: FloatArray, P: FloatArray, milling: Milling, rpm: float, depth: float
) -> int:
    w2 = float(np.max(natural_frequencies(M, K))) ** 2
    comp = float(np.max(np.linalg.eigvalsh(P @ np.linalg.solve(M, P.T))))
    w2 += depth * milling.teeth * math.hypot(milling.Kt, milling.Kn) * comp
    tau = milling.tooth_period(rpm)
    return max(20, int(math.ceil(math.sqrt(w2) * tau / _WH_MAX)))
