"""``aquasim-py reproduce``: claims as data, verdicts, a tiny reproduction end to end, resume
after a kill, and bad input. The real ``--quick`` of each paper is marked slow."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from aquasim_py import reproduce as rp
from aquasim_py.cli import main
from aquasim_py.reproduce.claims import Claim, Quantity
from aquasim_py.reproduce.verdict import evaluate

ROOT = Path(__file__).resolve().parents[1]
# two STVF claims on 2 seeds of a 25-s network: a few seconds
TINY = ["stvf", "--quick", "--only", "avg_rmse", "--only", "stvf_vs_slmp_rmse", "--runs", "2"]
TINY_SETS = ["--set", "simulation.duration_s=25.0"]


# ------------------------------------------------------------------------------- the claims
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
        assert c.kind == "reference" or c.paper is not None or c.kind == "less"
        assert paper.claim_readings(c), c.id


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


# ------------------------------------------------------------------------------- verdicts
def _claim(kind, paper=None, stat="mean", **kw):
    return Claim("c", "Fig. 1", "x", kind, Quantity("m", "a", statistic=stat), "s", paper=paper, **kw)


def test_value_verdict_uses_the_band_on_the_t_interval():
    rng = np.random.default_rng(1)
    x = 10 + rng.normal(0, 0.5, 40)
    assert evaluate(_claim("value", 10.0), x, None).verdict == "holds"
    assert evaluate(_claim("value", 20.0), x, None).verdict == "does not hold"
    wide = 10 + rng.normal(0, 20, 5)
    assert evaluate(_claim("value", 10.0), wide, None).verdict == "tie"
    o = evaluate(_claim("value", 10.0), x, None)
    from scipy import stats

    half = stats.t.ppf(0.975, 39) * x.std(ddof=1) / np.sqrt(40)
    assert (o.low, o.high) == pytest.approx((x.mean() - half, x.mean() + half))


def test_less_is_paired_and_rms_is_pooled():
    rng = np.random.default_rng(2)
    common = rng.normal(0, 5, 30)  # shared luck of each seed: pairing removes it
    a, b = 10 + common, 10.3 + common + rng.normal(0, 0.1, 30)
    c = Claim("c", "f", "x", "less", Quantity("m", "a"), "s", b=Quantity("m", "b"))
    assert evaluate(c, a, b).verdict == "holds"
    assert evaluate(c, b, a).verdict == "does not hold"
    r = evaluate(_claim("value", 5.0, "rms"), np.array([3.0, 4.0, 5.0, 6.0]), None)
    assert r.ours == pytest.approx(np.sqrt(np.mean([9, 16, 25, 36])))
    assert r.low <= r.ours <= r.high


def test_gap_pct_and_missing_runs():
    c = Claim("c", "f", "x", "gap_pct", Quantity("m", "a"), "s", b=Quantity("m", "b"), paper=50.0)
    a = np.array([1.0, 1.0, 1.0, np.nan])
    b = np.array([1.5, 1.5, 1.5, 9.0])
    o = evaluate(c, a, b)
    assert o.n == 3 and o.ours == pytest.approx(50.0) and o.verdict == "holds"
    assert evaluate(c, np.array([np.nan]), np.array([1.0])).verdict == "-"


# ------------------------------------------------------------------------------- end to end
def test_tiny_reproduction_writes_claims_and_page(tmp_path, capsys):
    out = tmp_path / "r"
    assert main(["reproduce", *TINY, *TINY_SETS, "--workers", "1", "--out", str(out), "--quiet"]) == 0
    t = pd.read_csv(out / "claims.csv")
    assert set(t["claim"]) == {"avg_rmse", "stvf_vs_slmp_rmse"}
    assert set(t["reading"]) == {"printed", "text"}
    assert (t["n"] == 2).all()
    assert set(t["verdict"]) <= {"holds", "does not hold", "tie"}
    assert (t.loc[t["claim"] == "avg_rmse", "paper_value"] == 7.09).all()
    assert (t["ci95_low"] <= t["ours"]).all() and (t["ours"] <= t["ci95_high"]).all()
    page = (out / "index.html").read_text()
    assert "avg_rmse" in page and "7.09" in page and "aquasim-py reproduce" in page
    info = json.loads((out / "reproduce.json").read_text())
    assert info["paper"] == "stvf" and info["runs_per_quantity"] == 2
    # one unit: both readings' variants on the same seeds (paired)
    (unit,) = (out / "units").iterdir()
    rows = pd.read_csv(unit / "sweep.csv")
    assert sorted(set(rows["variant"])) == ["slmp", "stvf", "stvf_text"]
    assert rows.groupby("variant")["seed"].apply(sorted).apply(tuple).nunique() == 1


@pytest.mark.slow  # a reproduction killed and resumed; the journal it resumes from is the sweep's (test_sweep)
def test_resume_after_a_kill_runs_only_the_missing_runs(tmp_path):
    out = tmp_path / "r"
    cmd = [sys.executable, "-m", "aquasim_py.cli", "reproduce", *TINY, *TINY_SETS, "--workers", "1", "--out", str(out)]
    cmd += ["--quiet", "--runs", "3"]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    journal = None
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:  # kill it once some, not all, runs are journalled
        found = list(out.glob("units/*/rows.jsonl"))
        if found and found[0].read_text().count("\n") >= 2:
            journal = found[0]
            break
        time.sleep(0.1)
    assert journal is not None, "no run finished in time"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    before = [json.loads(x)["key"] for x in journal.read_text().splitlines() if x.strip().endswith("}")]
    assert 2 <= len(before) < 9 and not (out / "claims.csv").exists()
    assert main(["reproduce", *TINY, *TINY_SETS, "--runs", "3", "--workers", "1", "--out", str(out), "--resume"]) == 0
    after = [json.loads(x)["key"] for x in journal.read_text().splitlines()]
    assert after[: len(before)] == before  # kept
    assert len(after) == 9 and len(set(after)) == 9  # 3 variants x 3 seeds, none run twice
    assert (out / "claims.csv").exists()


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["nosuch"], "unknown paper 'nosuch'"),
        (["stvf", "--quick", "--full"], "not allowed with argument"),
        (["stvf", "--only", "nosuch"], "has no claim 'nosuch'"),
        (["stvf", "--runs", "0"], "positive integer"),
        (["stvf", "--set", "simulation.duration_s=-1"], "duration_s"),
        (["stvf", "--workers", "2", "--scheduler", "tcp://x:1"], "not allowed with argument"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, args, needle):
    assert main(["reproduce", *args, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("error:") and needle in err
    assert not (tmp_path / "o").exists()


# ------------------------------------------------------------------------------- paper scale
@pytest.mark.slow
@pytest.mark.parametrize("key", sorted(rp.PAPERS))
def test_quick_reproduction_of_each_paper(tmp_path, key):
    """The real --quick of each paper exits 0 and writes one row per claim and reading."""
    out = tmp_path / key
    assert main(["reproduce", key, "--quick", "--workers", "2", "--out", str(out), "--quiet"]) == 0
    t = pd.read_csv(out / "claims.csv")
    paper = rp.PAPERS[key]
    assert len(t) == sum(len(paper.claim_readings(c)) for c in paper.claims)
    assert t["n"].min() >= 1
