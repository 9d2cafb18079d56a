"""The network page of a sweep report: throughput S against offered load G, with the ALOHA
theory curves.

Drawn from ``sweep.csv`` where it has ``net.offered_load`` and ``net.throughput``
(docs/metrics.md, "Network"). Each grid point is one marker at its runs' arithmetic mean G
and S, with their Student-t 95 % intervals as error bars (:func:`aquasim_py.metrics.
summarize_runs`: the theory is a statement about means); the points of one combination of the
grid's text keys (a MAC, a variant) form a line, in increasing G, whatever numeric key set
the load. The curves are pure ALOHA's S = G e^(-2G) and slotted ALOHA's S = G e^(-G)
(Poisson traffic, many nodes at one distance from one receiver, no capture).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from aquasim_py.reporting.figures import plt, save_figure
from aquasim_py.reporting.sweep import SweepData, point_label, text_keys

__all__ = ["LOAD", "THROUGHPUT", "aloha_throughput", "load_points", "throughput_plot"]

LOAD = "net.offered_load"
THROUGHPUT = "net.throughput"


def aloha_throughput(g: np.ndarray, slotted: bool = False) -> np.ndarray:
    """ALOHA's throughput at offered load ``g`` (frames per frame time): G e^(-2G) pure
    (Abramson 1970), G e^(-G) slotted (Roberts 1975)."""
    g = np.asarray(g, dtype=float)
    return g * np.exp(-(1.0 if slotted else 2.0) * g)


def load_points(data: SweepData) -> pd.DataFrame:
    """Per grid point (the grid keys' columns): ``n`` runs, mean and 95 % interval of G and S
    (``g``, ``g_low``, ``g_high``, ``s``, ``s_low``, ``s_high``), in the sweep's order."""
    from aquasim_py.metrics import summarize_runs

    keys = list(data.grid)
    s = summarize_runs(data.runs, keys, [LOAD, THROUGHPUT])
    wide = []
    for metric, name in ((LOAD, "g"), (THROUGHPUT, "s")):
        m = s[s["metric"] == metric].set_index(keys)
        wide.append(
            m[["n", "mean", "ci95_low", "ci95_high"]].rename(
                columns={"n": f"n_{name}", "mean": name, "ci95_low": f"{name}_low", "ci95_high": f"{name}_high"}
            )
        )
    out = wide[0].join(wide[1], how="inner").reset_index()
    out["n"] = out[["n_g", "n_s"]].min(axis=1)
    return out.drop(columns=["n_g", "n_s"])


def throughput_plot(data: SweepData, path: Path) -> Path | None:
    """S against G per line (module docstring); None when the
    sweep has no network metrics."""
    if LOAD not in data.metrics or THROUGHPUT not in data.metrics:
        return None
    pts = load_points(data)
    if pts.empty:
        return None
    categories = text_keys(data)
    fig, ax = plt.subplots(figsize=(7.0, 4.8))
    groups = pts.groupby(categories, sort=False) if categories else [((), pts)]
    for combo, g in groups:
        g = g.sort_values("g")
        values = dict(zip(categories, combo if isinstance(combo, tuple) else (combo,)))
        err_g = np.nan_to_num(np.vstack([g["g"] - g["g_low"], g["g_high"] - g["g"]]), nan=0.0)
        err_s = np.nan_to_num(np.vstack([g["s"] - g["s_low"], g["s_high"] - g["s"]]), nan=0.0)
        label = point_label(data, values) if values else "measured"
        # markers only: a straight line between two points would read as a curve below the theory
        ax.errorbar(g["g"], g["s"], xerr=err_g, yerr=err_s, marker="o", ms=5, capsize=3, ls="none", label=label)
    hi = float(np.nanmax(pts["g_high"].fillna(pts["g"])))
    gg = np.linspace(0.0, max(hi, 0.1) * 1.05, 400)
    ax.plot(gg, aloha_throughput(gg), "k--", lw=1.0, label="pure ALOHA, G e^(-2G)")
    ax.plot(gg, aloha_throughput(gg, slotted=True), "k:", lw=1.2, label="slotted ALOHA, G e^(-G)")
    ax.set_xlabel("offered load G (frames per frame time)")
    ax.set_ylabel("throughput S (frames per frame time)")
    n = int(pts["n"].min())
    ax.set_title(f"Throughput against offered load\nmean and 95 % CI over runs (n >= {n} per point)", fontsize=10)
    ax.set_xlim(left=0.0)
    ax.set_ylim(bottom=0.0)
    ax.grid(True, alpha=0.25)
    ax.legend(fontsize=8)
    return save_figure(fig, path)
