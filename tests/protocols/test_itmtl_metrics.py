"""Metrics of ITMTL and the baselines on hand-made trace tables."""

import numpy as np
import pandas as pd
import pytest

from aquasim_protocols.itmtl.metrics import coverage_upper_bound, per_round, protocol_metrics


def _nodes():
    roles = ["anchor"] * 3 + ["ordinary"] * 3
    return pd.DataFrame({"node": range(6), "role": roles, "protocol": "itmtl"})


def test_coverage_upper_bound_iterated_promotion():
    # 3 hears 0, 1, 2 -> localizable; 4 hears 1, 2, 3 -> after 3; 5 hears 0 and 4 only -> never
    links = [(0, 3), (1, 3), (2, 3), (1, 4), (2, 4), (3, 4), (0, 5), (4, 5)]
    pk = pd.DataFrame({"event": "rx", "src": [a for a, b in links], "node": [b for a, b in links]})
    tables = {"nodes": _nodes(), "packets": pk}
    assert coverage_upper_bound(tables) == pytest.approx(2 / 3)
    # one more link from an anchor makes 5 reachable through 4
    pk2 = pd.concat([pk, pd.DataFrame({"event": ["rx"], "src": [1], "node": [5]})])
    assert coverage_upper_bound({"nodes": _nodes(), "packets": pk2}) == 1.0


def test_metrics_sync_over_covered_nodes_and_nmse():
    nodes = _nodes()
    # node 3 localized in rounds 1-2, node 4 never: its clock rows count only in the *_all stats
    clocks = pd.DataFrame(
        {
            "time": [10.0, 40.0, 12.0, 42.0],
            "node": [3, 3, 4, 4],
            "protocol": "itmtl",
            "round": [1, 2, 1, 2],
            "error": [-4e-5, 1e-5, 3e-4, -5e-4],
        }
    )
    est = pd.DataFrame(
        {
            "time": [10.0, 40.0],
            "node": [3, 3],
            "protocol": "itmtl",
            "round": [1, 2],
            "x": [103.0, 130.0],
            "y": [200.0, 204.0],
            "z": [50.0, 50.0],
            "true_x": [100.0, 130.0],
            "true_y": [200.0, 200.0],
            "true_z": [50.0, 50.0],
            "error": [3.0, 4.0],
            "is_reference": [False, True],
            "fixed": [True, False],
        }
    )
    tables = {
        "nodes": nodes,
        "clocks": clocks,
        "estimates": est,
        "packets": pd.DataFrame({"event": [], "src": [], "node": []}),
    }
    m = protocol_metrics(tables, "itmtl")
    assert m["sync_final_mean_s"] == pytest.approx(1e-5)
    assert m["sync_final_mean_all_s"] == pytest.approx((1e-5 + 5e-4) / 2)
    assert m["loc_rmse_m"] == pytest.approx(np.sqrt((9 + 16) / 2))
    # NMSE about the centroid of the true positions (115, 200, 50): spread 2 * 15^2
    assert m["loc_nmse"] == pytest.approx(25.0 / (2 * 15**2))
    assert m["loc_rmse_fixed_m"] == pytest.approx(3.0)
    assert m["coverage"] == pytest.approx(1 / 3)
    assert m["promoted_share"] == pytest.approx(1 / 3)
    pr = per_round(tables, "itmtl")
    assert pr.loc[1, "sync_mean_s"] == pytest.approx(4e-5)
    assert pr.loc[2, "sync_all_mean_s"] == pytest.approx((1e-5 + 5e-4) / 2)


def test_mac_metrics_on_a_hand_made_table():
    from aquasim_protocols.itmtl.metrics import mac_metrics

    # 4 Res sent, 1 lost to a collision at its addressee, 1 to half duplex
    pk = pd.DataFrame(
        {
            "event": ["tx"] * 4 + ["drop", "drop", "rx", "rx"] + ["tx"],
            "reason": [None] * 4 + ["collision", "half_duplex", None, None] + [None],
            "kind": ["sync_res"] * 8 + ["sync_req"],
        }
    )
    # node 3: round 1 short although 3 references scheduled answers (MAC), round 2 short with
    # only 2 references in reach (topology), round 3 complete
    rounds = pd.DataFrame(
        {
            "node": [3, 3, 3],
            "protocol": "itmtl",
            "round": [1, 2, 3],
            "answers": [2, 2, 3],
            "needed": [3, 3, 3],
            "retried": [True, True, False],
        }
    )
    rep = pd.DataFrame({"node": [0, 1, 2, 0, 1, 0, 1, 2], "requester": 3, "round": [1, 1, 1, 2, 2, 3, 3, 3]})
    m = mac_metrics({"packets": pk, "reqres_rounds": rounds, "reqres_replies": rep}, "itmtl")
    assert m["res_collision_fraction"] == pytest.approx(1 / 4)
    assert m["short_round_fraction"] == pytest.approx(1 / 3)
    assert m["short_round_fraction_all"] == pytest.approx(2 / 3)
    assert m["retry_fraction"] == pytest.approx(2 / 3)
