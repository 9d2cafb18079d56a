"""ALOHA's throughput against its theory, from a sweep of ``scenarios/mac_aloha.toml`` (or any
sweep with ``net.offered_load``, ``net.throughput`` and a ``variant`` column naming pure and
slotted ALOHA runs).

    aquasim-py sweep scenarios/mac_aloha.toml --out out/mac_aloha-sweep
    python tools/mac_theory.py out/mac_aloha-sweep [--markdown]

Per grid point: the runs' mean offered load G and throughput S with Student-t 95 % intervals
(:func:`aquasim_py.metrics.summarize_runs`), the theory at the measured G (pure: G e^(-2G),
slotted: G e^(-G); ``--slot-ratio`` for a slot longer than the frame: G e^(-G s / T)), and
S / theory - 1 with the interval of S carried over. ``--nodes N`` adds the finite population's
expectation (the own node never collides with itself: the exponent times (N - 1) / N).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from aquasim_py.metrics import summarize_runs


def table(sweep_dir: Path, slot_ratio: float = 1.0, nodes: int | None = None) -> pd.DataFrame:
    runs = pd.read_csv(sweep_dir / "sweep.csv")
    runs = runs[runs["error"].isna()] if "error" in runs.columns else runs
    keys = list(runs.columns[: list(runs.columns).index("run")])
    s = summarize_runs(runs, keys, ["net.offered_load", "net.throughput"])
    g = s[s["metric"] == "net.offered_load"].set_index(keys)
    th = s[s["metric"] == "net.throughput"].set_index(keys)
    out = pd.DataFrame(index=g.index)
    out["n"] = th["n"]
    out["G"] = g["mean"]
    out["G_ci"] = (g["ci95_high"] - g["ci95_low"]) / 2.0
    out["S"] = th["mean"]
    out["S_ci"] = (th["ci95_high"] - th["ci95_low"]) / 2.0
    variant = out.index.get_level_values("variant") if "variant" in keys else pd.Index(["pure"] * len(out))
    slotted = np.asarray(["slot" in str(v) for v in variant])
    k = np.where(slotted, slot_ratio, 2.0)
    out["theory"] = out["G"] * np.exp(-k * out["G"])
    out["S/theory-1 %"] = 100.0 * (out["S"] / out["theory"] - 1.0)
    out["CI %"] = 100.0 * out["S_ci"] / out["theory"]
    if nodes is not None:
        expect = out["G"] * np.exp(-k * out["G"] * (nodes - 1) / nodes)
        out[f"S/expected({nodes})-1 %"] = 100.0 * (out["S"] / expect - 1.0)
    return out.reset_index()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("sweep_dir", type=Path)
    ap.add_argument("--slot-ratio", type=float, default=1.001, help="slotted ALOHA's slot / frame time (default 1.001)")
    ap.add_argument("--nodes", type=int, help="the number of sources, for the finite population's expectation")
    ap.add_argument("--markdown", action="store_true", help="a Markdown table (for the docs)")
    args = ap.parse_args(argv)
    t = table(args.sweep_dir, args.slot_ratio, args.nodes)
    if args.markdown:  # (by hand: pandas' to_markdown needs tabulate, a docs-only package)
        cells = [[v if isinstance(v, str) else f"{v:.4g}" for v in row] for row in t.itertuples(index=False)]
        print("| " + " | ".join(map(str, t.columns)) + " |")
        print("|" + "---|" * len(t.columns))
        for row in cells:
            print("| " + " | ".join(row) + " |")
    else:
        with pd.option_context("display.width", 200, "display.max_columns", 30):
            print(t.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
