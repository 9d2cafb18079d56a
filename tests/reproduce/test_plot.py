"""claims.png: tick labels of unitless numbers far from 1 (an NMSE difference of 1e-4) stay
short enough not to overlap."""

from __future__ import annotations

import itertools
import math

import pandas as pd

from aquasim_py.reproduce import plot


def test_tick_labels_of_small_unitless_numbers_do_not_overlap(tmp_path, monkeypatch):
    rows = [
        {
            "claim": "nmse_vs_wsc",
            "figure": "Fig. 10",
            "kind": "less",
            "reading": reading,
            "a_metric": "localization.nmse",
            "paper_value": math.nan,
            "paper_runs": "",
            "ours": -1.15e-4 + k * 2e-5,
            "ci95_low": -1.58e-4 + k * 2e-5,
            "ci95_high": -7.12e-5 + k * 2e-5,
            "pi95_low": math.nan,
            "pi95_high": math.nan,
            "verdict": "holds",
        }
        for k, reading in enumerate(("round_trip", "model", "promotion"))
    ]
    figures = []
    monkeypatch.setattr(plot.plt, "close", figures.append)
    plot.plot_claims(pd.DataFrame(rows), "t", tmp_path / "claims.png")
    (fig,) = figures
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    ax = fig.axes[0]
    boxes = [t.get_window_extent(renderer) for t in ax.get_xticklabels() if t.get_text()]
    assert len(boxes) >= 3
    boxes.sort(key=lambda b: b.x0)
    assert all(a.x1 <= b.x0 for a, b in itertools.pairwise(boxes))
    assert ax.xaxis.get_offset_text().get_text()  # the power of ten beside the axis
