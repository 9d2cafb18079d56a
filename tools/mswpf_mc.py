"""Monte Carlo for the MSWPF tables: run a sweep file's jobs and keep every run's per-interval
errors (the paper's RMSE, eq 37, is over runs at each interval, then averaged over time).

    nice -n 10 python tools/mswpf_mc.py scenarios/mswpf_table1_sweep.toml --runs 100 --workers 2

Writes out/mswpf_mc/<sweep name>.csv (grid values, run, seed, step, error_m, n_reports, and per
run the wall time and mean filter-step time) and prints, per grid point, the paper's metric
(time average of the per-interval RMSE over runs) with a 95 % bootstrap CI over runs, and the
paired differences between weight schemes (common random numbers: run r has the same seed at
every grid point). Runs are the sweep's jobs (same seeds as ``aquasim-py sweep``); ``--runs``
keeps the first N of each grid point.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from aquasim_protocols.mswpf.metrics import step_errors
from aquasim_py import scenario as _scenario
from aquasim_py import sweep as _sweep


def run_one(base: dict[str, Any], path: str | None, job: _sweep.Job) -> pd.DataFrame:
    """One run: its per-interval errors with the job's grid values, seed and timings."""
    overrides = [(_scenario.parse_key_path(k), v) for k, v in job.point]
    sc = _scenario.load_dict(base, path, overrides=overrides, seed=job.seed)
    started = time.perf_counter()
    sim = _scenario.build(sc)
    sim.run(sc.simulation.duration_s)
    wall = time.perf_counter() - started
    tables = sim.trace.frames()
    e = step_errors(tables)[["step", "error", "n_selected", "n_reports"]].rename(columns={"error": "error_m"})
    for k, v in job.point:
        e[k] = v
    e["run"] = job.run
    e["seed"] = job.seed
    e["run_wall_s"] = wall
    tm = tables.get("mswpf_timing")
    e["step_ms"] = float(tm["step_ms"].mean()) if tm is not None and len(tm) else np.nan
    e["select_ms"] = float(np.nanmean(tm["select_ms"].to_numpy(float))) if tm is not None and len(tm) else np.nan
    return e


def paper_metric(df: pd.DataFrame) -> float:
    """Time average over intervals of sqrt(mean over runs of error^2) (eq 37, Table 1's number)."""
    return float(np.sqrt((df["error_m"] ** 2).groupby(df["step"]).mean()).mean())


def bootstrap_ci(df: pd.DataFrame, n_boot: int = 1000, seed: int = 0) -> tuple[float, float]:
    """95 % CI of :func:`paper_metric` by resampling runs (all intervals of a run together)."""
    piv = df.pivot_table(index="run", columns="step", values="error_m") ** 2
    A = piv.to_numpy()
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, A.shape[0], (n_boot, A.shape[0]))
    vals = np.sqrt(np.nanmean(A[idx], axis=1)).mean(axis=1)
    lo, hi = np.percentile(vals, [2.5, 97.5])
    return float(lo), float(hi)


def paired(df: pd.DataFrame, by: list[str], key: str, a: str, b: str, n_boot: int = 1000) -> tuple[float, float, float]:
    """Paired difference metric(a) - metric(b) over the same runs, with a 95 % bootstrap CI."""
    pa = df[df[key] == a].pivot_table(index="run", columns="step", values="error_m") ** 2
    pb = df[df[key] == b].pivot_table(index="run", columns="step", values="error_m") ** 2
    runs = pa.index.intersection(pb.index)
    A, B = pa.loc[runs].to_numpy(), pb.loc[runs].to_numpy()
    d = float(np.sqrt(np.nanmean(A, 0)).mean() - np.sqrt(np.nanmean(B, 0)).mean())
    rng = np.random.default_rng(1)
    idx = rng.integers(0, len(runs), (n_boot, len(runs)))
    bs = np.sqrt(np.nanmean(A[idx], 1)).mean(1) - np.sqrt(np.nanmean(B[idx], 1)).mean(1)
    lo, hi = np.percentile(bs, [2.5, 97.5])
    return d, float(lo), float(hi)


def summarize(df: pd.DataFrame, grid_keys: list[str]) -> str:
    lines = []
    wkey = next((k for k in grid_keys if k.endswith("weights")), None)
    others = [k for k in grid_keys if k != wkey]
    groups = df.groupby(others, sort=False) if others else [((), df)]
    for gval, g in groups:
        label = ", ".join(f"{k.split('.')[-1]}={v}" for k, v in zip(others, np.atleast_1d(gval)))
        parts = []
        for w, gw in g.groupby(wkey, sort=False) if wkey else [("-", g)]:
            lo, hi = bootstrap_ci(gw)
            parts.append(f"{w} {paper_metric(gw):6.2f} [{lo:5.2f}, {hi:5.2f}]")
        n = g["run"].nunique()
        lines.append(f"{label or 'all'} (runs={n}): " + "  ".join(parts))
        if wkey:
            ws = list(pd.unique(g[wkey]))
            for a, b in (("gw", "ew"), ("ew", "bw"), ("gw", "bw")):
                if a in ws and b in ws:
                    d, lo, hi = paired(g, others, wkey, a, b)
                    lines.append(f"    {a}-{b}: {d:+6.2f} m [{lo:+.2f}, {hi:+.2f}]")
        rep = 1.0 - g["n_reports"].sum() / max(g["n_selected"].sum(), 1)
        lines.append(f"    report loss {rep:.3f}, mean run wall {g.groupby('run')['run_wall_s'].first().mean():.2f} s")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sweep")
    ap.add_argument("--runs", type=int, default=None, help="first N runs of each grid point (default: the file's)")
    ap.add_argument("--first-run", type=int, default=0, help="skip runs below this index (extend a CSV)")
    ap.add_argument("--append", action="store_true", help="add the new runs to an existing CSV")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", default=None)
    ap.add_argument("--only", action="append", default=[], help="KEY=V1,V2: run only these grid values")
    ap.add_argument("--set", action="append", default=[], help="KEY=VALUE override of the base scenario")
    ap.add_argument("--summary-only", action="store_true", help="summarize an existing CSV")
    a = ap.parse_args(argv)
    sc = _scenario.load(a.sweep, overrides=a.set)
    assert sc.sweep is not None
    keys = list(sc.sweep.grid)
    out = Path(a.out or f"out/mswpf_mc/{sc.name}.csv")
    if not a.summary_only:
        only = {k: v.split(",") for k, v in (o.split("=", 1) for o in a.only)}
        jobs = [
            j
            for j in _sweep.plan(sc)
            if (a.runs is None or j.run < a.runs)
            and j.run >= a.first_run
            and all(str(v) in only.get(k, [str(v)]) for k, v in j.point)
        ]
        base = {k: v for k, v in sc.to_dict().items() if k != "sweep"}
        path = str(sc.path) if sc.path is not None else None
        frames: list[pd.DataFrame] = []
        t0 = time.perf_counter()
        if a.workers <= 1:
            for i, j in enumerate(jobs):
                frames.append(run_one(base, path, j))
                print(f"\r{i + 1}/{len(jobs)} runs, {time.perf_counter() - t0:.0f} s", end="", file=sys.stderr)
        else:
            with ProcessPoolExecutor(max_workers=a.workers) as pool:
                futs = [pool.submit(run_one, base, path, j) for j in jobs]
                for i, f in enumerate(as_completed(futs)):
                    frames.append(f.result())
                    print(f"\r{i + 1}/{len(jobs)} runs, {time.perf_counter() - t0:.0f} s", end="", file=sys.stderr)
        print(file=sys.stderr)
        if a.append and out.exists():
            frames.insert(0, pd.read_csv(out))
        df = pd.concat(frames, ignore_index=True).sort_values(keys + ["run", "step"], kind="stable")
        out.parent.mkdir(parents=True, exist_ok=True)
        df.to_csv(out, index=False)
    df = pd.read_csv(out)
    print(f"{sc.name}: {out}")
    print(summarize(df, keys))
    return 0


if __name__ == "__main__":
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    raise SystemExit(main())
