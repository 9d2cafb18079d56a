"""The paper's numbers beside ours: statistics on hand-made tables, and the main job's table."""

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from aquasim_protocols.itmtl.paper import algorithm, comparison, node_rounds, wsc_gap_per_round
from aquasim_py import cli

SCEN = Path(__file__).resolve().parents[2] / "scenarios" / "itmtl.toml"


def _nodes():
    return pd.DataFrame({"node": range(6), "role": ["anchor"] * 3 + ["ordinary"] * 3, "protocol": "itmtl"})


def _tables(rows):
    """rows: (node, round, |sync error| us, position error vector); true positions: node 3 at
    the origin, node 4 at x = 100 m, node 5 at y = 100 m (all at rest)."""
    truth = {3: (0.0, 0.0, 0.0), 4: (100.0, 0.0, 0.0), 5: (0.0, 100.0, 0.0)}
    est = pd.DataFrame(
        [
            {
                "time": 30.0 * r,
                "node": n,
                "protocol": "itmtl",
                "round": r,
                **{k: truth[n][i] + d[i] for i, k in enumerate("xyz")},
                **{f"true_{k}": truth[n][i] for i, k in enumerate("xyz")},
                "is_reference": False,
            }
            for n, r, _, d in rows
        ]
    )
    clk = pd.DataFrame(
        [{"time": 30.0 * r, "node": n, "protocol": "itmtl", "round": r, "error": -e * 1e-6} for n, r, e, _ in rows]
    )
    return {"nodes": _nodes(), "estimates": est, "clocks": clk}


# ITMTL localizes nodes 3 and 4 in rounds 1 and 2; wsc also node 5 in round 1 (left out: ITMTL
# did not localize it then) and only node 3 in round 2 (node 4 left out of ITMTL's round 2)
ITMTL = _tables([(3, 1, 10, (1, 0, 0)), (4, 1, 20, (0, 1, 0)), (3, 2, 10, (1, 0, 0)), (4, 2, 30, (0, 0, 1))])
WSC = _tables([(3, 1, 15, (2, 0, 0)), (4, 1, 30, (0, 0, 2)), (5, 1, 1000, (50, 0, 0)), (3, 2, 12, (3, 0, 0))])


def test_wsc_gap_uses_the_nodes_and_rounds_both_localized():
    g = wsc_gap_per_round(node_rounds(ITMTL, "itmtl"), node_rounds(WSC, "itmtl"), _nodes())
    # round 1: ITMTL (10 + 20) / 2 = 15 us, wsc (15 + 30) / 2 = 22.5 us -> +50 %;
    # round 2: node 3 alone, 10 vs 12 us -> +20 %
    assert g["sync_itmtl_s"].to_numpy() == pytest.approx([15e-6, 10e-6])
    assert g["sync_gap_pct"].to_numpy() == pytest.approx([50.0, 20.0])
    # round 1 NMSE: spread of (0,0,0) and (100,0,0) about their centre = 2 * 50^2 = 5000 m^2;
    # squared errors 2 (ITMTL) and 8 (wsc) -> 4e-4 and 1.6e-3, a 75 % decrease; round 2 has
    # one node (no spread): NaN
    assert g.loc[1, "nmse_itmtl"] == pytest.approx(4e-4)
    assert g.loc[1, "nmse_wsc"] == pytest.approx(1.6e-3)
    assert g.loc[1, "nmse_decrease_pct"] == pytest.approx(75.0)
    assert np.isnan(g.loc[2, "nmse_decrease_pct"])


def _result(protocol, compensate=True, **metrics):
    group = SimpleNamespace(role="ordinary", protocol=protocol, params={"compensate": compensate})
    anchors = SimpleNamespace(role="anchor", protocol=protocol, params={})
    tables = (ITMTL if compensate else WSC) if protocol == "itmtl" else {}
    return SimpleNamespace(scenario=SimpleNamespace(nodes=[anchors, group]), tables=tables, metrics=metrics)


def test_algorithm_names():
    assert algorithm(_result("itmtl").scenario) == "ITMTL"
    assert algorithm(_result("itmtl", compensate=False).scenario) == "ITMTL-wsc"
    assert [algorithm(_result(p).scenario) for p in ("tshl", "mu_sync", "mobi_sync", "beacon")] == [
        "TSHL",
        "MU-Sync",
        "Mobi-Sync",
        None,
    ]


def test_comparison_rows_say_what_the_paper_measured():
    s = "sync.final_mean_abs_error_s"
    results = {
        "a": _result("itmtl", **{s: 1e-5, "localization.nmse": 3e-5}),
        "b": _result("itmtl", compensate=False, **{s: 2e-5, "localization.nmse": 2e-5}),
        "c": _result("tshl", **{s: 1e-3, "localization.nmse": 4e-5}),
    }
    rows = comparison(results).set_index("figure")
    assert rows.loc["Fig. 9", "ours"] == "ITMTL 10 us, ITMTL-wsc 20 us, TSHL 1e+03 us: ITMTL lowest"
    assert rows.loc["Fig. 10", "ours"].endswith("ITMTL not lowest")
    assert rows.loc["Fig. 11", "ours"] == "50.0 % (round 1 of 2)"
    assert rows.loc["Fig. 11", "paper"] == "56.67 %"
    assert rows.loc["Fig. 12", "ours"].startswith("median 75.0 %")
    assert comparison({"c": results["c"]}) is None


def test_main_job_prints_the_paper_beside_the_variants(tmp_path, capsys):
    out = tmp_path / "o"
    rc = cli.main([str(SCEN), "--out", str(out), "--set", "simulation.duration_s=70"])
    assert rc == 0
    printed = capsys.readouterr().out
    assert (
        "beside this run (same statistic; paper.csv)" in printed and "56.67 %" in printed and "about 25.8 %" in printed
    )
    paper = pd.read_csv(out / "paper.csv")
    assert list(paper["figure"]) == ["Fig. 9", "Fig. 10", "Fig. 11", "Fig. 12"]
    assert "ITMTL-wsc" in paper.loc[0, "ours"] and "Mobi-Sync" in paper.loc[0, "ours"]
    assert paper.loc[2, "paper"] == "56.67 %" and paper.loc[3, "paper"] == "about 25.8 %"
