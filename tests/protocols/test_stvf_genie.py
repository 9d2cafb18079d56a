"""The references of STVF and SLMP: the genie multilateration (an oracle computed in the
metrics from trace tables) and the CRB of the geometry each estimate used."""

import numpy as np
import pandas as pd
import pytest

import aquasim_py
from aquasim_protocols.stvf.genie import crb_metrics, genie_fixes
from aquasim_py.estimation.bounds import range_crb_trace


def _positions(ids, xyz, vel, times):
    """A positions table of nodes in straight motion."""
    rows = []
    for i, p, v in zip(ids, xyz, vel):
        for t in times:
            q = np.asarray(p) + np.asarray(v) * t
            rows.append((t, i, *q, *v))
    return pd.DataFrame(rows, columns=["time", "node", "x", "y", "z", "vx", "vy", "vz"])


def test_genie_fixes_exact_ranges_give_the_true_position():
    """Beacons drifting at 1 m/s, a moored node, exact delays from each beacon's send
    instant: the genie recovers the node, and a collinear set is no fix."""
    beacons = [[0.0, 0.0, 20.0], [60.0, 5.0, 25.0], [10.0, 55.0, 22.0], [100.0, 0.0, 20.0], [200.0, 0.0, 20.0]]
    vel = [[1.0, 0.2, 0.0]] * 5 + [[0.0, 0.0, 0.0]]
    node = [30.0, 25.0, 24.0]
    pos = _positions([0, 1, 2, 3, 4, 9], [*beacons, node], vel, np.arange(0.0, 12.0))
    rows = []
    c = 1500.0
    for t_log, srcs in ((5.9, (0, 1, 2)), (6.9, (0, 3, 4))):  # the second: three beacons on one line
        for k, s in enumerate(srcs):
            t_rx = t_log - 0.7 + 0.1 * k
            p_node = np.array(node)
            # the delay d solves |p_node - p_src(t_rx - d)| = c d (iterate: converges at once)
            d = 0.0
            for _ in range(5):
                d = np.linalg.norm(p_node - (np.array(beacons[s]) + np.array(vel[0]) * (t_rx - d))) / c
            rows.append((t_log, 9, s, d, t_log - t_rx, p_node[2], 0.02, 80.0, 10.0))
    rng = pd.DataFrame(
        rows, columns=["time", "node", "src", "delay_s", "age_s", "depth_m", "rel_std", "range_m", "max_std_m"]
    )
    fixes = genie_fixes({"genie_ranges": rng, "positions": pos}, speed_mps=c)
    assert len(fixes) == 1  # the collinear period gives no fix
    assert fixes["error_m"].iloc[0] < 1e-6
    assert fixes["epoch"].iloc[0] == pytest.approx(5.9 - 0.6)


def test_crb_metrics_is_the_bound_of_each_estimate_geometry():
    ids = [0, 1, 2, 3, 7]
    xyz = [[0.0, 0.0, 20.0], [50.0, 0.0, 20.0], [0.0, 50.0, 20.0], [50.0, 50.0, 20.0], [20.0, 30.0, 25.0]]
    pos = _positions(ids, xyz, [[0.5, 0.0, 0.0]] * 5, np.arange(0.0, 10.0))
    est = pd.DataFrame(
        {
            "time": [3.9, 4.9],
            "node": [7, 7],
            "protocol": ["stvf", "stvf"],
            "x": [0.0, 0.0],
            "y": [0.0, 0.0],
            "z": [25.0, 25.0],
            "refs": ["0 1 2", "0 1 2 3"],
            "epoch_lag_s": [0.5, 0.5],
            "range_rel_std": [0.02, 0.02],
        }
    )
    nodes = pd.DataFrame({"node": ids, "role": ["anchor"] * 4 + ["ordinary"], "protocol": ["stvf"] * 5})
    m = crb_metrics({"estimates": est, "nodes": nodes, "positions": pos}, "stvf")
    expect = []
    for t, refs in ((3.4, [0, 1, 2]), (4.4, [0, 1, 2, 3])):
        x = np.array(xyz[4]) + [0.5 * t, 0, 0]
        a = np.array([xyz[i] for i in refs]) + [0.5 * t, 0, 0]
        expect.append(range_crb_trace(x, a, rel_std=0.02))
    assert m["crb_rows"] == 2
    assert m["crb_rmse_m"] == pytest.approx(np.sqrt(np.mean(expect)), rel=1e-9)


@pytest.mark.parametrize("variant", ["stvf", "slmp"])
def test_stvf_and_slmp_report_the_crb_of_their_geometry(variant):
    res = aquasim_py.run_scenario(
        "scenarios/stvf_quick.toml", variant=variant, overrides=["simulation.duration_s=30.0"], progress=False
    )
    m = res.metrics
    assert m[f"{variant}.crb_rows"] > 100
    assert 0.2 < m[f"{variant}.crb_rmse_m"] < m["localization.rmse_m"]


def test_genie_variant_beats_every_protocol_on_its_own_fixes():
    res = aquasim_py.run_scenario(
        "scenarios/stvf_quick.toml",
        variant="genie_multilateration",
        overrides=["simulation.duration_s=30.0"],
        progress=False,
    )
    m = res.metrics
    assert m["genie_multilateration.fixes"] > 100
    assert m["genie_multilateration.rmse_m"] < 3.0
    assert 0 < m["genie_multilateration.period_coverage"] <= m["genie_multilateration.coverage"] <= 1
