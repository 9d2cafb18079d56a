"""Checks of a drawn figure from matplotlib's artists alone, written apart from
:mod:`aquasim_py.reporting.figures` (which makes the promises hold): a legend's box against the
display coordinates of every drawn data point, tick label boxes against each other, and legend
entries whose data are identical must carry a "coincides with" note."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
from matplotlib.collections import LineCollection, PathCollection, QuadMesh
from matplotlib.container import ErrorbarContainer


def _points(ax: Any) -> Iterator[tuple[str, np.ndarray]]:
    """(what, display coordinates) of every data point ``ax`` draws inside itself."""
    for line in ax.lines:
        yield f"line {line.get_label()!r}", line.get_transform().transform(np.asarray(line.get_xydata(), float))
    for coll in ax.collections:
        if isinstance(coll, PathCollection):
            off = np.asarray(coll.get_offsets(), float).reshape(-1, 2)
            yield f"points {coll.get_label()!r}", coll.get_offset_transform().transform(off)
        elif isinstance(coll, LineCollection):
            for seg in coll.get_segments():
                yield "error bar or stem", coll.get_transform().transform(np.asarray(seg, float))


def legend_over_data(fig: Any) -> list[str]:
    """Legends whose box holds a data point (or overlaps a bar or a mesh)."""
    renderer = fig.canvas.get_renderer()
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None] + list(fig.legends)
    found = []
    for leg in legends:
        box = leg.get_window_extent(renderer)
        for ax in fig.axes:
            inside_ax = ax.bbox
            for what, px in _points(ax):
                px = px[np.isfinite(px).all(axis=1)]
                shown = px[[inside_ax.contains(*p) for p in px]]
                if any(box.contains(*p) for p in shown):
                    found.append(f"legend over {what}")
            found += [
                f"legend over a bar {p.get_label()!r}"
                for p in ax.patches
                if p.get_window_extent(renderer).overlaps(box)
            ]
            meshes = [c for c in ax.collections if isinstance(c, QuadMesh)]
            found += ["legend over the mesh" for c in meshes if c.get_window_extent(renderer).overlaps(box)]
    return found


def legend_over_titles(fig: Any) -> list[str]:
    """Legends over the figure's title or a panel's title or axis label."""
    renderer = fig.canvas.get_renderer()
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None] + list(fig.legends)
    texts = [
        *fig.texts,
        *(t for ax in fig.axes if ax.get_visible() for t in (ax.title, ax.xaxis.label, ax.yaxis.label)),
    ]
    boxes = [(t.get_text(), t.get_window_extent(renderer)) for t in texts if t.get_text()]
    return [
        f"legend over {text!r}" for leg in legends for text, b in boxes if b.overlaps(leg.get_window_extent(renderer))
    ]


def overlapping_ticks(fig: Any) -> list[str]:
    """Pairs of tick labels (of one axis) whose boxes overlap."""
    renderer = fig.canvas.get_renderer()
    found = []
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            lo, hi = sorted(axis.get_view_interval())
            boxes = [
                (t.label1.get_text(), t.label1.get_window_extent(renderer))
                for t in (*axis.get_major_ticks(), *axis.get_minor_ticks())
                if t.label1.get_visible() and t.label1.get_text() and lo <= t.get_loc() <= hi
            ]
            found += [f"{a} / {b}" for i, (a, ba) in enumerate(boxes) for b, bb in boxes[i + 1 :] if ba.overlaps(bb)]
    return found


def unnoted_identical(fig: Any) -> list[str]:
    """Two legend entries of one axes that draw identical data, the later one without a
    "coincides with" note (in its label, or in the panel's title)."""
    found = []
    for ax in fig.axes:
        entries = []
        for c in ax.containers:
            if isinstance(c, ErrorbarContainer) and not c.get_label().startswith("_"):
                segs = [np.asarray(s, float) for b in c.lines[2] for s in b.get_segments()]
                entries.append((c.get_label(), [np.asarray(c.lines[0].get_xydata(), float), *segs]))
        in_containers = {id(c.lines[0]) for c in ax.containers if isinstance(c, ErrorbarContainer)}
        entries += [
            (line.get_label(), [np.asarray(line.get_xydata(), float)])
            for line in ax.lines
            if id(line) not in in_containers and not line.get_label().startswith("_")
        ]
        for i, (label, data) in enumerate(entries):
            for first, other in entries[:i]:
                same = len(data) == len(other) and all(
                    a.shape == b.shape and np.array_equal(a, b, equal_nan=True) for a, b in zip(data, other)
                )
                if same and len(data[0]) and "coincides with" not in label and "coincides with" not in ax.get_title():
                    found.append(f"{label!r} draws the data of {first!r} without a note")
    return found


def findings(fig: Any) -> list[str]:
    """Everything the checks above find in ``fig`` (drawn first)."""
    fig.draw_without_rendering()
    return legend_over_data(fig) + legend_over_titles(fig) + overlapping_ticks(fig) + unnoted_identical(fig)
