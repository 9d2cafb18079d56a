"""Metrics from trace tables, checked against hand-computed values."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from aquasim_py import metrics


def est_table(rows):
    cols = ["time", "node", "x", "y", "z", "true_x", "true_y", "true_z", "is_reference"]
    return pd.DataFrame(rows, columns=cols)


@pytest.fixture
def est():
    # node 1: errors 5 (3-4-5) then 0; node 2: error 13 (5-12-13); node 0 is an anchor (reference)
    return est_table(
        [
            (1.0, 1, 3.0, 4.0, 0.0, 0.0, 0.0, 0.0, False),
            (2.0, 1, 10.0, 10.0, 10.0, 10.0, 10.0, 10.0, False),
            (1.5, 2, 5.0, 112.0, 0.0, 0.0, 100.0, 0.0, False),
            (1.0, 0, 50.0, 50.0, 50.0, 0.0, 0.0, 0.0, True),
        ]
    )


def test_position_errors_and_rmse(est):
    np.testing.assert_allclose(metrics.position_errors(est), [5.0, 0.0, 13.0])
    assert metrics.rmse(est) == pytest.approx(math.sqrt((25 + 0 + 169) / 3))
    # references included on request: the anchor's 50*sqrt(3) error joins
    assert metrics.rmse(est, exclude_references=False) == pytest.approx(math.sqrt((25 + 169 + 7500) / 4))


def test_rmse_final_and_time_window(est):
    # last row per node: node 1 at t=2 (0 m), node 2 (13 m)
    assert metrics.rmse(est, final=True) == pytest.approx(math.sqrt(169 / 2))
    assert metrics.rmse(est, t_min=1.2) == pytest.approx(math.sqrt(169 / 2))
    assert metrics.rmse(est, t_max=1.2) == pytest.approx(5.0)
    assert math.isnan(metrics.rmse(est, t_min=10.0))


def test_nmse_definition(est):
    # sum of squared errors over sum of squared true norms
    num = 25 + 0 + 169
    den = 0.0 + 300.0 + 100.0**2
    assert metrics.nmse(est) == pytest.approx(num / den)


def test_reference_flag_survives_csv_round_trip(tmp_path, est):
    est["is_reference"] = est["is_reference"].astype(object)
    est.loc[0, "is_reference"] = None  # unset flag -> blank in CSV -> NaN after reading
    p = tmp_path / "e.csv"
    est.to_csv(p, index=False)
    back = pd.read_csv(p)
    assert metrics.rmse(back) == pytest.approx(metrics.rmse(est))


def test_coverage(est):
    nodes = pd.DataFrame({"node": [0, 1, 2, 3], "role": ["anchor", "ordinary", "ordinary", "target"]})
    unknown = metrics.unknown_nodes(nodes)
    np.testing.assert_array_equal(unknown, [1, 2, 3])
    assert metrics.coverage(est, unknown) == pytest.approx(2 / 3)
    assert metrics.coverage(est, unknown, until=1.2) == pytest.approx(1 / 3)
    assert metrics.coverage(est.iloc[:0], unknown) == 0.0
    assert math.isnan(metrics.coverage(est, []))
    # an anchor's reference row does not cover it
    assert metrics.coverage(est, [0]) == 0.0


def test_sync_error_stats():
    clocks = pd.DataFrame(
        {"time": [1.0, 2.0, 3.0, 4.0, 5.0], "node": [1, 2, 1, 2, 3], "error": [-1.0, 2.0, -3.0, 4.0, 10.0]}
    )
    s = metrics.sync_error_stats(clocks, percentiles=(50, 90))
    assert s["mean_abs_error_s"] == pytest.approx((1 + 2 + 3 + 4 + 10) / 5)
    assert s["p50_abs_error_s"] == pytest.approx(3.0)  # median of 1, 2, 3, 4, 10
    # linear interpolation between order statistics: rank 0.9 * 4 = 3.6 -> 4 + 0.6 * (10 - 4)
    assert s["p90_abs_error_s"] == pytest.approx(7.6)
    # final rows: node 1 -> 3, node 2 -> 4, node 3 -> 10
    assert s["final_mean_abs_error_s"] == pytest.approx(17 / 3)
    assert metrics.sync_error_stats(clocks, (50,), t_min=3.0)["mean_abs_error_s"] == pytest.approx(17 / 3)


def test_packet_counts():
    p = pd.DataFrame(
        {
            "event": ["tx", "tx", "rx", "rx", "rx", "drop", "drop", "drop"],
            "reason": [None, None, None, None, None, "collision", "snr", "collision"],
        }
    )
    assert metrics.packet_counts(p) == {
        "sent": 2,
        "received": 3,
        "dropped": 3,
        "dropped.collision": 2,
        "dropped.snr": 1,
    }
    assert metrics.packet_counts(None) == {"sent": 0, "received": 0, "dropped": 0}


def test_positions_at_interpolates_linear_motion_exactly():
    t = np.arange(0.0, 10.0, 1.0)
    pos = pd.DataFrame(
        {
            "time": np.concatenate([t, t]),
            "node": [4] * 10 + [7] * 10,
            "x": np.concatenate([2.0 * t, np.zeros(10)]),
            "y": np.concatenate([-t, np.full(10, 3.0)]),
            "z": np.concatenate([np.full(10, 5.0), 0.5 * t]),
        }
    )
    q_node = np.array([7, 4, 4, 7, 4])
    q_time = np.array([2.25, 3.5, 0.0, 20.0, -1.0])
    got = metrics.positions_at(pos, q_node, q_time)
    # without velocity columns, the end samples are held
    expect = [[0.0, 3.0, 1.125], [7.0, -3.5, 5.0], [0.0, 0.0, 5.0], [0.0, 3.0, 4.5], [0.0, 0.0, 5.0]]
    np.testing.assert_allclose(got, expect)
    assert np.all(np.isnan(metrics.positions_at(pos, [9], [1.0])))
    # with them, the motion is extrapolated past the ends
    pos["vx"] = np.concatenate([np.full(10, 2.0), np.zeros(10)])
    pos["vy"] = np.concatenate([np.full(10, -1.0), np.zeros(10)])
    pos["vz"] = np.concatenate([np.zeros(10), np.full(10, 0.5)])
    got = metrics.positions_at(pos, q_node, q_time)
    expect[3] = [0.0, 3.0, 10.0]
    expect[4] = [-2.0, 1.0, 5.0]
    np.testing.assert_allclose(got, expect)


def test_summarize_adds_protocol_metrics_with_prefix(est):
    class Proto:
        name = "demo"

        @classmethod
        def metrics(cls, tables):
            return {"answer": 42.0, "rows": len(tables["estimates"])}

    nodes = pd.DataFrame({"node": [0, 1, 2], "role": ["anchor", "ordinary", "ordinary"]})
    clocks = pd.DataFrame({"time": [1.0], "node": [1], "error": [0.5]})
    m = metrics.summarize({"estimates": est, "nodes": nodes, "clocks": clocks, "packets": None}, [Proto, Proto])
    assert m["demo.answer"] == 42.0 and m["demo.rows"] == 4
    assert m["localization.rmse_m"] == pytest.approx(metrics.rmse(est))
    assert m["localization.coverage"] == 1.0
    assert m["sync.mean_abs_error_s"] == 0.5
    assert m["packets.sent"] == 0
    # warm-up drops early rows
    m2 = metrics.summarize({"estimates": est, "nodes": nodes}, [], warmup_s=1.2)
    assert m2["localization.rmse_m"] == pytest.approx(13 / math.sqrt(2))
