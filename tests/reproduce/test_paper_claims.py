"""The five papers' claims as data: every unit loads, each claim runs in the paper's own
set-up and statistic, and a reproduction from one run per quantity gives no verdict."""

from __future__ import annotations

import numpy as np
import pytest

from aquasim_py import reproduce as rp
from aquasim_py.reproduce.runner import evaluate_claims, resolved


@pytest.mark.parametrize("key", sorted(rp.PAPERS))
def test_every_claim_names_a_scenario_variant_and_reading_that_exist(key):
    """Each unit a claim needs loads (its scenario, overrides and variants), at both scales."""
    paper = rp.PAPERS[key]
    ids = [c.id for c in paper.claims]
    assert len(ids) == len(set(ids))
    for scale in (paper.quick, paper.full):
        for unit in rp.plan_units(paper, scale, paper.claims):
            sc = unit.load()
            for v in unit.variants:
                assert v is None or v in sc.variants
    for c in paper.claims:
        assert c.kind in ("reference", "less") or c.paper is not None or "(reference)" in c.figure
        assert paper.claim_readings(c), c.id


def _fake_rows(paper: rp.Paper, scale: rp.Scale, runs: int) -> tuple[list[rp.Unit], dict[str, list[dict]]]:
    """Rows of ``runs`` runs for every unit, with every column any claim reads (a positive
    random value; series of 5 intervals)."""
    rng = np.random.default_rng(0)
    units = rp.plan_units(paper, scale, paper.claims, runs=runs)
    columns: set[tuple[str, str]] = set()
    for c in paper.claims:
        for rd in paper.claim_readings(c):
            for q in (c.a, c.b):
                if q is not None:
                    columns.add(resolved(q, rd))
    rows: dict[str, list[dict]] = {}
    for u in units:
        rows[u.name] = []
        for v in u.variants:
            for r in range(runs):
                row: dict = {"run": r, "seed": r, "key": f"{v}-{r}", "error": None, "variant": v}
                for metric, statistic in columns:
                    if statistic == "time_mean_rms":
                        row.update({f"{metric}[{k:03d}]": float(rng.uniform(1, 2)) for k in range(5)})
                    else:
                        row[metric] = float(rng.uniform(1, 2))
                rows[u.name].append(row)
    return units, rows


@pytest.mark.parametrize("key", sorted(rp.PAPERS))
def test_one_run_per_quantity_gives_no_verdict(key):
    """``aquasim-py reproduce PAPER --runs 1`` (and any count below MIN_RUNS): no "holds" and
    no "does not hold" row; from MIN_RUNS runs the same claims get verdicts."""
    paper = rp.PAPERS[key]
    for runs in (1, rp.MIN_RUNS - 1):
        units, rows = _fake_rows(paper, paper.quick, runs)
        results = evaluate_claims(paper, paper.quick, paper.claims, rows, units)
        verdicts = {r.outcome.verdict for r in results}
        assert verdicts <= {"too few runs", "-"}, (runs, verdicts)
    units, rows = _fake_rows(paper, paper.quick, rp.MIN_RUNS)
    verdicts = {r.outcome.verdict for r in evaluate_claims(paper, paper.quick, paper.claims, rows, units)}
    assert verdicts & {"holds", "does not hold", "inconclusive"}


def _unit_of(paper: rp.Paper, scale: rp.Scale, claim_id: str, which: str = "a") -> rp.Unit:
    claim = next(c for c in paper.claims if c.id == claim_id)
    q = getattr(claim, which)
    units = rp.plan_units(paper, scale, [claim])
    (unit,) = [u for u in units if all(o in u.overrides for o in q.overrides) and q.variant in u.variants]
    return unit


@pytest.mark.parametrize("scale", ["quick", "full"])
def test_stvf_claims_run_at_the_papers_set_ups(scale):
    """Sec. 5.2.3's numbers at Ns = 200 (Nr = 3, Table 1's), Fig. 7's at Nr = 2 on the
    paper's accuracy metric (mean distance error), every run scored at every instant a node
    is localized, the after-training window a reading of the same runs."""
    paper = rp.PAPERS["stvf"]
    sc = getattr(paper, scale)
    for cid in ("avg_rmse", "below_avg", "converge5", "mean_iterations"):
        u = _unit_of(paper, sc, cid)
        loaded = u.load()
        assert loaded.nodes[1].params["n_samples"] == 200
        assert loaded.nodes[1].params.get("n_ref", 3) == 3
        assert loaded.metrics.warmup_s == 0.0
    for cid, which in (("stvf_vs_slmp_error", "a"), ("coverage_vs_slmp", "b")):
        u = _unit_of(paper, sc, cid, which)
        assert u.load().nodes[1].params["n_ref"] == 2
    claim = next(c for c in paper.claims if c.id == "stvf_vs_slmp_error")
    assert claim.a.metric == "stvf.mean_error_m" and claim.b.metric == "slmp.mean_error_m"
    window = next(r for r in paper.readings if r.window)
    assert window.window in sc.windows and resolved(claim.a, window)[0] == f"{window.window}.stvf.mean_error_m"
    assert paper.full.runs == 50  # "each simulation is run 50 times" (Sec. 5.1)


def test_itmtl_runs_figs_9_to_12_on_anchors_and_declares_fig_13():
    """Figs 9-12 with anchors as the only references (no promotion) by default; promotion a
    reading; the baselines (which never promote) on the same seeds; Fig. 13 a claim."""
    paper = rp.PAPERS["itmtl"]
    for cid in ("sync_vs_wsc", "nmse_vs_tshl", "wsc_sync_gap", "wsc_nmse_gap"):
        claim = next(c for c in paper.claims if c.id == cid)
        units = rp.plan_units(paper, paper.quick, [claim])
        default = [u for u in units if "itmtl" in u.variants and not any("=true" in o for o in u.overrides)]
        assert len(default) == 1 and default[0].load().nodes[1].params["promotion"] is False
        promoted = [u for u in units if any(o.endswith("promotion=true") for o in u.overrides)]
        assert len(promoted) == 1 and promoted[0].load().nodes[1].params["promotion"] is True
        for u in units:
            if "tshl" in u.variants:
                assert not u.overrides
    fig13 = next(c for c in paper.claims if c.figure == "Fig. 13")
    assert fig13.kind == "less" and fig13.b is not None and "nodes.1.params.imm=false" in fig13.b.overrides
    fig11 = next(c for c in paper.claims if c.id == "wsc_sync_gap")
    assert fig11.reduce == "max" and fig11.a.statistic == "interval_mean"  # "up to", per iteration


def test_statistics_and_numbers_are_the_papers():
    mswpf = rp.PAPERS["mswpf"]
    for c in mswpf.claims:
        assert c.a.statistic == "time_mean_rms", c.id  # eq 37
    pooled = next(r for r in mswpf.readings if r.metrics)
    assert set(pooled.metrics.values()) == {("mswpf.rmse_m", "rms")}
    imp = {c.id: c for c in mswpf.claims if c.kind == "gap_pct"}
    assert len(imp) == 5
    # the Improvement column is 100 (EW - GW) / EW of the table's own numbers
    gw = {c.overrides: c.paper for c in mswpf.claims if c.id.startswith("t1_gw_L")}
    ew = {c.overrides: c.paper for c in mswpf.claims if c.id.startswith("t1_ew_L")}
    for c in imp.values():
        if c.id.startswith("t1_"):
            assert 100 * (ew[c.overrides] - gw[c.overrides]) / ew[c.overrides] == pytest.approx(c.paper, abs=0.05)
    assert "L = 8" in next(c for c in mswpf.claims if c.id == "t3_gw").text
    ram = rp.PAPERS["ramezani"]
    assert ram.full.runs_by_scenario["track"] == 5000
    counts = {u.scenario.stem: u.runs for u in rp.plan_units(ram, ram.full, ram.claims, runs={"track": 500})}
    assert counts == {"ramezani_localization": 50, "ramezani_tracking": 500}  # --runs track=500
    for c in ram.claims:
        if c.kind == "ratio":
            assert c.bound
        if c.id.startswith("gna"):
            assert c.figure == "Fig. 4"
    for c in rp.PAPERS["svlpf"].claims:
        if c.paper_runs == "one":
            assert c.kind == "value" and c.a.statistic == "mean"
    assert any(c.paper_runs == "one" for c in rp.PAPERS["svlpf"].claims)


def test_consensus_is_kept_out_of_the_claims():
    sv = rp.PAPERS["svlpf"]
    for c in sv.claims:
        names = [q.metric for q in (c.a, c.b) if q is not None]
        if any("consensus" in n for n in names):
            assert c.kind == "reference" and "own construction" in c.text


def test_no_variant_is_named_a_bound():
    for paper in rp.PAPERS.values():
        for scale in (paper.quick, paper.full):
            for unit in rp.plan_units(paper, scale, paper.claims):
                assert not any(v and "bound" in v for v in unit.variants)
