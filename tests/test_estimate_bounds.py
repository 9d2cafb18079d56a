"""The bounds computed after a run (aquasim_py.estimate_bounds): the declared column equals the
per-row computation at the kernel's exact positions, and the applied noise equals the noise the
channel put on the timestamps, measured from the packets trace."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from aquasim_py import scenario
from aquasim_py.estimate_bounds import applied_range_noise, estimate_bounds
from aquasim_py.estimation.bounds import range_geometry
from aquasim_py.metrics import positions_at
from aquasim_py.nodecore import NodeCore

ITMTL = Path(__file__).resolve().parents[1] / "scenarios" / "itmtl.toml"


def test_the_declared_bound_is_the_per_row_computation(monkeypatch):
    """Each declared estimate's bound as the kernel computed it while the row was logged
    (references at their exact positions then), against the bound computed after the run from
    the positions table. Anchors do not move: equal to rounding. Promoted references drift,
    and the table interpolates them between samples: the tolerance is derived from the largest
    interpolation error measured here (a unit vector to a reference turns by at most delta / r,
    and the bound moves relatively by a few times that)."""
    sc = scenario.load(ITMTL, variant="itmtl", overrides={"simulation.duration_s": 200.0})
    sim = scenario.build(sc)
    per_row: list[tuple[float, float, float, np.ndarray, np.ndarray]] = []
    log = NodeCore.log_estimate

    def logged(self, x, y, z, confidence, is_reference, extra, geometry=None):
        if geometry is not None:
            refs, std, rel_std, depth_known = geometry
            t = self.env.now
            here = np.asarray(self.position(t), dtype=float)
            idx = np.array(refs, dtype=np.int64)
            anchors = self.sim.positions_at(idx, np.full(idx.size, t))
            crb, gdop = range_geometry(here, anchors, std=std, rel_std=rel_std, depth_known=depth_known)
            per_row.append((t, float(crb), float(gdop), idx, anchors))
        log(self, x, y, z, confidence, is_reference, extra, geometry)

    monkeypatch.setattr(NodeCore, "log_estimate", logged)
    sim.run(sc.simulation.duration_s)
    tables = sim.trace.frames()
    b = estimate_bounds(tables, applied_range_noise(sc))
    assert b is not None and len(b) == len(per_row) >= 20
    crb = np.array([p[1] for p in per_row])
    gdop = np.array([p[2] for p in per_row])
    static = np.array([bool(np.all(tables["nodes"].loc[p[3], "role"] == "anchor")) for p in per_row])
    assert static.sum() >= 5 and (~static).sum() >= 5  # both kinds are checked
    # the interpolation error of every reference position the rows used, and the ranges
    delta = max(
        float(np.max(np.abs(positions_at(tables["positions"], p[3], np.full(p[3].size, p[0])) - p[4]))) for p in per_row
    )
    r_min = min(
        float(
            np.min(
                np.linalg.norm(
                    p[4] - tables["estimates"].loc[row, ["true_x", "true_y", "true_z"]].to_numpy(float), axis=1
                )
            )
        )
        for p, row in zip(per_row, b["row"])
    )
    tol = 10.0 * delta / r_min
    assert tol < 1e-4  # a tolerance with teeth
    for got, want in ((b["crb_h_declared_m"].to_numpy(), crb), (b["gdop"].to_numpy(), gdop)):
        assert np.allclose(got[static], want[static], rtol=1e-12, atol=0.0)
        assert np.allclose(got[~static], want[~static], rtol=tol, atol=0.0)


def test_the_applied_range_noise_is_the_jitter_in_the_traces():
    """A known MAC jitter (1e-4 s) and a known clock read jitter of the ordinary nodes (5e-5 s),
    clocks otherwise perfect, so that a stamp is true time plus its noise: the one-way stamp
    error e = (rx stamp - tx stamp) - time of flight of every reception has variance s_tx^2 +
    s_rx^2, and a two-way range c^2 E[e^2] / 2. The bound's range std of an anchor-ordinary and
    an ordinary-ordinary link must equal c sqrt(mean(e^2) / 2) within the Monte Carlo accuracy
    of n receptions: the relative std of sqrt(mean e^2) is 1 / sqrt(2 n); 5 of them."""
    import aquasim_py

    clock = {"skew_ppm": 0.0, "skew_std_ppm": 0.0, "offset_s": 0.0, "offset_std_s": 0.0, "jitter_std_s": 5e-5}
    res = aquasim_py.run_scenario(
        ITMTL,
        variant="itmtl",
        overrides={"simulation.duration_s": 300.0, "channel.jitter_std_s": 1e-4, "nodes.1.clock": clock},
    )
    noise = applied_range_noise(res.scenario)
    assert math.isclose(noise.speed_mps, 1495.0, rel_tol=1e-9)  # the profile's depth mean
    p = res.tables["packets"]
    tx = p[p["event"] == "tx"].set_index("uid")["local_time"]
    rx = p[p["event"] == "rx"]
    e = rx["local_time"].to_numpy() - tx.loc[rx["uid"]].to_numpy() - rx["tof"].to_numpy()
    anchor = res.tables["nodes"].set_index("node")["role"].eq("anchor")
    a_src = anchor.loc[rx["src"]].to_numpy()
    a_dst = anchor.loc[rx["node"]].to_numpy()
    checked = 0
    for name, sel, (i, j) in (
        ("anchor-ordinary", a_src != a_dst, (4, 0)),
        ("ordinary-ordinary", ~a_src & ~a_dst, (4, 5)),
    ):
        n = int(sel.sum())
        assert n >= 200, name
        measured = noise.speed_mps * math.sqrt(np.mean(e[sel] ** 2) / 2.0)
        applied = float(noise.range_std(np.array([i]), np.array([j]), np.zeros(1))[0])
        assert abs(applied / measured - 1.0) <= 5.0 / math.sqrt(2.0 * n), (name, applied, measured, n)
        checked += 1
    assert checked == 2
    # with equal noise everywhere the range std is c times the stamp jitter
    assert math.isclose(float(noise.range_std(np.array([0]), np.array([1]), np.zeros(1))[0]), 1495.0 * 1e-4)
    # the bounds table uses it: a row that used only anchors has the anchor-ordinary link's std
    b = res.bounds
    assert b is not None
    refs = res.tables["estimates"]["refs"].to_numpy()[b["row"]]
    only_anchors = np.array([all(anchor.loc[int(r)] for r in str(s).split()) for s in refs])
    assert only_anchors.sum() >= 5
    link = float(noise.range_std(np.array([4]), np.array([0]), np.zeros(1))[0])
    assert np.allclose(b["range_std_m"].to_numpy()[only_anchors], link, rtol=1e-12)
    assert np.isfinite(b["crb_h_m"]).all()


def test_variants_of_one_run_share_the_applied_noise():
    """ITMTL and ITMTL-wsc on one network: the same applied range noise, whatever each declares."""
    import aquasim_py

    res = aquasim_py.run_variants(ITMTL, variants=["itmtl", "wsc"], overrides={"simulation.duration_s": 200.0})
    m = {k: r.metrics for k, r in res.items()}
    assert m["itmtl"]["localization.range_std_m"] == m["wsc"]["localization.range_std_m"]
    for v in ("itmtl", "wsc"):
        b = res[v].bounds
        assert b is not None
        # the declared column is each protocol's own model; the applied one is the channel's
        assert np.allclose(b["range_std_m"], b["range_std_m"].iloc[0])
        assert np.isfinite(m[v]["localization.rmse_over_crb"]) and np.isfinite(
            m[v]["localization.rmse_over_crb_declared"]
        )


def test_a_protocols_own_measurement_noise_is_applied_noise():
    """STVF and SLMP draw their ToA error (noise_ratio x delay) themselves: the applied noise
    of their nodes includes it, beside the channel's sound-speed deviation, and a range's std
    is the two relative parts combined; a protocol that draws none (ITMTL) adds nothing."""
    stvf = scenario.load(ITMTL.parent / "stvf_quick.toml", variant="stvf")
    noise = applied_range_noise(stvf)
    assert noise.meas_rel_std is not None and noise.meas_std_m is not None
    np.testing.assert_array_equal(noise.meas_rel_std, np.full(noise.meas_rel_std.size, 0.02))
    assert not np.any(noise.meas_std_m)
    speed_rel = stvf.channel.sound_speed_std_mps / noise.speed_mps
    r = np.array([[50.0, 80.0]])
    got = noise.range_std(np.array([[0]]), np.array([[1, 2]]), r)
    np.testing.assert_allclose(got, math.hypot(0.02, speed_rel) * r, rtol=1e-12)

    itmtl = applied_range_noise(scenario.load(ITMTL, variant="itmtl"))
    assert itmtl.meas_rel_std is not None and not np.any(itmtl.meas_rel_std)
