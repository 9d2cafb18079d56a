"""``aquasim-py reproduce`` end to end: a tiny reproduction and its outputs, the runs read
again over a window, resume after a kill, progress in a log, and bad input. The real
``--quick`` of each paper is marked slow. Claims as data: tests/reproduce/."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from aquasim_py import reproduce as rp
from aquasim_py.cli import main
from aquasim_py.reproduce.runner import run_units

ROOT = Path(__file__).resolve().parents[1]
# two STVF claims on 2 seeds of a 25-s network: a few seconds
TINY = ["stvf", "--quick", "--only", "avg_rmse", "--only", "stvf_vs_slmp_error", "--runs", "2"]
TINY_SETS = ["--set", "simulation.duration_s=25.0"]
ONE_UNIT = ["stvf", "--quick", "--only", "avg_rmse"]  # STVF's two readings at Ns = 200: one unit


# ------------------------------------------------------------------------------- end to end
def test_tiny_reproduction_writes_claims_and_page(tmp_path, capsys):
    out = tmp_path / "r"
    assert main(["reproduce", *TINY, *TINY_SETS, "--workers", "1", "--out", str(out)]) == 0
    t = pd.read_csv(out / "claims.csv", keep_default_na=False)
    assert set(t["claim"]) == {"avg_rmse", "stvf_vs_slmp_error"}
    assert set(t["reading"]) == {"printed", "text", "printed_after_training", "text_after_training"}
    assert (t["n"] == 2).all()
    assert set(t["verdict"]) == {"too few runs"}  # 2 runs: no verdict
    assert {"paper_in_ci", "pi95_low", "flag", "unit"} <= set(t.columns)
    # the set-ups the claims ran in (Sec. 5.2.3 at Ns = 200, Fig. 7 at Nr = 2 on the mean error)
    avg = t[t["claim"] == "avg_rmse"]
    assert avg["a_overrides"].str.contains("n_samples=200").all()
    fig7 = t[t["claim"] == "stvf_vs_slmp_error"]
    assert fig7["a_overrides"].str.contains("n_ref=2").all() and not fig7["b_overrides"].str.contains("n_ref").any()
    assert set(fig7["a_metric"]) == {"stvf.mean_error_m", "after_training.stvf.mean_error_m"}
    assert (t.loc[t["claim"] == "avg_rmse", "paper_value"].astype(float) == 7.09).all()
    assert (t["unit"] == "m").all()
    num = t[["ci95_low", "ours", "ci95_high"]].astype(float)
    assert (num["ci95_low"] <= num["ours"]).all() and (num["ours"] <= num["ci95_high"]).all()
    # the after-training window is read from the same runs, and differs
    a = t[t["claim"] == "avg_rmse"].set_index("reading")["ours"].astype(float)
    assert a["printed"] != a["printed_after_training"]
    page = (out / "index.html").read_text()
    assert "avg_rmse" in page and "7.09" in page and "aquasim-py reproduce" in page and "claims.png" in page
    assert (out / "claims.png").stat().st_size > 10_000
    info = json.loads((out / "reproduce.json").read_text())
    assert info["paper"] == "stvf" and info["runs_per_quantity"] == [2] and info["cpu_time_s"] > 0
    # STVF at Nr = 2 and SLMP in units of their own, on the same seeds (paired by run)
    units = {u.name: pd.read_csv(u / "sweep.csv") for u in (out / "units").iterdir()}
    assert len(units) == 3
    seeds = {tuple(sorted(set(df["seed"]))) for df in units.values()}
    assert len(seeds) == 1
    assert not any((u / "traces").exists() for u in (out / "units").iterdir())  # read again, then removed
    printed = capsys.readouterr()
    assert " m [" in printed.out and "n = 2" in printed.out and "too few runs" in printed.out
    # not a terminal: whole progress lines, no carriage returns
    assert "\r" not in printed.err and printed.err.count("runs\n") >= 3


def test_a_window_at_zero_reads_the_runs_own_metrics(tmp_path):
    """The metrics read again from a run's traces over a window from t = 0 are the run's own:
    the re-reading changes nothing but the window."""
    stvf = rp.PAPERS["stvf"]
    paper = dataclasses.replace(stvf, readings=(rp.Reading("all", "every row, re-read", window="all"),))
    claim = next(c for c in paper.claims if c.id == "coverage_vs_slmp")
    scale = rp.Scale(paper.quick.scenarios, 1, paper.quick.overrides, windows={"all": 0.0})
    units = [u for u in rp.plan_units(paper, scale, [claim], sets=TINY_SETS[1:]) if "slmp" in u.variants]
    rows = run_units(units, tmp_path, workers=1)
    (row,) = [r for r in rows[units[0].name] if r["variant"] == "slmp"]
    shared = [k for k in row if k.startswith("all.")]
    assert len(shared) > 10
    for k in shared:
        assert row[k] == pytest.approx(row[k[len("all.") :]], rel=1e-12, nan_ok=True), k


@pytest.mark.slow  # a reproduction killed and resumed; the journal it resumes from is the sweep's (test_sweep)
def test_resume_after_a_kill_runs_only_the_missing_runs(tmp_path):
    out = tmp_path / "r"
    cmd = [
        sys.executable,
        "-m",
        "aquasim_py.cli",
        "reproduce",
        *ONE_UNIT,
        *TINY_SETS,
        "--workers",
        "1",
        "--out",
        str(out),
    ]
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
    assert 2 <= len(before) < 6 and not (out / "claims.csv").exists()
    assert (
        main(["reproduce", *ONE_UNIT, *TINY_SETS, "--runs", "3", "--workers", "1", "--out", str(out), "--resume"]) == 0
    )
    after = [json.loads(x)["key"] for x in journal.read_text().splitlines()]
    assert after[: len(before)] == before  # kept
    assert len(after) == 6 and len(set(after)) == 6  # 2 variants x 3 seeds, none run twice
    assert (out / "claims.csv").exists()


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["nosuch"], "unknown paper 'nosuch'"),
        (["stvf", "--quick", "--full"], "not allowed with argument"),
        (["stvf", "--only", "nosuch"], "has no claim 'nosuch'"),
        (["stvf", "--runs", "0"], "positive integer"),
        (["ramezani", "--full", "--runs", "nosuch=3"], "no scenario 'nosuch'"),
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
