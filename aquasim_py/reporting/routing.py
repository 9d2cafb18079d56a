"""The routing page of a sweep report: delivery ratio, energy per delivered packet and end-to-end
delay against node density (or any other numeric key swept), one line per routing protocol.

Drawn from ``sweep.csv`` where it has ``net.pdr`` (a routed sweep, docs/metrics.md,
"Routing"): one panel per metric of :data:`PANELS` the sweep has, against its first numeric
grid key (the node count of a group: the density; a VBF pipe's radius), one line per
combination of the other keys (a variant: a protocol), each point the mean over runs with its
95 % interval (:func:`aquasim_py.reporting.sweep.lines`). The file keeps its name,
``sweep_net_routing_vs_density.png``, whatever the key.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from aquasim_py.reporting.figures import plt, save_figure
from aquasim_py.reporting.sweep import SweepData, lines, summary, value_texts, x_keys

__all__ = ["PANELS", "routing_plot"]

#: the panels, in order: (metric, axis label)
PANELS = (
    ("net.pdr", "packet delivery ratio"),
    ("energy.per_delivered_j", "energy per delivered packet (J)"),
    ("net.delay_s", "end-to-end delay (s)"),
)


def routing_plot(data: SweepData, path: Path) -> Path | None:
    """The panels of :data:`PANELS` against the density (module docstring); None when the
    sweep has no routing metrics or no numeric grid key."""
    if "net.pdr" not in data.metrics:
        return None
    numeric = [k for k in x_keys(data) if k in data.grid and k != "variant"]
    if not numeric:
        return None
    x = numeric[0]
    panels = [(m, label) for m, label in PANELS if m in data.metrics]
    table = summary(data, [m for m, _ in panels])
    texts = value_texts(x, data.grid[x])
    fig, axes = plt.subplots(1, len(panels), figsize=(4.6 * len(panels), 4.2), squeeze=False)
    for ax, (metric, label) in zip(axes[0], panels):
        centers, highs = [], []
        for ln in lines(data, x, metric, table):
            xs = np.array([float(v) for v in ln.x])
            err = np.nan_to_num(np.vstack([ln.center - ln.low, ln.high - ln.center]), nan=0.0)
            ax.errorbar(xs, ln.center, yerr=err, marker="o", ms=4, capsize=3, lw=1.2, label=ln.label(data))
            centers.append(ln.center)
            highs.append(ln.high)
        ax.set_xticks([float(v) for v in data.grid[x]], [texts.get(v, v) for v in data.grid[x]])
        ax.set_xlabel(x)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.25)
        top = 1.05 if metric == "net.pdr" else _top(centers, highs)
        if top is not None:
            ax.set_ylim(0.0, top)
    axes[0][0].legend(fontsize=8)
    n = int(data.runs.groupby(list(data.grid)).size().min()) if len(data.runs) else 0
    fig.suptitle(f"Routing against {x}\nmean and 95 % CI over runs (n >= {n} per point)", fontsize=10)
    return save_figure(fig, path)


def _top(centers: list[np.ndarray], highs: list[np.ndarray]) -> float | None:
    """The top of a panel's axis: the highest interval's end, but at most twice the highest mean
    (a point of few runs, e.g. a sparse network that delivered one packet, has an interval that
    would flatten every line; its bar runs off the axis instead). None: no finite mean."""
    c = np.concatenate(centers) if centers else np.array([])
    c = c[np.isfinite(c)]
    if not len(c) or c.max() <= 0.0:
        return None
    h = np.concatenate(highs)
    h = h[np.isfinite(h)]
    return 1.05 * float(min(h.max() if len(h) else c.max(), 2.0 * c.max()))
