"""STVF vs SLMP vs the multilateration bound: the variants of a scenario over seeds (and node
densities), scored with the generic ``localization.*`` metrics and the Section-5 protocol
metrics; means with 95 % Student-t confidence intervals.

    python tools/stvf_compare.py scenarios/stvf_quick.toml --seeds 1-5
    python tools/stvf_compare.py scenarios/stvf_quick.toml --seeds 1-10 \\
        --densities 6 8 12 16 20 24 --set-stvf n_ref=2 --workers 2 --out out/stvf_fig7_quick
    python tools/stvf_compare.py scenarios/stvf.toml --seeds 1-10 --workers 2 --out out/stvf_table1

Density (expected nodes within range, STVF Sec. 5.3.1) is set through the range: r =
sqrt(density x area / (N pi)), applied to the channel and to every protocol's ``range_m``.
The variants are the scenario's ``[variants.*]`` tables (read here directly, so the tool
works before and after the generic variants loader). Writes ``runs.csv`` and ``summary.csv``
under ``--out`` and prints the summary.
"""

from __future__ import annotations

import argparse
import math
import tomllib
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy import stats

from aquasim_py import scenario
from aquasim_py.metrics import summarize

KEEP = (
    "localization.rmse_m",
    "localization.coverage",
    "localization.estimates",
    "avg_rmse_m",
    "share_below_avg",
    "mean_error_m",
    "rmse_m",
    "coverage",
    "converge_within_5",
    "relocalization_share",
)


def _seeds(text: str) -> list[int]:
    if "-" in text:
        a, b = text.split("-")
        return list(range(int(a), int(b) + 1))
    return [int(s) for s in text.split(",")]


def _variant_overrides(raw: dict[str, Any], density: float | None, extra: dict[str, list[str]]) -> dict[str, list]:
    """{variant: [(key, value), ...]} including the density's range and per-protocol --set."""
    variants = raw.get("variants") or {"as_written": {}}
    out: dict[str, list] = {}
    groups = raw["nodes"]
    for name, table in variants.items():
        ov: list[tuple[str, Any]] = list(table.items())
        protocols = [dict(ov).get(f"nodes.{i}.protocol", g["protocol"]) for i, g in enumerate(groups)]
        if density is not None:
            lo, hi = raw["environment"]["volume"]["lo"], raw["environment"]["volume"]["hi"]
            area = (hi[0] - lo[0]) * (hi[1] - lo[1])
            n = sum(int(g["count"]) for g in groups)
            r = math.sqrt(density * area / (n * math.pi))
            ov.append(("channel.max_range_m", r))
            ov += [(f"nodes.{i}.params.range_m", r) for i in range(len(groups))]
        for i, proto in enumerate(protocols):
            for item in extra.get(proto, []):
                k, v = item.split("=", 1)
                ov.append((f"nodes.{i}.params.{k}", scenario.parse_value(v)))
        out[name] = ov
    return out


def run_one(job: tuple[str, dict[str, Any], list, int, str, float | None]) -> dict[str, Any]:
    path, raw, overrides, seed, variant, density = job
    sc = scenario.load_dict(raw, path, overrides=[(scenario.parse_key_path(k), v) for k, v in overrides], seed=seed)
    sim = scenario.build(sc)
    sim.run(sc.simulation.duration_s)
    frames = sim.trace.frames()
    m = summarize(frames, warmup_s=sc.metrics.warmup_s)
    proto = sc.nodes[1].protocol
    # protocol metrics scored on the same window as the generic ones
    from aquasim_protocols.stvf.metrics import localization_metrics

    pm = localization_metrics(frames, proto, t_min=sc.metrics.warmup_s or None)
    row: dict[str, Any] = {"variant": variant, "seed": seed, "density": density}
    for k in KEEP:
        if k in m:
            row[k] = m[k]
        elif k in pm:
            row[k] = pm[k]
        elif f"{proto}.{k}" in m:
            row[k] = m[f"{proto}.{k}"]
    return row


def summary(runs: pd.DataFrame) -> pd.DataFrame:
    """Mean and 95 % t-interval half-width per (density, variant) of every numeric column."""
    cols = [c for c in KEEP if c in runs.columns]
    rows = []
    for (dens, var), g in runs.groupby(["density", "variant"], dropna=False, sort=True):
        row: dict[str, Any] = {"density": dens, "variant": var, "runs": len(g)}
        for c in cols:
            x = g[c].dropna().to_numpy(float)
            row[c] = x.mean() if len(x) else np.nan
            row[c + "_ci95"] = (
                stats.t.ppf(0.975, len(x) - 1) * x.std(ddof=1) / np.sqrt(len(x)) if len(x) > 1 else np.nan
            )
        rows.append(row)
    return pd.DataFrame(rows)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenario")
    ap.add_argument("--seeds", default="1-5")
    ap.add_argument("--densities", type=float, nargs="*", default=None)
    ap.add_argument("--set", dest="sets", action="append", default=[], help="KEY=VALUE for every variant")
    ap.add_argument("--set-stvf", action="append", default=[], help="PARAM=VALUE for the stvf nodes")
    ap.add_argument("--set-slmp", action="append", default=[], help="PARAM=VALUE for the slmp nodes")
    ap.add_argument("--variants", nargs="*", default=None)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", default="out/stvf_compare")
    a = ap.parse_args(argv)
    path = Path(a.scenario)
    raw = tomllib.loads(path.read_text())
    raw_base = {k: v for k, v in raw.items() if k != "variants"}
    for item in a.sets:
        k, v = item.split("=", 1)
        scenario.apply_override(raw_base, k, scenario.parse_value(v))
    extra = {"stvf": a.set_stvf, "slmp": a.set_slmp}
    jobs: list[tuple[str, dict[str, Any], list, int, str, float | None]] = []
    for dens in a.densities or [None]:
        for variant, ov in _variant_overrides(raw, dens, extra).items():
            if a.variants and variant not in a.variants:
                continue
            jobs.extend((str(path), raw_base, ov, seed, variant, dens) for seed in _seeds(a.seeds))
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    rows: list[dict[str, Any]] = []

    def keep(row: dict[str, Any]) -> None:
        # runs.csv grows as runs finish, so an interrupted sweep keeps what it did
        rows.append(row)
        pd.DataFrame(rows).to_csv(out / "runs.csv", index=False)

    if a.workers > 1:
        with ProcessPoolExecutor(a.workers) as ex:
            for row in ex.map(run_one, jobs):
                keep(row)
    else:
        for job in jobs:
            keep(run_one(job))
    runs = pd.DataFrame(rows)
    s = summary(runs)
    s.to_csv(out / "summary.csv", index=False)
    with pd.option_context("display.width", 200, "display.max_columns", 30):
        print(s.round(3).to_string(index=False))


if __name__ == "__main__":
    main()
