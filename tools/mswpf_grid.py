"""MSWPF parameter report: which eq 6 exponent k, source level S and threshold scheme reproduce
Table 1 (the paper does not give them legibly). The grid is declared in docs/mswpf.md.

    nice -n 10 python tools/mswpf_grid.py --run --workers 2   # 20 paired runs per point
    python tools/mswpf_grid.py                                  # score the CSVs

Each point runs ``scenarios/mswpf_table1_sweep.toml`` (L = 2, 4, 6, 8 x GW / EW / BW, r_x = 0,
ideal links) with its (k, S, scheme) set on both the channel and the fusion centre, runs 0-19
(the sweep's seeds, the same at every point), into out/mswpf_mc/grid_k<k>_S<S>_<scheme>.csv.
Score: D = sqrt(mean over the 12 cells of ln(ours / paper)^2) with a 95 % bootstrap CI over
runs, the mean log ratio, and D(point) - D(default) paired over the same runs.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
import mswpf_mc

GRID = [(1, "5e3"), (1, "5e4"), (2, "5e4"), (2, "5e5"), (2, "5e6")]
SCHEMES = ["pressure", "distance"]
DEFAULT = (1, "5e4", "pressure")
RUNS = 20
L, W = "nodes.1.params.levels", "nodes.1.params.weights"
LEVELS, WEIGHTS = [2, 4, 6, 8], ["gw", "ew", "bw"]
#: Table 1 of the paper (m), GW / EW / BW at L = 2, 4, 6, 8
PAPER = np.array([[27.05, 31.80, 31.92], [11.38, 13.95, 18.14], [7.312, 9.694, 14.3], [6.265, 8.581, 13.15]])


def csv_path(d: Path, k: int, S: str, scheme: str) -> Path:
    return d / f"grid_k{k}_S{S}_{scheme}.csv"


def run_point(d: Path, k: int, S: str, scheme: str, workers: int) -> None:
    sets = [
        f"channel.pressure_exponent={k}",
        f"nodes.1.params.exponent={k}",
        f"channel.pressure_source_level={S}",
        f"nodes.1.params.source_level={S}",
        f"nodes.1.params.threshold_scheme={scheme}",
    ]
    args = ["scenarios/mswpf_table1_sweep.toml", "--runs", str(RUNS), "--workers", str(workers)]
    args += [a for s in sets for a in ("--set", s)] + ["--out", str(csv_path(d, k, S, scheme))]
    mswpf_mc.main(args)


def squared_errors(df: pd.DataFrame) -> np.ndarray:
    """Squared errors (runs, 4 L, 3 schemes, steps) of the first RUNS runs."""
    df = df[df["run"] < RUNS]
    out = []
    for lv in LEVELS:
        row = []
        for w in WEIGHTS:
            g = df[(df[L] == lv) & (df[W] == w)]
            row.append(g.pivot_table(index="run", columns="step", values="error_m").to_numpy() ** 2)
        out.append(row)
    return np.asarray(out).transpose(2, 0, 1, 3)


def cells(E: np.ndarray) -> np.ndarray:
    """Table 1's metric (eq 37 averaged over time) per (L, scheme) from squared errors (runs, ...)."""
    return np.asarray(np.sqrt(E.mean(axis=0)).mean(axis=-1))


def score(T: np.ndarray) -> float:
    """RMS of ln(ours / paper) over the 12 cells."""
    return float(np.sqrt(np.mean(np.log(T / PAPER) ** 2)))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default="out/mswpf_mc")
    ap.add_argument("--run", action="store_true", help="run the points whose CSV is missing")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--boot", type=int, default=1000)
    ap.add_argument("--fig", default=None, help="draw Table 1's cells of every point beside the paper's (PNG)")
    a = ap.parse_args(argv)
    d = Path(a.dir)
    points = [(k, S, sch) for sch in SCHEMES for k, S in GRID]
    if a.run:
        for p in points:
            if not csv_path(d, *p).exists():
                run_point(d, *p, a.workers)
    E = {p: squared_errors(pd.read_csv(csv_path(d, *p))) for p in points if csv_path(d, *p).exists()}
    if DEFAULT not in E:
        print(f"missing {csv_path(d, *DEFAULT)}", file=sys.stderr)
        return 2
    rng = np.random.default_rng(0)
    idx = rng.integers(0, RUNS, (a.boot, RUNS))
    boot = {p: np.array([score(cells(e[i])) for i in idx]) for p, e in E.items()}
    print(
        f"{'k':>2} {'S':>5} {'thresholds':>10} | {'D':>5} [95 % CI]     | mean ln ratio (x) | D - D(default) [95 % CI]"
    )
    for p, e in E.items():
        T = cells(e)
        lo, hi = np.percentile(boot[p], [2.5, 97.5])
        dd = boot[p] - boot[DEFAULT]
        dlo, dhi = np.percentile(dd, [2.5, 97.5])
        m = float(np.mean(np.log(T / PAPER)))
        print(
            f"{p[0]:>2} {p[1]:>5} {p[2]:>10} | {score(T):5.2f} [{lo:4.2f}, {hi:4.2f}] | {m:+5.2f} (x{np.exp(m):4.2f})"
            f"       | {score(T) - score(cells(E[DEFAULT])):+5.2f} [{dlo:+5.2f}, {dhi:+5.2f}]"
        )
        for i, lv in enumerate(LEVELS):
            gw, ew, bw = T[i]
            print(f"{'':>20} L = {lv}: GW {gw:6.2f}  EW {ew:6.2f}  BW {bw:6.2f}  GW<EW<BW {gw < ew < bw}")
    if a.fig:
        figure({p: cells(e) for p, e in E.items()}, Path(a.fig))
    return 0


def figure(T: dict[tuple[int, str, str], np.ndarray], path: Path) -> None:
    """Average error vs L per scheme (panels GW / EW / BW), one line per grid point, the paper's
    Table 1 in black; log scale, so equal ratios look equal."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6), sharey=True)
    for j, (ax, w) in enumerate(zip(axes, WEIGHTS)):
        for p, t in T.items():
            ax.plot(LEVELS, t[:, j], "o-" if p[2] == "pressure" else "s--", ms=3, label=f"k={p[0]} S={p[1]} {p[2]}")
        ax.plot(LEVELS, PAPER[:, j], "k*-", lw=2, ms=8, label="paper (Table 1)")
        ax.set_yscale("log")
        ax.set_xticks(LEVELS)
        ax.set_xlabel("Quantization level L")
        ax.set_title(f"{w.upper()} ({RUNS} runs per point)")
    axes[0].set_ylabel("Average error (m)")
    fig.legend(*axes[0].get_legend_handles_labels(), fontsize=7, loc="center right")
    fig.tight_layout(rect=(0, 0, 0.84, 1))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
