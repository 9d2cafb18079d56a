"""One plot per reproduction: a small panel per claim, in the claim's own unit, with the
paper's number (a dashed line and its +-25 % band; 0 and the paper's side for an ordering) and
ours under each reading (a point with its 95 % CI, and the prediction interval of one run where
the paper's number is one run), coloured by verdict."""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import pandas as pd
from matplotlib.ticker import MaxNLocator

from aquasim_py.reporting.figures import DPI, plt

from .claims import REL_TOL
from .report import number_unit

__all__ = ["plot_claims"]

_COLOURS = {"holds": "#2a9d2a", "does not hold": "#c0392b", "inconclusive": "#b8860b"}


def plot_claims(table: pd.DataFrame, title: str, path: Path, ncols: int = 4) -> Path:
    """Draw ``claims.csv``'s rows (one panel per claim) into ``path`` (PNG)."""
    claims = list(dict.fromkeys(table["claim"]))
    readings = list(dict.fromkeys(table["reading"]))
    ncols = max(1, min(ncols, len(claims)))
    nrows = max(1, math.ceil(len(claims) / ncols))
    height = 0.9 + 0.28 * len(readings)
    fig, axes = plt.subplots(nrows, ncols, figsize=(3.6 * ncols, height * nrows + 0.6), squeeze=False)
    for ax in axes.flat[len(claims) :]:
        ax.set_visible(False)
    for ax, cid in zip(axes.flat, claims):
        g = table[table["claim"] == cid]
        first = next(iter(g.itertuples()))
        vals = [*g["ours"], *g["ci95_low"], *g["ci95_high"], first.paper_value]
        u = number_unit(str(first.kind), str(first.a_metric), vals)
        paper = float(first.paper_value)
        if math.isfinite(paper):
            if first.paper_runs != "one":  # a one-run number is judged by the prediction interval
                lo, hi = sorted((paper * (1 - REL_TOL), paper * (1 + REL_TOL)))
                ax.axvspan(lo / u.scale, hi / u.scale, color="0.9", lw=0)
            ax.axvline(paper / u.scale, color="k", ls="--", lw=1)
        elif first.kind == "less":
            ax.axvline(0.0, color="k", ls="--", lw=1)
        for r in g.itertuples():
            y = readings.index(r.reading)
            colour = _COLOURS.get(str(r.verdict), "0.5")
            if math.isfinite(r.pi95_low):
                ax.plot([r.pi95_low / u.scale, r.pi95_high / u.scale], [y, y], color=colour, lw=0.8, alpha=0.5)
            if math.isfinite(r.ci95_low):
                ax.plot([r.ci95_low / u.scale, r.ci95_high / u.scale], [y, y], color=colour, lw=2.5)
            ax.plot([r.ours / u.scale], [y], "o", color=colour, ms=4)
        ax.set_yticks(range(len(readings)))
        ax.set_yticklabels(readings, fontsize=7)
        ax.set_ylim(-0.7, len(readings) - 0.3)
        ax.invert_yaxis()
        ax.set_title(textwrap.fill(f"{cid} ({first.figure})", 48), fontsize=8)
        ax.tick_params(axis="x", labelsize=7)
        # unitless numbers far from 1 (an NMSE of 1e-4) in powers of ten: fixed-point labels
        # of such numbers are long and overlap
        ax.xaxis.set_major_locator(MaxNLocator(nbins=5))
        ax.ticklabel_format(axis="x", style="sci", scilimits=(-3, 4))
        ax.xaxis.get_offset_text().set_fontsize(7)
        ax.set_xlabel(f"{_what(str(first.kind))} ({u.unit})" if u.unit else _what(str(first.kind)), fontsize=7)
    handles = [plt.Line2D([], [], color=c, marker="o", lw=2.5, label=v) for v, c in _COLOURS.items()]
    handles.append(plt.Line2D([], [], color="0.5", marker="o", lw=2.5, label="too few runs / reference"))
    handles.append(plt.Line2D([], [], color="k", ls="--", label=f"paper (grey: +-{REL_TOL:.0%}); 0 for an ordering"))
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=7, frameon=False)
    fig.suptitle(f"{title}: ours (95 % CI; thin: one run's 95 % PI) against the paper", fontsize=9)
    fig.tight_layout(rect=(0, 0.5 / (height * nrows + 0.6), 1, 1))  # room for the legend below
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def _what(kind: str) -> str:
    return {"less": "a - b", "gap_pct": "gap", "ratio": "ratio"}.get(kind, "value")
