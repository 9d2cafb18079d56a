"""Ramezani protocols end to end through the kernel: anchors ping, targets measure ToFs from
real packets (the channel's ray-traced delay) and localize / track.

References (independent of the protocol's code path): the CRB of the fix computed here from
the closed-form isogradient gradient at the true position, and the statistics of many fixes.
A wrong delay model (straight rays, a wrong profile) leaves the RMSE far above the CRB at a
small sigma_t, so these tests fail when the model is wrong.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from aquasim_protocols.ramezani import RamezaniNode
from aquasim_protocols.ramezani.math import PAPER_A, PAPER_B, TETRAHEDRON, fix_crb
from aquasim_py import scenario

SCEN = Path(__file__).resolve().parents[2] / "scenarios"


def run(name: str, *overrides: str):
    sc = scenario.load(SCEN / name, overrides=list(overrides))
    sim = scenario.build(sc)
    sim.run(sc.simulation.duration_s)
    return sim.trace.frames()


def sigma(s: float) -> list[str]:
    return [f"nodes.{i}.params.sigma_t_s={s!r}" for i in (1, 2)]


def errors(frames, model: str) -> np.ndarray:
    e = frames["estimates"]
    e = e[e["model"] == model]
    return e[["x", "y", "z"]].to_numpy(float) - e[["true_x", "true_y", "true_z"]].to_numpy(float)


def test_localization_on_crb_at_small_noise() -> None:
    # 0.01 ms: the CRB is ~2 cm, ten times below the straight-ray model error
    frames = run("ramezani_localization.toml", *sigma(1e-5), "simulation.duration_s=300.0")
    target = frames["estimates"][["true_x", "true_y", "true_z"]].to_numpy(float)[0]
    crb = float(fix_crb(TETRAHEDRON, target, PAPER_B, PAPER_A, 1e-5))
    ee, ea = errors(frames, "essp"), errors(frames, "assp")
    assert len(ee) == len(ea) == 150  # one fix per 2 s frame, no ping lost
    rmse_e = np.sqrt(np.mean(np.sum(ee**2, axis=1)))
    rmse_a = np.sqrt(np.mean(np.sum(ea**2, axis=1)))
    # 150 fixes in 3-D: the RMSE has a relative std of about 3 %; 15 % is ~5 sigma
    assert rmse_e == pytest.approx(np.sqrt(crb), rel=0.15)
    # unbiased: the mean error is within 4 standard errors of zero on every axis
    assert np.all(np.abs(ee.mean(axis=0)) < 4 * ee.std(axis=0) / np.sqrt(len(ee)))
    assert rmse_a > 5 * rmse_e
    m = RamezaniNode.metrics(frames)
    assert m["localization_essp.sqrt_mean_crb_m"] == pytest.approx(np.sqrt(crb), rel=1e-9)
    assert m["localization_essp.rmse_m"] == pytest.approx(rmse_e, rel=1e-12)


def test_localization_large_noise_both_on_crb() -> None:
    # 1 ms: noise dominates, ESSP and ASSP both sit at the bound (Fig. 4, right end)
    frames = run("ramezani_localization.toml", *sigma(1e-3), "simulation.duration_s=300.0")
    m = RamezaniNode.metrics(frames)
    assert m["localization_essp.rmse_over_bound"] == pytest.approx(1.0, abs=0.15)
    assert m["localization_assp.rmse_over_bound"] == pytest.approx(1.0, abs=0.15)


def test_localization_uses_its_own_profile_not_the_environment() -> None:
    # the node believes a = 0.05 while the water has a = 0.1: ESSP loses its advantage
    frames = run(
        "ramezani_localization.toml", *sigma(1e-5), "simulation.duration_s=100.0", "nodes.1.params.gradient_per_s=0.05"
    )
    m = RamezaniNode.metrics(frames)
    assert m["localization_essp.rmse_over_bound"] > 3.0


def test_localization_with_depth_gauge() -> None:
    # eq 37: the depth row tightens z; the CRB with the row is what the fixes reach
    frames = run(
        "ramezani_localization.toml",
        *sigma(1e-3),
        "simulation.duration_s=300.0",
        "nodes.1.params.use_depth=true",
        "nodes.1.params.sigma_z_m=0.5",
        "nodes.1.sensors.depth_noise_std_m=0.5",
    )
    m = RamezaniNode.metrics(frames)
    target = frames["estimates"][["true_x", "true_y", "true_z"]].to_numpy(float)[0]
    with_z = float(fix_crb(TETRAHEDRON, target, PAPER_B, PAPER_A, 1e-3, 0.5))
    without = float(fix_crb(TETRAHEDRON, target, PAPER_B, PAPER_A, 1e-3))
    assert with_z < 0.8 * without
    assert m["localization_essp.sqrt_mean_crb_m"] == pytest.approx(np.sqrt(with_z), rel=1e-9)
    assert m["localization_essp.rmse_over_bound"] == pytest.approx(1.0, abs=0.15)


def test_tracking_short_run() -> None:
    frames = run(
        "ramezani_tracking.toml",
        "simulation.duration_s=995.0",
        *[f"nodes.{i}.params.rmse_from_step=50" for i in (1, 2)],
    )
    e = frames["estimates"]
    for model in ("essp", "assp"):
        g = e[e["model"] == model].sort_values("step")
        assert g["step"].tolist() == list(range(1, 101))
        assert g["depth_used"].tolist() == [k % 10 == 0 for k in range(1, 101)]
    m = RamezaniNode.metrics(frames)
    # from 30 m off on every axis (52 m) the EKF-ESSP converges to the bound's scale
    assert e[e["model"] == "essp"]["error"].iloc[0] < 60.0
    assert m["tracking_essp.rmse_over_bound"] < 2.0
    assert np.isfinite(m["tracking_assp.rmse_m"])
    assert m["tracking_essp.estimates"] == 51


def test_tracking_from_first_fix_without_depth(tmp_path: Path) -> None:
    # no operator guess: the first frame's GN fix is the prior; rho = 0: ToFs only
    text = (SCEN / "ramezani_tracking.toml").read_text().replace("initial_guess = [530.0, 80.0, 80.0], ", "")
    assert "initial_guess" not in text
    p = tmp_path / "t.toml"
    p.write_text(text)
    sc = scenario.load(
        p,
        overrides=[
            "simulation.duration_s=505.0",
            "nodes.1.params.rho=0",
            "nodes.1.params.rmse_from_step=20",
            "nodes.2.params.rmse_from_step=20",
        ],
    )
    sim = scenario.build(sc)
    sim.run(sc.simulation.duration_s)
    frames = sim.trace.frames()
    e = frames["estimates"]
    g = e[e["model"] == "essp"].sort_values("step")
    assert g["step"].tolist() == list(range(1, 51))  # frame 0 became the prior
    assert not g["depth_used"].any()
    m = RamezaniNode.metrics(frames)
    assert m["tracking_essp.rmse_over_bound"] < 2.0


# --------------------------------------------------------------------------- pure maths
@pytest.mark.parametrize("a", [0.1, 0.017, -0.05, 0.0, 1e-9])
def test_continued_model_equals_channel_in_water(a: float) -> None:
    from aquasim_protocols.ramezani.math import essp_model

    rng = np.random.default_rng(1)
    X = rng.uniform([-3000, -3000, 0], [3000, 3000, 400], (2000, 3))
    tc, gc = essp_model(1480.0, a, continued=True)
    tw, gw = essp_model(1480.0, a)
    t_ref, g_ref = tw(TETRAHEDRON, X[:, None]), gw(TETRAHEDRON, X[:, None])
    ok = np.isfinite(t_ref)
    assert ok.mean() > 0.5
    np.testing.assert_allclose(tc(TETRAHEDRON, X[:, None])[ok], t_ref[ok], rtol=1e-13)
    np.testing.assert_allclose(gc(TETRAHEDRON, X[:, None])[ok], g_ref[ok], rtol=1e-9, atol=1e-18)


def test_continued_gradient_above_surface_finite_differences() -> None:
    from aquasim_protocols.ramezani.math import essp_model

    tc, gc = essp_model(PAPER_B, PAPER_A, continued=True)
    X = np.array([[800.0, 40.0, -20.0], [300.0, -200.0, -5.0], [60.0, 50.0, -60.0]])
    h = 1e-3
    fd = np.stack(
        [(tc(TETRAHEDRON, (X + h * e)[:, None]) - tc(TETRAHEDRON, (X - h * e)[:, None])) / (2 * h) for e in np.eye(3)],
        axis=-1,
    )
    np.testing.assert_allclose(gc(TETRAHEDRON, X[:, None]), fd, rtol=1e-6, atol=1e-12)


def test_fig6_essp_stays_on_crb_assp_departs() -> None:
    # Fig. 6 (pure maths): sigma_t = 1 ms, target = [x, 50, 50] + N(0, 100 I); plain Algorithm 1
    from aquasim_protocols.ramezani.math import localize_batch, tof_functions

    rng = np.random.default_rng(6)
    tt, _ = tof_functions("essp", PAPER_B, PAPER_A, TETRAHEDRON)
    ratios = {}
    for x in (50.0, 400.0, 1000.0):
        X = np.array([x, 50.0, 50.0]) + 10.0 * rng.standard_normal((3000, 3))
        t = tt(TETRAHEDRON, X[:, None]) + 1e-3 * rng.standard_normal((3000, 4))
        bound = np.sqrt(np.mean(fix_crb(TETRAHEDRON, X, PAPER_B, PAPER_A, 1e-3)))
        for m in ("essp", "assp"):
            tf, gf = tof_functions(m, PAPER_B, PAPER_A, TETRAHEDRON, continued=True)
            Xe, _, _ = localize_batch(TETRAHEDRON, t, tf, gf, 1e-3, TETRAHEDRON.mean(axis=0))
            ratios[m, x] = np.sqrt(np.mean(np.sum((Xe - X) ** 2, axis=1))) / bound
    for x in (50.0, 400.0, 1000.0):
        assert ratios["essp", x] == pytest.approx(1.0, abs=0.08), ratios
    assert ratios["assp", 50.0] < 1.05
    assert ratios["assp", 400.0] > 1.1
    assert ratios["assp", 1000.0] > 1.5
