"""MSWPF figures and the timing table from the Monte Carlo CSVs of tools/mswpf_mc.py.

    python tools/mswpf_figures.py [--dir out/mswpf_mc] [--out out/mswpf_figures]

Draws the per-interval RMSE curves (eq 37 over runs) of Figs. 5-7 (L = 4, 6, 8), Fig. 8 (time
average vs L), Figs. 9-11 (r_x = 2, 4, 6), Fig. 12 (vs r_x), Fig. 14 (GW with Ns = 3, 4, 5) and
Fig. 15 (GW-3, EW-3, EW-5) for whichever CSVs exist, and prints Table 4 (mean wall time of one
Monte Carlo run and of one filter step, 3-D, per L) from mswpf_table4_sweep.csv. Wall times
depend on the machine and its load; they are not part of any deterministic trace.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

W = "nodes.1.params.weights"
L = "nodes.1.params.levels"
RX = "nodes.0.sensors.position_noise_std_m"
NS = "nodes.1.params.n_select"


def rmse_curve(df: pd.DataFrame) -> pd.Series:
    """Per-interval RMSE over runs (eq 37)."""
    return np.sqrt((df["error_m"] ** 2).groupby(df["step"]).mean())


def curves(df: pd.DataFrame, key: str, value: object, title: str, path: Path) -> None:
    sub = df[df[key] == value]
    if sub.empty:
        return
    fig, ax = plt.subplots(figsize=(5, 3.2))
    for w, g in sub.groupby(W, sort=False):
        c = rmse_curve(g)
        ax.plot(c.index, c.values, label=f"{str(w).upper()} (avg {c.mean():.2f} m)")
    ax.set_xlabel("Time (s)")
    ax.set_ylabel("RMSE (m)")
    ax.set_title(f"{title} ({sub['run'].nunique()} MC runs)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def averages(df: pd.DataFrame, key: str, xlabel: str, path: Path) -> None:
    fig, ax = plt.subplots(figsize=(5, 3.2))
    for w, g in df.groupby(W, sort=False):
        xs = sorted(g[key].unique())
        ax.plot(xs, [rmse_curve(g[g[key] == x]).mean() for x in xs], "o-", label=str(w).upper())
    ax.set_xlabel(xlabel)
    ax.set_ylabel("Average error (m)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default="out/mswpf_mc")
    ap.add_argument("--out", default="out/mswpf_figures")
    a = ap.parse_args()
    d, out = Path(a.dir), Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    t1 = d / "mswpf_table1_sweep.csv"
    if t1.exists():
        df = pd.read_csv(t1)
        for num, lv in ((5, 4), (6, 6), (7, 8)):
            curves(df, L, lv, f"Fig. {num}: 2-D, L = {lv}", out / f"fig{num}_L{lv}.png")
        averages(df, L, "Quantization level L", out / "fig8_vs_L.png")
    t2 = d / "mswpf_table2_sweep.csv"
    if t2.exists():
        df = pd.read_csv(t2)
        for num, rx in ((9, 2.0), (10, 4.0), (11, 6.0)):
            curves(df, RX, rx, f"Fig. {num}: 2-D, r_x = r_y = {rx:g}", out / f"fig{num}_rx{rx:g}.png")
        averages(df, RX, "Node location noise r_x = r_y (m)", out / "fig12_vs_rx.png")
    t3 = d / "mswpf_table3_sweep.csv"
    if t3.exists():
        df = pd.read_csv(t3)
        fig, ax = plt.subplots(figsize=(5, 3.2))
        for (w, ns), g in df.groupby([W, NS], sort=False):
            if w == "gw" or (w == "ew" and ns in (3, 5)):
                c = rmse_curve(g)
                ax.plot(c.index, c.values, label=f"{str(w).upper()}-{ns} (avg {c.mean():.2f} m)")
        ax.set_xlabel("Time (s)")
        ax.set_ylabel("RMSE (m)")
        ax.set_title(f"Figs. 14-15: 3-D, GW / EW, Ns selected ({df['run'].nunique()} runs)", fontsize=10)
        ax.legend()
        fig.tight_layout()
        fig.savefig(out / "fig14_15_3d.png", dpi=120)
        plt.close(fig)
    t4 = d / "mswpf_table4_sweep.csv"
    if t4.exists():
        df = pd.read_csv(t4)
        runs = df.groupby([L, W, NS, "run"]).agg(wall=("run_wall_s", "first"), step=("step_ms", "first"))
        tab = runs.groupby([L, W, NS]).mean().reset_index()
        print("Table 4 (3-D): mean wall time of one MC run (s) / of one filter step (ms)")
        print(f"{'L':>3} " + " ".join(f"{c:>16}" for c in ("GW-3", "EW-3", "EW-5")))
        for lv, g in tab.groupby(L):
            cells = []
            for w, ns in (("gw", 3), ("ew", 3), ("ew", 5)):
                r = g[(g[W] == w) & (g[NS] == ns)]
                cells.append(f"{r['wall'].iloc[0]:7.2f} / {r['step'].iloc[0]:6.2f}" if len(r) else f"{'-':>16}")
            print(f"{lv:>3} " + " ".join(f"{c:>16}" for c in cells))
    print(f"figures in {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
