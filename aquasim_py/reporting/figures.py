"""What every report plot shares, and the checks that keep it readable.

matplotlib runs on its file-only Agg backend (imported before pyplot by every report module,
so that no report opens a window, also on a machine without a display); figures come from
:func:`subplots` (constrained layout, which makes room for legends outside the axes) and are
written by :func:`save_figure`, which first makes three promises hold (:func:`finish`):

- **every labelled series can be seen.** Series drawn on the same path (each within
  :data:`TOL_PX` of the other over at least :data:`COINCIDE_FRACTION` of its length, in the
  figure as drawn: the same data, or data closer than a line's width) are drawn in turns: the
  first solid, each later one dashed with its dashes where the others leave gaps (hollow
  markers, larger), so every colour shows along the common path; the later ones' legend
  entries say ``(coincides with FIRST)`` (a series named by its label up to a parenthesis), or, where the legend is the figure's (small
  multiples), the panel's title does;
- **no legend covers data.** A legend inside the axes that covers a drawn point or line, a bar,
  a mesh, a filled area or a text moves outside, to the right of its axes;
- **no tick labels overlap.** Crowded numeric ticks are thinned, crowded categories slanted,
  and a log axis drops its minor labels first.

:func:`problems` lists what still breaks a promise in a figure as drawn: the report tests run
it on every figure the reports save. :func:`dodge` spreads several series' points at one x so
that their error bars stay apart.
"""

from __future__ import annotations

import weakref
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np

matplotlib.use("Agg")  # reports are files: never a window

import matplotlib.pyplot as plt  # after the backend is chosen
from matplotlib import cbook
from matplotlib.category import StrCategoryLocator
from matplotlib.collections import Collection, LineCollection, PathCollection, QuadMesh
from matplotlib.container import ErrorbarContainer
from matplotlib.legend import Legend
from matplotlib.lines import Line2D
from matplotlib.text import Text
from matplotlib.ticker import FixedLocator, LogLocator, MaxNLocator, NullFormatter
from matplotlib.transforms import Bbox, ScaledTranslation

__all__ = [
    "COINCIDE_FRACTION",
    "DPI",
    "TOL_PX",
    "coincides",
    "dodge",
    "finish",
    "plt",
    "problems",
    "save_figure",
    "subplots",
]

DPI = 110
#: a series whose drawn path lies within this many pixels of another's is hidden under it
#: where they meet (report lines are 1-1.5 pt wide: 1.5-2.3 px at :data:`DPI`)
TOL_PX = 1.5
#: two series coincide when each lies within :data:`TOL_PX` of the other over this fraction of
#: its drawn length
COINCIDE_FRACTION = 0.75
#: the least room between two tick labels
GAP_PX = 3.0
NOTE = "coincides with"
_STEP_PX = 0.5  # lines are sampled every half pixel along their drawn path


def subplots(nrows: int = 1, ncols: int = 1, **kw: Any) -> tuple[Any, Any]:
    """:func:`matplotlib.pyplot.subplots` with the constrained layout every report figure uses."""
    return plt.subplots(nrows, ncols, layout="constrained", **kw)


def save_figure(fig: Any, path: Path) -> Path:
    """:func:`finish` the figure, write ``path`` as PNG and close ``fig``; returns ``path``."""
    finish(fig)
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def dodge(ax: Any, i: int, k: int, step_pt: float = 7.0) -> Any:
    """The transform that draws series ``i`` of ``k`` sharing their x values ``(i - (k - 1) / 2)
    * step_pt`` points to the side, so that their points and error bars stay apart at any
    scale (their data stay as they are)."""
    shift = (i - (k - 1) / 2) * step_pt / 72.0
    return ax.transData + ScaledTranslation(shift, 0.0, ax.figure.dpi_scale_trans)


# -- the series as drawn --------------------------------------------------------------------------


@dataclass
class _Series:
    """One labelled series of an axes as drawn: the artist that carries its label, its line
    (restyled when it coincides with another) and the display coordinates along what it draws."""

    label: str
    artist: Any
    line: Line2D | None
    px: np.ndarray
    data: tuple[np.ndarray, ...]

    def same_data(self, other: _Series) -> bool:
        """Whether the two series draw the same data (NaNs alike; nothing is not data: an empty
        legend proxy coincides with nothing)."""
        if not any(a.size for a in self.data):
            return False
        return len(self.data) == len(other.data) and all(
            a.shape == b.shape and np.array_equal(a, b, equal_nan=True) for a, b in zip(self.data, other.data)
        )


def _labelled(label: object) -> bool:
    return isinstance(label, str) and bool(label) and not label.startswith("_")


def _densify(px: np.ndarray, closed: bool = False) -> np.ndarray:
    """Points every :data:`_STEP_PX` along the polyline ``px`` ((n, 2) display coordinates;
    a non-finite point breaks it)."""
    if closed and len(px):
        px = np.vstack([px, px[:1]])
    if len(px) < 2:
        return px[np.isfinite(px).all(axis=1)]
    seg = px[1:] - px[:-1]
    ok = np.isfinite(seg).all(axis=1)
    length = np.where(ok, np.hypot(seg[:, 0], seg[:, 1]), 0.0)
    n = np.clip(np.ceil(length / _STEP_PX), 0, 20_000).astype(int)
    idx = np.repeat(np.arange(len(seg)), n)
    k = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
    pts = px[idx] + (k / np.maximum(n[idx], 1))[:, None] * seg[idx]
    ends = px[np.isfinite(px).all(axis=1)]
    return np.vstack([pts, ends])


def _xy(line: Line2D) -> np.ndarray:
    return np.asarray(line.get_xydata(), dtype=float).reshape(-1, 2)


def _line_px(line: Line2D) -> np.ndarray:
    """Display coordinates along a Line2D as drawn (its steps, its segments sampled; only its
    vertices when it draws markers alone)."""
    xy = _xy(line)
    style = line.get_drawstyle()
    if style in cbook.STEP_LOOKUP_MAP and style != "default" and len(xy):
        xy = np.column_stack(cbook.STEP_LOOKUP_MAP[style](xy[:, 0], xy[:, 1]))
    px = line.get_transform().transform(xy)
    if line.get_linestyle() in ("None", "none", " ", "") or line.get_linewidth() == 0:
        return px[np.isfinite(px).all(axis=1)]
    return _densify(px)


def _collection_px(coll: Collection) -> np.ndarray:
    """Display coordinates of what a collection draws: a scatter's points, the sampled
    segments of a line collection (error bars, stems)."""
    if isinstance(coll, LineCollection):
        segs = [coll.get_transform().transform(np.asarray(s, dtype=float)) for s in coll.get_segments() if len(s)]
        return np.vstack([_densify(s) for s in segs]) if segs else np.empty((0, 2))
    if isinstance(coll, PathCollection):
        off = np.asarray(coll.get_offsets(), dtype=float).reshape(-1, 2)
        return coll.get_offset_transform().transform(off)
    return np.empty((0, 2))


def _in_axes(ax: Any, px: np.ndarray) -> np.ndarray:
    """The points drawn inside the axes (the rest is clipped away)."""
    if not len(px):
        return px
    b = ax.bbox
    keep = (px[:, 0] >= b.x0 - 0.5) & (px[:, 0] <= b.x1 + 0.5) & (px[:, 1] >= b.y0 - 0.5) & (px[:, 1] <= b.y1 + 0.5)
    return px[keep]


def _series(ax: Any) -> list[_Series]:
    """The labelled series of ``ax`` in drawing order: lines, error-bar plots, scatters."""
    out: list[_Series] = []
    inside: set[int] = set()
    for c in ax.containers:
        parts = [a for a in cbook.flatten(c) if a is not None]
        inside |= {id(a) for a in parts}
        if isinstance(c, ErrorbarContainer) and _labelled(c.get_label()):
            data_line = c.lines[0]
            px = _line_px(data_line) if data_line is not None else np.empty((0, 2))
            bars = [_collection_px(b) for b in c.lines[2]]
            data = [_xy(data_line)] if data_line is not None else []
            data += [np.asarray(seg, dtype=float) for b in c.lines[2] for seg in b.get_segments()]
            out.append(_Series(str(c.get_label()), c, data_line, _in_axes(ax, np.vstack([px, *bars])), tuple(data)))
    out += [
        _Series(line.get_label(), line, line, _in_axes(ax, _line_px(line)), (_xy(line),))
        for line in ax.lines
        if id(line) not in inside and _labelled(line.get_label())
    ]
    for coll in ax.collections:
        if id(coll) not in inside and isinstance(coll, PathCollection) and _labelled(coll.get_label()):
            off = np.asarray(coll.get_offsets(), dtype=float)
            out.append(_Series(str(coll.get_label()), coll, None, _in_axes(ax, _collection_px(coll)), (off,)))
    return out


def _covered_fraction(a: np.ndarray, b: np.ndarray) -> float:
    """The fraction of the display points ``a`` that fall on a pixel within :data:`TOL_PX` of
    one of the points ``b`` (both rounded to pixels; the pixels around ``b`` marked on a grid)."""
    if not len(a) or not len(b):
        return 0.0
    reach = int(np.floor(TOL_PX))
    ia, ib = np.rint(a).astype(np.int64), np.rint(b).astype(np.int64)
    lo = np.minimum(ia.min(axis=0), ib.min(axis=0)) - reach
    size = np.maximum(ia.max(axis=0), ib.max(axis=0)) - lo + reach + 1
    near = np.zeros((int(size[0]), int(size[1])), dtype=bool)
    for dx in range(-reach, reach + 1):
        for dy in range(-reach, reach + 1):
            if dx * dx + dy * dy <= TOL_PX * TOL_PX:
                near[ib[:, 0] - lo[0] + dx, ib[:, 1] - lo[1] + dy] = True
    return float(np.mean(near[ia[:, 0] - lo[0], ia[:, 1] - lo[1]]))


def _apart(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether the boxes around two point sets (grown by :data:`TOL_PX`) do not meet."""
    if not len(a) or not len(b):
        return True
    lo_a, hi_a, lo_b, hi_b = a.min(axis=0), a.max(axis=0), b.min(axis=0), b.max(axis=0)
    return bool(np.any(lo_a > hi_b + TOL_PX) or np.any(lo_b > hi_a + TOL_PX))


def coincides(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two series drawn at the display points ``a`` and ``b`` coincide: each within
    :data:`TOL_PX` of the other over :data:`COINCIDE_FRACTION` of its points."""
    if _apart(a, b):
        return False
    return _covered_fraction(a, b) >= COINCIDE_FRACTION and _covered_fraction(b, a) >= COINCIDE_FRACTION


def _groups(series: Sequence[_Series]) -> list[list[int]]:
    """Indices of the series that coincide (the same data, or drawn on one path: :func:`coincides`),
    grouped, the first drawn first; single ones left out."""
    parent = list(range(len(series)))

    def root(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    for i in range(len(series)):
        for j in range(i):
            a, b = series[i], series[j]
            if root(i) != root(j) and (a.same_data(b) or coincides(a.px, b.px)):
                parent[root(i)] = root(j)
    groups: dict[int, list[int]] = {}
    for i in range(len(series)):
        groups.setdefault(root(i), []).append(i)
    return [g for g in groups.values() if len(g) > 1]


# -- making the promises hold ---------------------------------------------------------------------


def _draw(fig: Any) -> Any:
    """Lay ``fig`` out and place every artist, without rasterizing; returns the renderer that
    measures texts."""
    fig.draw_without_rendering()
    return fig.canvas.get_renderer()


#: a line's style before it took turns (line style, marker fill, marker size), to restore it
_DRAWN_AS: weakref.WeakKeyDictionary[Line2D, tuple[Any, Any, float]] = weakref.WeakKeyDictionary()


def _restore(line: Line2D) -> None:
    """Draw a line as it was before it took turns."""
    if (style := _DRAWN_AS.pop(line, None)) is not None:
        line.set_linestyle(style[0])
        line.set_fillstyle(style[1])
        line.set_markersize(style[2])


def _take_turns(line: Line2D, turn: int, k: int) -> None:
    """Dash the ``turn``-th (1..k-1) of ``k`` coinciding lines so that its dashes fall where
    the others' leave gaps (the first, solid, shows in the remaining one), markers hollow and
    larger so that the ones below show inside."""
    size = _DRAWN_AS.setdefault(line, (line.get_linestyle(), line.get_fillstyle(), line.get_markersize()))[2]
    on = 3.0
    line.set_linestyle((on * (k - turn), (on, on * (k - 1))))
    if line.get_marker() not in (None, "None", "none", ""):
        line.set_fillstyle("none")
        line.set_markersize(size + 2.5 * turn)  # from its own size: the same however often it is finished


def _name(label: str) -> str:
    """A series' name in a note: its label up to a parenthesis (``itmtl (median 0.1 m)`` -> ``itmtl``)."""
    return label.split(" (", 1)[0]


def _below_gid(ax: Any) -> str:
    return f"legend of axes {id(ax)}"


def _legend_of(ax: Any) -> Legend | None:
    """The axes' own legend, also once moved below the figure."""
    leg = ax.get_legend()
    if isinstance(leg, Legend):
        return leg
    return next((f for f in ax.figure.legends if f.get_gid() == _below_gid(ax)), None)


def _plain(label: str) -> str:
    """A label without the note :func:`finish` gave it."""
    return label.split(f" ({NOTE} ", 1)[0]


def _note_coincident(fig: Any) -> bool:
    """Draw coinciding series in turns and say so (the legend entry, or the panel's title);
    whether anything changed. Run again after the layout moved, it mends only what differs."""
    changed = False
    for ax in fig.axes:
        series = _series(ax)
        leg = _legend_of(ax)
        entries = {t.get_text(): (t, h) for t, h in zip(leg.get_texts(), leg.legend_handles)} if leg else {}
        notes, later = [], set()
        for group in _groups(series):
            first = _name(_plain(series[group[0]].label))
            for turn, i in enumerate(group[1:], start=1):
                s = series[i]
                later.add(i)
                if s.line is not None:
                    _take_turns(s.line, turn, len(group))
                if s.label not in entries:
                    notes.append(f"{_name(_plain(s.label))} {NOTE} {first}")
                    continue
                text, handle = entries[s.label]
                if isinstance(handle, Line2D) and s.line is not None:
                    _take_turns(handle, turn, len(group))
                label = f"{_plain(s.label)} ({NOTE} {first})"
                if label != s.label:
                    text.set_text(label)
                    s.artist.set_label(label)
                    changed = True
        for i, s in enumerate(series):  # noted before, alone now: plain again
            if i not in later and s.label != _plain(s.label):
                if s.label in entries:
                    text, handle = entries[s.label]
                    text.set_text(_plain(s.label))
                    if isinstance(handle, Line2D):
                        _restore(handle)
                s.artist.set_label(_plain(s.label))
                if s.line is not None:
                    _restore(s.line)
                changed = True
        kept = [line for line in ax.get_title().split("\n") if f" {NOTE} " not in line and line]
        title = "\n".join(kept + (["; ".join(notes)] if notes else []))
        if title != ax.get_title():
            ax.set_title(title, fontsize=8 if notes else None)
            changed = True
    return changed


def _data_covered(ax: Any, box: Bbox, renderer: Any) -> list[str]:
    """What of ``ax``'s drawn data lies inside the display box ``box``: points and lines
    (sampled along their paths), bars, meshes, filled areas, images, texts."""

    def hit(px: np.ndarray) -> bool:
        px = _in_axes(ax, px)
        return bool(np.any((px[:, 0] > box.x0) & (px[:, 0] < box.x1) & (px[:, 1] > box.y0) & (px[:, 1] < box.y1)))

    def area(coll: Collection) -> bool:  # a mesh (filled to its edges) or a filled area
        if not coll.get_window_extent(renderer).overlaps(box):
            return False
        tr = coll.get_transform()
        return isinstance(coll, QuadMesh) or any(tr.transform_path(p).intersects_bbox(box) for p in coll.get_paths())

    shown = [a for a in (*ax.lines, *ax.collections, *ax.patches, *ax.images, *ax.texts) if a.get_visible()]
    found = []
    for a in shown:
        if isinstance(a, Line2D):
            covered = hit(_line_px(a))
        elif isinstance(a, (LineCollection, PathCollection)):
            covered = hit(_collection_px(a))
        elif isinstance(a, Collection):
            covered = area(a)
        else:  # a bar, an image, a text
            covered = bool(not isinstance(a, Text) or a.get_text()) and a.get_window_extent(renderer).overlaps(box)
        if covered:
            found.append(f"{type(a).__name__} {a.get_label()!r}")
    return found


def _legends(fig: Any) -> Iterable[tuple[Any, Legend]]:
    """(its axes or None, legend) for every legend of the figure (a legend moved below the
    figure keeps its axes)."""
    owners = {_below_gid(ax): ax for ax in fig.axes}
    for ax in fig.axes:
        if isinstance(leg := ax.get_legend(), Legend):
            yield ax, leg
    for leg in fig.legends:
        yield owners.get(leg.get_gid()), leg


def _legend_covers(fig: Any, leg: Legend, renderer: Any) -> list[str]:
    box = leg.get_window_extent(renderer)
    return [what for ax in fig.axes for what in _data_covered(ax, box, renderer)]


def _move_legends_off_data(fig: Any, renderer: Any) -> bool:
    """A legend that covers data leaves its axes: below the figure, across its width, when its
    axes is the figure's only one (a colour bar aside); else to the right of its axes.
    Whether any moved."""
    panels = [ax for ax in fig.axes if not _is_colorbar(ax)]
    moved = False
    for ax in fig.axes:
        leg = ax.get_legend()
        if leg is None or not _legend_covers(fig, leg, renderer):
            continue
        if len(panels) == 1:
            _legend_below(fig, ax, leg)
        else:
            leg.set_loc("upper left")
            leg.set_bbox_to_anchor((1.02, 1.0), transform=ax.transAxes)
        renderer = _draw(fig)
        moved = True
    return moved


def _is_colorbar(ax: Any) -> bool:
    return ax.get_label() == "<colorbar>"


def _legend_below(fig: Any, ax: Any, leg: Legend) -> None:
    """Replace ``leg`` (the axes' legend, inside it or already below the figure) by a figure
    legend below the axes with the same entries (their labels as they are now), in as many
    columns (at most 4) as fit the figure's width."""
    by_label = dict(zip(*ax.get_legend_handles_labels()[::-1]))
    labels = [t.get_text() for t in leg.get_texts() if t.get_text() in by_label]
    size = leg.get_texts()[0].get_fontsize() if labels else None
    leg.remove()
    for ncols in range(min(len(labels), 4), 0, -1):
        new = fig.legend([by_label[x] for x in labels], labels, loc="outside lower center", ncols=ncols, fontsize=size)
        new.set_gid(_below_gid(ax))  # still this axes' legend (its notes go there)
        # a legend's size does not depend on where the layout puts it: measured without one
        if ncols == 1 or new.get_window_extent(fig.canvas.get_renderer()).width <= 0.98 * fig.bbox.width:
            return
        new.remove()


def _tick_labels(axis: Any, renderer: Any) -> list[Any]:
    """The display boxes of the tick labels an axis draws (ticks inside its view)."""
    lo, hi = sorted(axis.get_view_interval())
    span = (hi - lo) * 1e-9
    ticks = [t for t in (*axis.get_major_ticks(), *axis.get_minor_ticks()) if lo - span <= t.get_loc() <= hi + span]
    labels = [label for t in ticks for label in (t.label1, t.label2)]
    return [label.get_window_extent(renderer) for label in labels if label.get_visible() and label.get_text().strip()]


def _crowded(axis: Any, renderer: Any) -> bool:
    """Whether two tick labels of ``axis`` overlap or come closer than :data:`GAP_PX`."""
    boxes = [b.padded(GAP_PX / 2) for b in _tick_labels(axis, renderer)]
    return any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1 :])


def _thin(axis: Any, rounds: int, renderer: Any) -> None:
    """One step against crowded tick labels on ``axis``: a log axis loses its minor labels,
    then half its decades; categories (and ticks set by value) slant further; other numbers
    get about half as many ticks."""
    shown = len(_tick_labels(axis, renderer))
    if isinstance(axis.get_major_locator(), (FixedLocator, StrCategoryLocator)):  # ticks chosen by the plot
        axis.set_tick_params(labelrotation=30 + 15 * min(rounds, 4))
        for label in axis.get_majorticklabels():
            label.set_horizontalalignment("right" if axis.axis_name == "x" else "center")
    elif axis.get_scale() == "log":
        if rounds == 0:
            axis.set_minor_formatter(NullFormatter())
        else:
            axis.set_major_locator(LogLocator(numticks=max(2, shown // 2)))
    else:
        axis.set_major_locator(MaxNLocator(nbins=max(1, shown // 2), steps=[1, 2, 5, 10]))


def _thin_crowded_ticks(fig: Any, renderer: Any) -> bool:
    """Thin or slant crowded tick labels until none overlap (a few steps at most); whether
    any were."""
    thinned = False
    for rounds in range(6):
        crowded = [axis for ax in fig.axes for axis in (ax.xaxis, ax.yaxis) if _crowded(axis, renderer)]
        if not crowded:
            break
        for axis in crowded:
            _thin(axis, rounds, renderer)
        renderer = _draw(fig)
        thinned = True
    return thinned


def finish(fig: Any) -> None:
    """Lay ``fig`` out so that the module's three promises hold: coinciding series drawn in
    turns and noted, legends off the data, tick labels apart. Each step lays the figure out
    again only if it changed it."""
    renderer = _draw(fig)
    for _ in range(4):  # a step may undo another's work (a legend grown by a note): until none acts
        moved = _move_legends_off_data(fig, renderer)
        if moved:
            renderer = _draw(fig)
        noted = _note_coincident(fig)
        if noted:
            for ax, leg in list(_legends(fig)):  # a note made a legend below the figure wider
                if ax is not None and leg.get_gid() == _below_gid(ax):
                    _legend_below(fig, ax, leg)
            renderer = _draw(fig)
        if not (_thin_crowded_ticks(fig, renderer) or moved or noted):
            break
        renderer = _draw(fig)
    fig.set_layout_engine("none")  # laid out: saving keeps this layout instead of computing it again


# -- what is still wrong ----------------------------------------------------------------------------


def problems(fig: Any) -> list[str]:
    """What in ``fig`` as drawn breaks a promise of this module: a legend over data, tick
    labels that overlap, two series that coincide without a note, two legend entries drawn
    alike (same colour, line style and marker). Empty when none."""
    renderer = _draw(fig)
    out = []
    for ax, leg in _legends(fig):
        where = "figure legend" if ax is None else f"legend of {ax.get_title()!r}"
        out += [f"{where} covers {what}" for what in _legend_covers(fig, leg, renderer)]
        box = leg.get_window_extent(renderer)
        out += [
            f"{where} covers the text {t.get_text()!r}"
            for t in _labels(fig)
            if t.get_window_extent(renderer).overlaps(box)
        ]
        styles: dict[tuple[Any, ...], str] = {}
        for text, handle in zip(leg.get_texts(), leg.legend_handles):
            key = _style(handle)
            if key is not None and key in styles:
                out.append(f"{where}: {text.get_text()!r} is drawn like {styles[key]!r}")
            elif key is not None:
                styles[key] = text.get_text()
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            if _crowded(axis, renderer):
                out.append(f"{axis.axis_name} tick labels of {ax.get_title()!r} overlap")
        series = _series(ax)
        for group in _groups(series):
            first = _name(series[group[0]].label)
            for i in group[1:]:
                s = series[i]
                if f"{NOTE} {first}" not in s.label and f"{_name(s.label)} {NOTE} {first}" not in ax.get_title():
                    out.append(f"{s.label!r} coincides with {first!r} in {ax.get_title()!r} without a note")
    return out


def _labels(fig: Any) -> list[Text]:
    """The figure's titles and axis labels that show."""
    texts = [*fig.texts, *(t for ax in fig.axes for t in (ax.title, ax.xaxis.label, ax.yaxis.label))]
    return [t for t in texts if t.get_visible() and t.get_text()]


def _style(handle: Any) -> tuple[Any, ...] | None:
    """What tells a legend handle apart: colour, line style, marker, fill (None: not a line)."""
    if isinstance(handle, Line2D):
        return (
            matplotlib.colors.to_hex(handle.get_color()),
            str(handle.get_linestyle()),
            str(handle.get_marker()),
            handle.get_fillstyle(),
        )
    return None
