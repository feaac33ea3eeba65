"""Modal fit (chatterlab.structure.fit_modes): LSCF poles with a
stabilisation diagram, LSFD residues, variable-projection refinement.

Oracles: synthetic receptances of known modes.  Noise-free data are
recovered to round-off; on noisy data the errors are held to a multiple of
the Cramer-Rao bound computed here from the true model and the noise level
(the refinement is the maximum-likelihood estimator for the relative complex
noise used, hence efficient to first order in the noise); the fitted model's
matrices reproduce the real-mode sum exactly.
"""

from __future__ import annotations

import numpy as np
import pytest

from chatterlab.errors import InputError
from chatterlab.structure import assemble, fit_modes

FN = np.array([620.0, 1480.0, 3300.0])  # Hz
ZETA = np.array([0.035, 0.02, 0.03])
K = np.array([2.5e7, 4.0e7, 9.0e7])  # modal stiffness at the driving point, N/m
EPS = np.finfo(float).eps


def modal_sum(w: np.ndarray, fn=FN, zeta=ZETA, k=K) -> np.ndarray:
    """Driving-point receptance sum_r (w_r^2 / k_r) / (w_r^2 - w^2 + 2 j zeta_r w_r w)."""
    wn = 2 * np.pi * np.asarray(fn)
    return np.sum((wn**2 / k) / (wn**2 - w[:, None] ** 2 + 2j * zeta * wn * w[:, None]), axis=1)


def uneven_grid(rng: np.random.Generator, n: int = 900) -> np.ndarray:
    f = np.sort(np.concatenate([np.linspace(100.0, 5000.0, 2 * n // 3), rng.uniform(100.0, 5000.0, n // 3)]))
    return 2 * np.pi * np.unique(f)


def relative_noise(rng: np.random.Generator, shape: tuple[int, ...], sigma: float) -> np.ndarray:
    """Complex Gaussian with E|e|^2 = sigma^2 (sigma^2 / 2 per real component)."""
    return sigma * (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / np.sqrt(2)


def crb(w: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """Cramer-Rao standard deviations of (w_r, zeta_r) for the fitted
    parameterisation (per mode w_r, zeta_r, Re R_r, Im R_r; LR, UR) of the
    driving-point data with relative complex noise of level sigma.

    The weighted residual e_k = (H_meas - H(theta)) / |H| has E|e_k|^2 =
    sigma^2, so the Fisher information is F = (2 / sigma^2) Re sum_k J_k^H J_k
    with J_k = dH(w_k)/dtheta / |H(w_k)| (complex Gaussian errors), and
    cov >= F^-1.  dH/dtheta by central differences (relative step 1e-6: the
    model is analytic, the error O(1e-12) relative)."""
    wn = 2 * np.pi * FN
    lam = -ZETA * wn + 1j * wn * np.sqrt(1 - ZETA**2)
    R = (wn**2 / K) / (2j * lam.imag)  # residues of the true (real) modes
    theta0 = np.concatenate([wn, ZETA, R.real, R.imag, [0.0, 0.0]])
    m = FN.size
    s = 1j * w

    def model(th: np.ndarray) -> np.ndarray:
        om, ze = th[:m], th[m : 2 * m]
        rr = th[2 * m : 3 * m] + 1j * th[3 * m : 4 * m]
        la = -ze * om + 1j * om * np.sqrt(1 - ze**2)
        H = np.sum(rr / (s[:, None] - la) + rr.conj() / (s[:, None] - la.conj()), axis=1)
        return H + th[4 * m] / s**2 + th[4 * m + 1]

    H0 = model(theta0)
    scale = np.concatenate([wn, ZETA, np.abs(R), np.abs(R), [1e3 * wn[0] ** 2 * 1e-9, 1e-9]])
    J = np.empty((w.size, theta0.size), complex)
    for j in range(theta0.size):
        d = np.zeros_like(theta0)
        d[j] = 1e-6 * scale[j]
        J[:, j] = (model(theta0 + d) - model(theta0 - d)) / (2 * d[j])
    J /= np.abs(H0)[:, None]
    F = (2 / sigma**2) * (J.conj().T @ J).real
    sd = np.sqrt(np.diag(np.linalg.inv(F)))
    return sd[:m], sd[m : 2 * m]


def test_noise_free_modal_sum_is_recovered_to_round_off():
    # An exact modal sum on an uneven grid that does not reach 0 Hz: the
    # refinement's weighted residual vanishes at the true parameters and the
    # Levenberg-Marquardt iteration stops when the relative step is < 1e-15,
    # so the poles carry round-off only: the residual's round-off (~eps per
    # point, relative) moves a pole by ~eps / (zeta sqrt(N_half-power)) <
    # 1e-13 relative.  1e-10 leaves three decades for the conditioning of
    # the LSFD solve (column-scaled, condition < 1e3 here).
    rng = np.random.default_rng(3)
    w = uneven_grid(rng)
    fit = fit_modes((w, modal_sum(w)))
    assert fit.n_modes == 3
    np.testing.assert_allclose(fit.frequency_hz, FN, rtol=1e-10)
    np.testing.assert_allclose(fit.damping, ZETA, rtol=1e-10)
    np.testing.assert_allclose(fit.modal_stiffness[:, 0], K, rtol=1e-9)
    assert np.all(np.abs(fit.quality.complexity) < 1e-9)  # real modes stay real
    assert fit.quality.error < 1e-11
    assert np.all(np.abs(fit.lower) < 1e-9 * np.abs(fit.measured.data).max() * w[0] ** 2)
    assert np.all(np.abs(fit.upper) < 1e-9 * np.abs(fit.measured.data).max())


def test_noisy_fit_within_the_cramer_rao_bound():
    # 2 % relative complex noise (a tap test's level).  The estimator is the
    # maximum-likelihood one for this noise (weights 1/|H|), so to first
    # order in sigma it is unbiased with the CRB covariance; a Gaussian
    # estimate exceeds 4.5 standard deviations with probability 7e-6, so
    # with 6 parameters this seeded test fails by chance with p < 5e-5.  A
    # Monte-Carlo run of 200 seeds (z = error / the fit's sd) gave means
    # |z| <= 0.07, standard deviations 0.87-1.04 and max |z| 3.2 (the
    # first-order theory: 0, 1, and ~3.4 expected for 1200 draws).
    sigma = 0.02
    rng = np.random.default_rng(11)
    w = 2 * np.pi * np.linspace(100.0, 5000.0, 1000)
    H = modal_sum(w) * (1 + relative_noise(rng, w.shape, sigma))
    fit = fit_modes((w, H))
    assert fit.n_modes == 3
    sd_w, sd_z = crb(w, sigma)
    err_w = fit.omega_n - 2 * np.pi * FN
    err_z = fit.damping - ZETA
    assert np.all(np.abs(err_w) < 4.5 * sd_w), err_w / sd_w
    assert np.all(np.abs(err_z) < 4.5 * sd_z), err_z / sd_z
    # the fit's own uncertainty is the CRB: same Jacobian to O(sigma) (2 %),
    # residual variance estimated from ~2000 residuals (sampling error
    # 1/sqrt(2000) ~ 2 %, on the std 1 %): 10 % is five times both
    np.testing.assert_allclose(fit.std_omega, sd_w, rtol=0.10)
    np.testing.assert_allclose(fit.std_damping, sd_z, rtol=0.10)
    # the weighted rms error of a correct model is the noise level: the
    # residual has 2N real components and ~ 6 + 8 parameters, so its rms is
    # sigma sqrt(1 - p/2N) to within the sampling error 1/sqrt(2N) ~ 2 %
    assert abs(fit.quality.weighted_error / sigma - 1) < 0.05
    assert np.all(fit.quality.frac > 1 - 2 * sigma**2)  # 1 - FRAC ~ sigma^2 for white noise


def test_the_pole_refinement_matters():
    # Without refinement the z-domain LSCF poles carry a model bias (a
    # continuous-time mode is not rational in exp(j w dt)): on noise-free data
    # their error is far above round-off, and the refinement removes it.
    w = 2 * np.pi * np.linspace(100.0, 5000.0, 800)
    raw = fit_modes((w, modal_sum(w)), refine=False)
    ref = fit_modes((w, modal_sum(w)))
    e_raw = np.max(np.abs(raw.frequency_hz / FN - 1))
    e_ref = np.max(np.abs(ref.frequency_hz / FN - 1))
    assert e_ref < 1e-10 and e_ref < 1e-3 * e_raw, (e_ref, e_raw)


def test_stabilisation_diagram_marks_the_true_poles_stable():
    rng = np.random.default_rng(5)
    w = 2 * np.pi * np.linspace(100.0, 5000.0, 800)
    H = modal_sum(w) * (1 + relative_noise(rng, w.shape, 0.02))
    fit = fit_modes((w, H), max_order=20)
    st = fit.stabilisation
    assert st.orders == tuple(range(1, 21))
    # at the top quarter of the orders each true mode has a pole stable in
    # frequency (1 %) and damping (5 %) within 1 % of it
    for p, lam, s in zip(st.orders, st.poles, st.status, strict=True):
        if p < 15:
            continue
        for f in FN:
            near = np.abs(np.abs(lam) / (2 * np.pi) - f) < 0.01 * f
            assert np.any(near & (s == 2)), (p, f)
    # first order: nothing to compare with, every pole is new
    assert np.all(st.status[0] == 0)


def test_modes_by_frequency_picks_the_named_poles():
    w = 2 * np.pi * np.linspace(100.0, 5000.0, 800)
    fit = fit_modes((w, modal_sum(w)), modes=[1500.0, 3000.0, 600.0])
    np.testing.assert_allclose(fit.frequency_hz, FN, rtol=1e-10)  # as exact as the automatic choice
    with pytest.raises(InputError, match="no pole within 10 %"):
        fit_modes((w, modal_sum(w)), modes=[4500.0])


def matrix_data(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(Phi, H): the shapes and their receptance, (n_out, n_in, n_freq) as an FRF holds it."""
    Phi = np.array([[0.2, 0.1], [0.05, -0.15], [0.1, 0.12]])  # mass-normalised shapes, 1/sqrt(kg)
    wn = 2 * np.pi * FN
    H = np.einsum("ra,rb,kr->abk", Phi, Phi, 1 / (wn**2 - w[:, None] ** 2 + 2j * ZETA * wn * w[:, None]))
    return Phi, H


def test_matrix_fit_recovers_shapes_and_to_model_is_exact():
    from chatterlab.frequency import frf

    w = 2 * np.pi * np.linspace(100.0, 5000.0, 700)
    Phi, H = matrix_data(w)
    fit = fit_modes((w, H), max_order=12)
    np.testing.assert_allclose(fit.frequency_hz, FN, rtol=1e-10)
    # shapes up to sign: |phi_hat . phi| = |phi|^2
    for r in range(3):
        sgn = np.sign(fit.shapes[r] @ Phi[r])
        np.testing.assert_allclose(sgn * fit.shapes[r], Phi[r], rtol=1e-9, atol=1e-12)
    model = fit.to_model(residuals="none")
    assert model.matrices.coordinates == ("1", "2", "fit.q1")  # 3 modes on 2 coordinates: one internal
    fr = assemble(model).at()
    G = frf(fr, w, inputs=["1.x", "2.x"], outputs=["1.x", "2.x"]).data
    # the model's receptance is Psi diag(1/d_r) Psi^T with Psi^T M Psi = I: the
    # real-mode sum exactly, up to the solve's round-off (cond(Z) eps |H|, the
    # dynamic stiffness condition < 1e4 off resonance and ~1/zeta = 50 more at
    # one): 1e-10 of the peak
    ref = fit.frf(w, real_modes=True, residuals=False)
    assert ref.data.shape == G.shape and ref.outputs == ("1", "2")  # the fit's FRF: the one container
    assert np.max(np.abs(G - ref.data)) < 1e-10 * np.abs(H).max()
    assert np.max(np.abs(G - H)) < 1e-9 * np.abs(H).max()


def test_noisy_matrix_fit_within_its_standard_deviations():
    # The poly-reference path on a full 2 x 2 receptance with 2 % relative
    # noise on every entry: the errors within 4.5 of the fit's standard
    # deviations (which the single-entry test checks against the Cramer-Rao
    # bound), and the shapes within their first-order noise: a relative
    # error of ~ sigma / sqrt(N_half-power) per entry, bounded here by 5 %
    # of |phi| (> 10 x that for the ~60 points in each half-power band).
    sigma = 0.02
    rng = np.random.default_rng(23)
    w = 2 * np.pi * np.linspace(100.0, 5000.0, 900)
    Phi, H = matrix_data(w)
    # the noise drawn one frequency after another (the realisation this seeded test was written for)
    Hn = H * (1 + np.moveaxis(relative_noise(rng, (w.size, 2, 2), sigma), 0, -1))
    fit = fit_modes((w, Hn), max_order=12)
    assert fit.n_modes == 3
    assert np.all(np.abs(fit.omega_n - 2 * np.pi * FN) < 4.5 * fit.std_omega)
    assert np.all(np.abs(fit.damping - ZETA) < 4.5 * fit.std_damping)
    for r in range(3):
        sgn = np.sign(fit.shapes[r] @ Phi[r])
        assert np.max(np.abs(sgn * fit.shapes[r] - Phi[r])) < 0.05 * np.abs(Phi[r]).max()
    assert abs(fit.quality.weighted_error / sigma - 1) < 0.05
    # a noise pole at 2140 Hz is stable over the orders by chance; the
    # significance test drops it (its term ~ the noise, the modes' ~ 100x)
    assert "dropped 1 pole(s)" in fit.message
    assert np.all(fit.quality.significance > 20)


def test_fitted_model_poles_are_the_fitted_poles():
    # What to_model is for: every analysis of chatterlab runs on the model.
    # Its complex modes (the eigenvalues the root solver and the lobes use)
    # are the fitted poles and the pseudo-mode's, exactly: M, L, K are
    # diagonalised by Psi with diag(w^2) and diag(2 zeta w), so the
    # eigenvalues are -zeta w +- j w sqrt(1 - zeta^2) up to the
    # eigen-solver's round-off (~eps cond(Psi)^2 relative).
    w = 2 * np.pi * np.linspace(100.0, 5000.0, 700)
    _, H = matrix_data(w)
    fit = fit_modes((w, H), max_order=12)
    fr = assemble(fit.to_model()).at()
    lam = fr.complex_modes.lam
    lam = lam[lam.imag > 0]
    lam = lam[np.argsort(lam.imag)]
    om, ze, _ = fit.real_modes()
    assert om.size == 3  # noise-free modal sum: no residual worth a pseudo-mode
    want = -ze * om + 1j * om * np.sqrt(1 - ze**2)
    np.testing.assert_allclose(lam, want[np.argsort(want.imag)], rtol=1e-9)
    np.testing.assert_allclose(lam, fit.poles, rtol=1e-9)
    # with a residual: the tool-point case of the next test has one pseudo-mode
    H2 = H + 4e-9  # an upper residual of 4e-9 m/N on every entry (rank one: one pseudo-mode)
    fit2 = fit_modes((w, H2), max_order=12)
    lam2 = assemble(fit2.to_model()).at().complex_modes.lam
    lam2 = np.sort(lam2[lam2.imag > 0].imag)
    assert lam2.size == 4
    np.testing.assert_allclose(lam2[:3], fit2.poles.imag, rtol=1e-9)
    np.testing.assert_allclose(lam2[3], 10 * w[-1] * np.sqrt(1 - 0.05**2), rtol=1e-9)


def test_single_coordinate_two_modes_model_with_residual_pseudo_modes():
    # The tap-test case: one driving point, two modes in the band, and the
    # residual terms exactly as the fit models them (LR / s^2 + UR), so the
    # fit is exact and the model's error is the pseudo-modes' alone.
    from chatterlab.frequency import frf

    w = 2 * np.pi * np.linspace(100.0, 2500.0, 800)
    LR, UR = 2.0e-3, 4.0e-9  # 1/kg (a mass of 500 kg below the band), m/N
    H = modal_sum(w, FN[:2], ZETA[:2], K[:2]) + LR / (1j * w) ** 2 + UR
    fit = fit_modes((w, H))
    np.testing.assert_allclose(fit.frequency_hz, FN[:2], rtol=1e-10)
    np.testing.assert_allclose([fit.lower[0, 0], fit.upper[0, 0]], [LR, UR], rtol=1e-8)
    om, ze, Ph = fit.real_modes(residuals="both")
    w_hi, w_lo = 10 * w[-1], w[0] / 10
    np.testing.assert_allclose(om, [*(2 * np.pi * FN[:2]), w_hi, w_lo], rtol=1e-10)
    np.testing.assert_allclose(ze[2:], 0.05)
    model = fit.to_model(name="tap", residuals="both")
    assert model.matrices.coordinates == ("1", "fit.q1", "fit.q2", "fit.q3")
    fr = assemble(model).at()
    G = frf(fr, w, inputs=["1.x"], outputs=["1.x"]).data[0, 0]
    ref = np.sum(Ph[0] ** 2 / (om**2 - w[:, None] ** 2 + 2j * ze * om * w[:, None]), axis=1)
    assert np.max(np.abs(G - ref)) < 1e-10 * np.abs(H).max()  # the matrices: exact (solve round-off)
    # against the data the only difference is the pseudo-modes' own: UR as a
    # mode at w_hi (damping 0.05) is UR / (1 - x^2 + 2j 0.05 x), x = w/w_hi, and
    # LR as a mode at w_lo is -LR/w^2 / (1 - y^2 - 2j 0.05 y) with y = w_lo/w
    x, y = w / w_hi, w_lo / w
    pseudo_err = UR / (1 - x**2 + 2j * 0.05 * x) - UR + (-LR / w**2) / (1 - y**2 - 2j * 0.05 * y) + LR / w**2
    assert np.max(np.abs(G - H - pseudo_err)) < 1e-9 * np.abs(H).max()
    assert np.max(np.abs(pseudo_err)) > 1e4 * 1e-9 * np.abs(H).max()  # so the comparison is not empty
    np.testing.assert_allclose(fit.modal_stiffness[:, 0], K[:2], rtol=1e-9)


def test_bad_input_is_one_line():
    w = 2 * np.pi * np.linspace(100.0, 5000.0, 200)
    H = modal_sum(w)
    cases = [
        ((w[::-1], H), {}, "increase strictly"),
        ((w, H[:-1]), {}, "must have shape"),
        ((w, H), {"band": (0.0, 10.0)}, "at least 8"),
        ((np.concatenate([[0.0], w]), np.concatenate([[0j], H])), {}, "exclude 0 Hz"),
        ((w, H), {"max_order": 0}, "max_order"),
        ((w, H), {"weighting": "log"}, "weighting"),
        ("file.csv", {}, "an FRF or a tuple"),
        ((w, np.ones((w.size, 1, 1))), {}, r"looks like \(n_freq, n_out, n_in\)"),
    ]
    for frf_, kw, msg in cases:
        with pytest.raises(InputError, match=msg) as ei:
            fit_modes(frf_, **kw)
        assert "\n" not in str(ei.value)
    # a cross FRF without a driving point has no shape scale
    fit = fit_modes((w, H[None, None, :]))
    object.__setattr__(fit, "inputs", ("elsewhere",))
    with pytest.raises(InputError, match="driving point"):
        fit.to_model()
