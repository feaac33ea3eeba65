"""Receptance coupling (chatterlab.structure couple / couple_tool /
identify_joint / rotations_from_translations).

The exact oracle: a holder (steel beam clamped at its far end) and a
carbide tool (free-free) joined in one chatterlab model -- rigidly (the
beams share a node) or by a [[spring]] -- against the coupling of the two
substructures' computed receptances.  Then a measured-like noisy holder
(error within the first-order propagation of the noise), joint
identification, and the convergence orders of the finite-difference
rotations.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from chatterlab.errors import InputError
from chatterlab.model import build_model
from chatterlab.structure import (
    FRF,
    Joint,
    assemble,
    couple,
    couple_tool,
    identify_joint,
    receptance,
    rotations_from_translations,
    tool_model,
)

EPS = np.finfo(float).eps
LH, DH = 0.08, 0.04  # holder overhang and diameter, m
LT, DT = 0.06, 0.012  # tool length and diameter, m
KJ, KROT, CJ, CROT = 5.0e7, 2.0e5, 200.0, 5.0  # the joint


def beam(id_, n1, n2, E, rho, nu, d, el, eta=0.0, G=None):
    return {
        "id": id_,
        "nodes": [n1, n2],
        "E": E,
        **({"nu": nu} if G is None else {"G": G}),
        "rho": rho,
        "A": math.pi * d**2 / 4,
        "I": math.pi * d**4 / 64,
        "kappa": 6 * (1 + nu) / (7 + 6 * nu),
        "eta": eta,
        "elements": el,
    }


def holder_beam(extra_nodes=()):
    nodes = [{"id": "h0", "at": [-LH, 0.0]}, {"id": "h1", "at": [0.0, 0.0]}]
    return nodes, [beam("holder", "h0", "h1", 2.1e11, 7850.0, 0.3, DH, 6, eta=2e4)]


def full_model(joint: str):
    nodes, beams = holder_beam()
    tool = beam("tool", "base", "tip", 6.0e11, 14500.0, 0.22, DT, 8)
    if joint == "rigid":
        tool["nodes"] = ["h1", "tip"]
        return build_model(
            {
                "node": [*nodes, {"id": "tip", "at": [LT, 0.0]}],
                "beam": [*beams, tool],
                "support": [{"node": "h0"}],
            }
        )
    return build_model(
        {
            "node": [*nodes, {"id": "base", "at": [0.0, 0.0]}, {"id": "tip", "at": [LT, 0.0]}],
            "beam": [*beams, tool],
            "support": [{"node": "h0"}],
            "spring": [
                {"id": "joint", "a": "h1", "b": "base", "c1": 1e9, "c2": KJ, "c6": KROT, "d2": CJ, "d6": CROT}
            ],
        }
    )


def holder_model():
    nodes, beams = holder_beam()
    return build_model({"node": nodes, "beam": beams, "support": [{"node": "h0"}]})


W = 2 * np.pi * np.linspace(100.0, 8000.0, 500)
SPRING = Joint.spring(KJ, KROT, CJ, CROT)


def stack(structure, outputs, inputs, w):
    """The receptance as one matrix per frequency (n_freq, n_out, n_in): the layout of the algebra below."""
    return receptance(structure, outputs, inputs, w).matrices


def round_off_bound(frozens, w):
    """n eps max cond of the dynamic stiffness matrices solved (the forward
    error of a backward-stable solve is <= n eps cond |x|), per frequency."""
    out = np.zeros(w.size)
    for fr in frozens:
        s = 1j * w
        Z = s[:, None, None] ** 2 * fr.A + s[:, None, None] * fr.B + fr.C
        out = np.maximum(out, fr.n * EPS * np.linalg.cond(Z))
    return out


@pytest.mark.parametrize("joint", ["rigid", "spring"])
def test_coupling_computed_substructures_equals_the_full_model(joint):
    full = assemble(full_model(joint)).at()
    hold = assemble(holder_model()).at()
    tool = assemble(tool_model(LT, DT, E=6.0e11, nu=0.22, rho=14500.0, elements=8)).at()
    G_full = receptance(full, ["tip.y"], ["tip.y"], W).data[0, 0]
    holder = receptance(hold, ["h1.y", "h1.rz"], ["h1.y", "h1.rz"], W)
    HA = holder.matrices
    jt = Joint.rigid(2) if joint == "rigid" else SPRING
    G = couple_tool(holder, tool, joint=jt).data[0, 0]
    # forward error: each receptance to n eps cond(Z) relative; the RCSA
    # combination H_tt - H_tc S^-1 H_ct then errs by that times the size of
    # its terms (and cond(S) once more for the 2x2 solve)
    cpl = ["base.y", "base.rz"]
    Htt = np.abs(receptance(tool, ["tip.y"], ["tip.y"], W).data[0, 0])
    S = stack(tool, cpl, cpl, W) + HA + jt.compliance(W)
    Htc = stack(tool, ["tip.y"], cpl, W)
    corr = np.abs(Htc @ np.linalg.solve(S, np.swapaxes(Htc, 1, 2)))[:, 0, 0]
    kS = np.linalg.cond(S)
    rel = round_off_bound([full, hold, tool], W)
    bound = rel * np.abs(G_full) + (rel + 4 * EPS * kS) * (Htt + corr)
    err = np.abs(G - G_full)
    assert np.all(err <= bound), np.max(err / bound)
    # (a worst-case bound: the normwise cond of a free-free tool's Z is large
    # at low frequency; it amounts to ~2e-5 of |G| here, the error measured is
    # 3e-11 of |G| -- any error in the coupling formula is O(1))


def test_general_coupling_with_three_coordinates_and_all_outputs():
    # couple() over (x, y, rz) with the axial spring: every entry of the
    # assembled matrix (A's and B's coordinates) equals the full model's
    full = assemble(full_model("spring")).at()
    hold = assemble(holder_model()).at()
    tool = assemble(tool_model(LT, DT, E=6.0e11, nu=0.22, rho=14500.0, elements=8)).at()
    a = ["h1.x", "h1.y", "h1.rz"]
    b = ["base.x", "base.y", "base.rz", "tip.y"]
    w = W[::5]
    HA = stack(hold, a, a, w)
    HB = stack(tool, b, b, w)
    jt = Joint((1e9, KJ, KROT), (0.0, CJ, CROT))
    G = couple(HA, HB, [0, 1, 2], [0, 1, 2], jt.compliance(w))
    ref = stack(full, a + b, a + b, w)
    rel = round_off_bound([full, hold, tool], w)
    scale = np.max(np.abs(ref), axis=(1, 2))
    # the same forward-error argument, with cond(S) <= 1e4 on this grid
    assert np.all(np.max(np.abs(G - ref), axis=(1, 2)) <= 1e4 * rel * scale)
    np.testing.assert_allclose(G, np.swapaxes(G, 1, 2), rtol=0, atol=1e-9 * scale.max())  # reciprocity


def test_noisy_holder_error_stays_within_the_propagated_noise():
    # 2 % independent relative complex noise on each holder entry.  To first
    # order dG = H_tc S^-1 dH_A S^-1 H_ct, so the error is complex Gaussian with
    # variance sigma^2 sum_jk |u_j|^2 |H_A,jk|^2 |v_k|^2 (u = H_tc S^-1,
    # v = S^-1 H_ct); P(|dG| > 4.5 sd) = exp(-4.5^2) = 1.6e-9 per frequency.
    # The second-order term is ~ sigma |S^-1 H_A| times the first, so the
    # bound is 4.5 (1 + sigma max|S^-1 H_A|) per frequency.
    sigma = 0.02
    rng = np.random.default_rng(7)
    hold = assemble(holder_model()).at()
    tool = assemble(tool_model(LT, DT, E=6.0e11, nu=0.22, rho=14500.0, elements=8)).at()
    HA = stack(hold, ["h1.y", "h1.rz"], ["h1.y", "h1.rz"], W)
    eps = sigma * (rng.standard_normal(HA.shape) + 1j * rng.standard_normal(HA.shape)) / np.sqrt(2)
    # the holder as arrays (omega, data (n_out, n_in, n_freq)): the tuple form of couple_tool
    G0 = couple_tool((W, np.moveaxis(HA, 0, -1)), tool, joint=SPRING).data[0, 0]
    Gn = couple_tool((W, np.moveaxis(HA * (1 + eps), 0, -1)), tool, joint=SPRING).data[0, 0]
    cpl = ["base.y", "base.rz"]
    S = stack(tool, cpl, cpl, W) + HA + SPRING.compliance(W)
    u = np.linalg.solve(np.swapaxes(S, 1, 2), np.swapaxes(stack(tool, ["tip.y"], cpl, W), 1, 2))[:, :, 0]
    v = np.linalg.solve(S, stack(tool, cpl, ["tip.y"], W))[:, :, 0]
    sd = sigma * np.sqrt(np.einsum("kj,kjl,kl->k", np.abs(u) ** 2, np.abs(HA) ** 2, np.abs(v) ** 2))
    second = np.max(np.abs(np.linalg.solve(S, HA)), axis=(1, 2))
    ratio = np.abs(Gn - G0) / sd
    assert np.all(ratio < 4.5 * (1 + sigma * second)), (ratio.max(), second.max())
    # and the error is really the noise's: its rms over the band is sd's to 20 %
    # (500 samples: sampling error of an rms ~ 1/sqrt(2 x 500) = 3 %)
    assert 0.8 < np.sqrt(np.mean(ratio**2)) < 1.2


def test_joint_identification_recovers_the_joint():
    # the "measured" tool point is the full model's (joint = the spring);
    # starting a factor 3 away, the fit returns the joint to the solver's
    # tolerance on noise-free data, and within 4.5 of its own standard
    # deviations on 1 % noise (the least squares on log(G) is the
    # maximum-likelihood estimator for relative noise, its covariance
    # s^2 (J^T J)^-1)
    full = assemble(full_model("spring")).at()
    hold = assemble(holder_model()).at()
    tool = tool_model(LT, DT, E=6.0e11, nu=0.22, rho=14500.0, elements=8)
    holder = receptance(hold, ["h1.y", "h1.rz"], ["h1.y", "h1.rz"], W).renamed(
        ("h.y", "h.rz"), ("h.y", "h.rz")
    )
    G = receptance(full, ["tip.y"], ["tip.y"], W).data
    start = Joint.spring(3 * KJ, KROT / 3, 2 * CJ, CROT)
    free = ("k", "k_rot", "c")
    fit = identify_joint(
        holder, tool, FRF.from_arrays(W, G, ("tip.y",), ("tip.y",)), initial=start, free=free
    )
    got = np.array([fit.joint.stiffness[0], fit.joint.stiffness[1], fit.joint.damping[0]])
    true = np.array([KJ, KROT, CJ])
    np.testing.assert_allclose(got, true, rtol=1e-6)
    assert fit.joint.damping[1] == CROT  # not free: kept
    rng = np.random.default_rng(2)
    Gn = G * (1 + 0.01 * (rng.standard_normal(G.shape) + 1j * rng.standard_normal(G.shape)) / np.sqrt(2))
    fitn = identify_joint(
        holder, tool, FRF.from_arrays(W, Gn, ("tip.y",), ("tip.y",)), initial=start, free=free
    )
    gotn = np.array([fitn.joint.stiffness[0], fitn.joint.stiffness[1], fitn.joint.damping[0]])
    assert np.all(np.abs(gotn - true) < 4.5 * fitn.std), (gotn - true) / fitn.std
    assert abs(fitn.error / 0.01 - 1) < 0.1  # the residual is the noise


def test_finite_difference_rotations_converge_at_their_orders():
    # Holder end receptances from translations at spacings s, 2s back along
    # the axis; errors against the model's own rotation receptances, at
    # 200 Hz (well below the holder's first mode: smooth deflection).
    # Shear is suppressed (G = 1e8 E): differences of the deflection give its
    # slope psi + gamma and a force couple shears the short segment (a term
    # 1 / (kappa G A s) that grows as s -> 0), so on a Timoshenko holder
    # they converge to the Euler-Bernoulli values, not to the section
    # rotation (the stated limit of the finite-difference route).
    # Orders, from Taylor expansions at the free end (y'' = 0 there under an
    # end force): the cross terms (rotation per force) err by O(s^2) with
    # either stencil; the rotation per moment by O(s) with both, since the
    # force pattern's moment diagram differs from a pure end moment over the
    # stencil (an error ~ s / L of the integral of M / EI); the three-point
    # pattern's constant is half the two-point one (moment diagram 1/2 over
    # 2s against 0 over s).
    w = np.array([2 * np.pi * 200.0])
    errs: dict[int, list[np.ndarray]] = {2: [], 3: []}
    spacings = [0.004, 0.002, 0.001]
    for s in spacings:
        nodes = [
            {"id": "h0", "at": [-LH, 0.0]},
            {"id": "p2", "at": [-2 * s, 0.0]},
            {"id": "p1", "at": [-s, 0.0]},
            {"id": "h1", "at": [0.0, 0.0]},
        ]
        beams = [
            beam("b0", "h0", "p2", 2.1e11, 7850.0, 0.3, DH, 4, G=2.1e19),
            beam("b1", "p2", "p1", 2.1e11, 7850.0, 0.3, DH, 1, G=2.1e19),
            beam("b2", "p1", "h1", 2.1e11, 7850.0, 0.3, DH, 1, G=2.1e19),
        ]
        fr = assemble(build_model({"node": nodes, "beam": beams, "support": [{"node": "h0"}]})).at()
        pts = ["h1.y", "p1.y", "p2.y"]
        Ht = stack(fr, pts, pts, w)
        ex = stack(fr, ["h1.y", "h1.rz"], ["h1.y", "h1.rz"], w)[0]
        for n_p in (2, 3):
            fd = rotations_from_translations(Ht[:, :n_p, :n_p], s)[0]
            errs[n_p].append(np.abs(fd - ex) / np.abs(ex))
            assert fd[0, 0] == ex[0, 0]  # the translation is measured, not differenced
    for n_p in (2, 3):
        e = np.array(errs[n_p])  # (n_s, 2, 2)
        for (i, j), order in (((0, 1), 2), ((1, 0), 2), ((1, 1), 1)):
            slope = np.polyfit(np.log(spacings), np.log(e[:, i, j]), 1)[0]
            assert abs(slope - order) < 0.1, (n_p, i, j, slope)
    ratio = np.array(errs[3])[:, 1, 1] / np.array(errs[2])[:, 1, 1]
    np.testing.assert_allclose(ratio, 0.5, rtol=0.05)  # O(s) relative corrections


def test_bad_input_is_one_line():
    tool = tool_model(LT, DT)
    HA = np.ones((W.size, 2, 2), complex)
    holder = FRF.from_arrays(W, np.ones((2, 2, W.size)), ("h.y", "h.rz"), ("h.y", "h.rz"))
    cases = [
        (lambda: Joint((1e7, -1.0)), "must be >= 0"),
        (lambda: Joint((1e7,), (1.0, 2.0)), "one per coordinate"),
        (lambda: Joint((0.0, 1e5)), "not joined"),
        (lambda: tool_model(-0.1, DT), "length must be > 0"),
        (
            lambda: couple_tool(holder, tool, holder_coords=("h.y", "holder.rz")),
            "no coupling coordinate 'holder.rz'",
        ),
        (lambda: couple_tool(holder, tool, joint=Joint.rigid(3)), "the joint has 3 coordinates"),
        (lambda: couple_tool("holder.csv", tool), "an FRF or a tuple"),
        (lambda: couple_tool((W, HA), tool), r"looks like \(n_freq, n_out, n_in\)"),
        (lambda: rotations_from_translations(HA, 0.0), "spacing must be > 0"),
        (lambda: couple(HA, HA, [0, 1], [0]), "same number"),
        (
            lambda: couple_tool(holder, tool, base="bse"),
            "unknown point 'bse'",
        ),  # a coupling point that does not exist
        (lambda: couple_tool(holder, tool, outputs=("tp.y",)), "unknown point 'tp'"),
        (
            lambda: identify_joint(holder, tool, holder, initial=Joint.spring(1e7, 1e5), free=("k", "mass")),
            "free parameter 'mass'",
        ),
        (
            lambda: identify_joint(holder, tool, holder, initial=Joint.spring(1e7, 1e5), free=("c",)),
            "initial c",
        ),
    ]
    for call, msg in cases:
        with pytest.raises(InputError, match=msg) as ei:
            call()
        assert "\n" not in str(ei.value)
