"""MSWPF: fusion weights, the unquantized limit of the filter update, and a small network run
(both link modes, determinism, the truth barrier's bookkeeping)."""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aquasim_protocols.mswpf.math import (
    equivalent_std,
    fusion_weights,
    sensor_model,
    weighted_log_likelihood,
)
from aquasim_py import scenario
from aquasim_py.estimation import normalize_log_weights


@settings(max_examples=30, deadline=None)
@given(mi=st.lists(st.floats(0.0, 3.0), min_size=1, max_size=8), scheme=st.sampled_from(["gw", "ew", "bw"]))
def test_fusion_weights_sum_to_one(mi: list[float], scheme: str) -> None:
    a = fusion_weights(mi, scheme)  # type: ignore[arg-type]
    assert a.sum() == pytest.approx(1.0, abs=1e-12)
    assert np.all(a >= 0)


def test_weight_schemes_order_by_mi() -> None:
    mi = np.array([0.2, 0.5, 1.3])
    gw, ew, bw = (fusion_weights(mi, s) for s in ("gw", "ew", "bw"))
    np.testing.assert_allclose(gw, mi / mi.sum())
    np.testing.assert_allclose(ew, 1 / 3)
    np.testing.assert_allclose(bw, (1 / mi) / (1 / mi).sum())
    assert np.all(np.diff(gw) > 0) and np.all(np.diff(bw) < 0)


def _posterior_mean(loglik: np.ndarray, X: np.ndarray) -> np.ndarray:
    w, _ = normalize_log_weights(loglik)
    return np.asarray(w @ X)


def test_dense_quantizer_without_location_noise_approaches_the_unquantized_update() -> None:
    """L large, r_x = 0: the weighted quantized likelihood (eq 25) tends to the same weighted
    product of Gaussian likelihoods of the raw readings. The quantizer then reports the bin of
    z, i.e. z up to half a bin (delta / 2): with delta = 0.05 and a pressure slope of ~5 /m the
    posterior mean may move by ~ delta / (2 slope) = 5 mm; 5 cm is allowed. A 4-level
    quantizer must differ by more (the test can fail)."""
    rng = np.random.default_rng(0)
    S, k, r = 5e4, 1.0, 5.0
    sensors = np.array([[0.0, 0.0, 100.0], [120.0, 0.0, 100.0], [0.0, 120.0, 100.0]])
    X = np.column_stack([rng.normal(60, 15, 4000), rng.normal(50, 15, 4000), np.full(4000, 50.0)])
    truth = np.array([[62.0, 47.0, 50.0]])
    z = sensor_model(truth, sensors, S, k)[0][:, 0] + rng.normal(0, r, 3)
    h, g = sensor_model(X, sensors, S, k)
    rm = equivalent_std(r, g, np.zeros(3))
    alpha = np.array([0.5, 0.3, 0.2])
    ref = _posterior_mean(alpha @ (-0.5 * ((z[:, None] - h) / r) ** 2), X)
    dense = np.arange(0.0, 3000.0, 0.05)
    lv = np.searchsorted(dense, z, side="right")
    got = _posterior_mean(weighted_log_likelihood(lv, h, rm, dense, alpha), X)
    assert np.linalg.norm(got - ref) < 0.05
    coarse = np.array([300.0, 450.0, 600.0])
    lv = np.searchsorted(coarse, z, side="right")
    far = _posterior_mean(weighted_log_likelihood(lv, h, rm, coarse, alpha), X)
    assert np.linalg.norm(far - ref) > 0.5


def _small_network(ideal: bool) -> dict[str, Any]:
    """3 x 3 sensors (spacing 120 m), FC, target crossing the grid: 6 intervals."""
    return {
        "simulation": {"duration_s": 12.5, "seed": 3},
        "environment": {"volume": {"lo": [-100.0, -100.0, 0.0], "hi": [400.0, 400.0, 200.0]}},
        "channel": {
            "max_range_m": 1500.0,
            "bitrate_bps": 4000.0,
            "reflections": "none",
            "pressure_kind": "mswpf_emission",
        },
        "nodes": [
            {
                "name": "sensors",
                "role": "ordinary",
                "protocol": "mswpf",
                "placement": {"kind": "grid", "shape": [3, 3, 1], "lo": [0.0, 0.0, 100.0], "hi": [240.0, 240.0, 100.0]},
                "sensors": {"position_fix": True, "position_noise_std_m": 2.0},
                "params": {"fusion_center": 9, "hello_slot_s": 0.5},
            },
            {
                "name": "fc",
                "role": "sink",
                "protocol": "mswpf",
                "placement": {"kind": "explicit", "positions": [[120.0, 120.0, 10.0]]},
                "params": {
                    "start_s": 6.0,
                    "steps": 6,
                    "n_particles": 300,
                    "levels": 6,
                    "x0": [55.0, 65.0, 10.0, 10.0],
                    "ideal_links": ideal,
                },
            },
            {
                "name": "target",
                "role": "target",
                "protocol": "mswpf",
                "placement": {"kind": "explicit", "positions": [[60.0, 60.0, 50.0]]},
                "mobility": {"model": "noisy_constant_velocity", "velocity": [10.0, 10.0, 0.0], "start_s": 6.0},
                "params": {"start_s": 6.0, "steps": 6},
            },
        ],
        "trace": {"position_interval_s": 1.0},
    }


def _run(d: dict[str, Any]) -> dict[str, Any]:
    sc = scenario.load_dict(copy.deepcopy(d), None)
    sim = scenario.build(sc)
    sim.run(sc.simulation.duration_s)
    return sim.trace.frames()


@pytest.mark.parametrize("ideal", [True, False])
def test_network_tracks_and_is_deterministic(ideal: bool) -> None:
    from aquasim_protocols.mswpf.metrics import mswpf_metrics

    a, b = _run(_small_network(ideal)), _run(_small_network(ideal))
    for t in ("mswpf_steps", "estimates", "packets"):
        assert a[t].to_csv() == b[t].to_csv()
    steps = a["mswpf_steps"]
    assert list(steps["step"]) == list(range(6))
    m = mswpf_metrics(a)
    assert m["rmse_m"] < 20.0
    pk = a["packets"]
    reports = pk[(pk["kind"] == "mswpf_report") & (pk["event"] == "tx")]
    if ideal:
        assert len(reports) == 0 and (steps["n_reports"] == steps["n_selected"]).all()
        assert m["report_loss"] == 0.0
    else:
        assert len(reports) > 0
        # weights of the reports that arrived sum to one
        for w in steps["weights"]:
            if w:
                assert sum(map(float, w.split())) == pytest.approx(1.0, abs=1e-3)


@pytest.mark.slow
@pytest.mark.skipif(
    not hasattr(__import__("aquasim_py"), "run_scenario"), reason="variants loader not on this branch yet"
)
def test_shipped_2d_scenario_variants_run() -> None:
    import aquasim_py

    r = aquasim_py.run_scenario("scenarios/mswpf_2d.toml", variant="ew", overrides=["nodes.1.params.steps=10"])  # type: ignore[attr-defined]
    assert r.metrics["mswpf.steps"] == 10
    assert r.scenario.nodes[1].params["weights"] == "ew"


@pytest.mark.parametrize("relocalize", [True, False])
def test_location_error_is_white_when_sensors_relocalize(relocalize: bool) -> None:
    """Eq 4: a sensor's believed position is its true one plus white noise of std r_x per axis,
    fresh every interval; the fix of each report is in ``mswpf_reports``. Without relocalizing
    the error is one draw for the whole run. The sample std of the pooled x / y errors lies in
    the chi-square 99.9 % interval around r_x."""
    from scipy.stats import chi2

    rx = 4.0
    d = _small_network(True)
    d["nodes"][0]["sensors"]["position_noise_std_m"] = rx
    d["nodes"][0]["params"]["relocalize"] = relocalize
    t = _run(d)
    rep = t["mswpf_reports"]
    truth = t["positions"].groupby("node")[["x", "y"]].first()
    err = rep[["x", "y"]].to_numpy() - truth.loc[rep["node"]].to_numpy()
    per_sensor = rep.groupby("node")[["x", "y"]].nunique().max(axis=1)
    n_reports = rep.groupby("node").size()
    assert (n_reports > 1).any()  # some sensor reported more than once
    if relocalize:
        assert (per_sensor == n_reports).all()  # a new fix every report
        n = err.size
        s = float(np.sqrt(np.mean(err**2)))
        assert np.sqrt(chi2.ppf(5e-4, n) / n) * rx < s < np.sqrt(chi2.ppf(1 - 5e-4, n) / n) * rx
    else:
        assert (per_sensor == 1).all()


def test_pcrlb_selection_is_the_brute_force_det_j_maximizer() -> None:
    """Eqs 32-36 end to end: the tracker's choice of Ns = 3 among the qualified candidates is
    the subset a brute force picks by det(J^P + sum of the subset's J^D), with each sensor's
    J^D computed independently: E over particles of sum_l grad P_l grad P_l^T / P_l, grad P_l
    by central differences of eq 12 in the target position (r_x = 0, so r_m = r exactly)."""
    import itertools

    from aquasim_protocols.mswpf.math import MswpfConfig, MswpfTracker, thresholds
    from aquasim_py.estimation import level_probabilities

    gam = thresholds(6, 5e4, 1.0, 50.0, 160.0)
    tr = MswpfTracker(
        MswpfConfig(gammas=tuple(gam), n_particles=300),
        [300.0, 310.0, 10.0, 10.0],
        60 * np.eye(4),
        np.random.default_rng(5),
    )
    g = np.arange(0.0, 1000.0, 120.0)
    sensors = np.array([[x, y, 100.0] for x in g for y in g])
    loc = np.zeros(len(sensors))
    idx, _ = tr.select(sensors, loc)

    P = tr.positions()
    cand = np.flatnonzero(np.linalg.norm(sensors - P.mean(axis=0), axis=1) <= 160.0)
    assert len(cand) > 3  # a real choice

    def probs(pos: np.ndarray, s: np.ndarray) -> np.ndarray:
        return level_probabilities(5e4 / np.linalg.norm(pos - s, axis=1), 5.0, gam)

    eps = 1e-3
    J_D = []
    for c in cand:
        p0 = probs(P, sensors[c])
        grads = [(probs(P + eps * e, sensors[c]) - probs(P - eps * e, sensors[c])) / (2 * eps) for e in np.eye(3)[:2]]
        G = np.stack(grads, axis=-1)  # (N, L, 2)
        ok = p0 > 1e-300
        I = np.einsum(
            "nla,nlb->ab", np.where(ok[..., None], G, 0.0) / np.sqrt(np.where(ok, p0, 1.0))[..., None], G
        ) / len(P)
        full = np.zeros((4, 4))
        full[:2, :2] = I
        J_D.append(full)
    dets = {
        sub: np.linalg.det(tr.J_prior + sum(J_D[i] for i in sub)) for sub in itertools.combinations(range(len(cand)), 3)
    }
    best = max(dets, key=lambda k: dets[k])
    ranked = sorted(dets.values(), reverse=True)
    assert ranked[0] > ranked[1] * (1 + 1e-6)  # the maximizer is clear of the finite-difference error
    assert sorted(idx.tolist()) == sorted(cand[list(best)].tolist())


def test_ideal_fusion_weights_are_eq27_of_eq23_on_the_fc_particles(monkeypatch: pytest.MonkeyPatch) -> None:
    """The GW path end to end (ideal links, location noise r_x = 2): at every fusion each weight
    is I_s / sum I (eq 27) over the reports that arrived, and each I_s is eq 23 on exactly the
    fusion centre's predicted particles of that interval, at the position the sensor reported,
    with eq 10's r_m. Reference: h = S / D^k, its gradient by central differences and the level
    probabilities by scipy's normal cdf, independent of the package's quantizer maths."""
    from scipy.stats import norm

    from aquasim_protocols.mswpf import math as mm

    seen: list[tuple[Any, ...]] = []
    orig = mm.MswpfTracker.update

    def spy(self: Any, sensors: Any, loc_std: Any, levels: Any, mi: Any, info: Any = None) -> Any:
        X = self.positions().copy()
        out = orig(self, sensors, loc_std, levels, mi, info)
        seen.append((X, np.array(sensors, float), np.array(loc_std, float), np.array(mi, float), out[0], self.cfg))
        return out

    monkeypatch.setattr(mm.MswpfTracker, "update", spy)
    _run(_small_network(True))
    assert len(seen) == 6
    for X, S, loc, mi, alpha, cfg in seen:
        assert len(S) == 3 and np.all(loc == 2.0)
        np.testing.assert_allclose(alpha, mi / mi.sum(), rtol=1e-12)
        gam = np.concatenate([[-np.inf], cfg.gammas, [np.inf]])
        for s, ls, mi_s in zip(S, loc, mi):

            def h(P: np.ndarray, s: np.ndarray = s) -> np.ndarray:
                return cfg.source_level / np.linalg.norm(P - s, axis=1) ** cfg.exponent

            e = 1e-4
            gx = (h(X + [e, 0, 0]) - h(X - [e, 0, 0])) / (2 * e)
            gy = (h(X + [0, e, 0]) - h(X - [0, e, 0])) / (2 * e)
            rm = np.sqrt(cfg.r**2 + (gx**2 + gy**2) * ls**2)
            P = np.diff(norm.cdf((gam[None, :] - h(X)[:, None]) / rm[:, None]), axis=1)  # (N, L)

            def ent(p: np.ndarray) -> np.ndarray:
                return -np.sum(np.where(p > 0, p * np.log(np.where(p > 0, p, 1.0)), 0.0), axis=-1)

            ref = ent(P.mean(axis=0)) - ent(P).mean()
            assert mi_s == pytest.approx(ref, rel=1e-6, abs=1e-9)


def test_shipped_scenarios_default_to_the_literal_reading():
    """Eq 6 as printed (k = 2, S = 5 x 10^4) and the paper's CV truth (q = 1, kept in the
    field) in every MSWPF scenario; the former pair survives as the *_former variants."""
    import tomllib
    from pathlib import Path

    from aquasim_protocols.mswpf.node import MswpfNode

    assert MswpfNode.Params().exponent == 2.0
    root = Path(__file__).resolve().parents[2] / "scenarios"
    for path in sorted(root.glob("mswpf_*.toml")):
        raw = tomllib.loads(path.read_text())
        assert raw["channel"]["pressure_exponent"] == 2.0, path.name
        assert raw["channel"]["pressure_source_level"] == 5e4, path.name
        fc, target = raw["nodes"][1], raw["nodes"][2]
        assert fc["params"]["exponent"] == 2.0 and fc["params"]["source_level"] == 5e4, path.name
        assert target["mobility"]["q"] == 1.0 and target["mobility"]["confine_steps"] > 0, path.name
    two = tomllib.loads((root / "mswpf_2d.toml").read_text())["variants"]
    for w in ("gw", "ew", "bw"):
        former = two[f"{w}_former"]
        assert former["nodes.1.params.exponent"] == former["channel.pressure_exponent"] == 1.0
        assert former["nodes.2.mobility.q"] == 0.0
