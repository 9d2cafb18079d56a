"""The sweep report: each metric against each numeric swept value, every comparison kept.

Drawn from ``sweep.csv`` alone (plan order, so the first appearance of each grid value is its
order in the scenario). For a metric and an x key (each numeric grid key; with none, the
first grid key), the runs are grouped by x and by every other grid key (:func:`lines`: one
line per combination of the other keys, and variant, in scenario order), so a grid ``model x
sigma_t`` draws ESSP and ASSP apart against sigma_t instead of pooling them. The plot shows
them as small multiples (:func:`layout`, :func:`draw`): in each panel a line per value of one
other key (the one with the fewest values, at most :data:`MAX_LINES`), a panel per
combination of the rest. Each point is the sign-respecting centre and 95 % interval of
:mod:`aquasim_py.reporting.intervals` over its runs, the ``center`` columns of ``summary.csv``.

Axes: an x key whose values are positive and closer to evenly spaced in log than in linear
terms (``[1e-5, 1e-4, 1e-3]``, ``[10, 20, 40]``) gets a log axis, a metric whose centres are
positive and span more than a decade a log y axis; times and lengths are shown in their
display unit (:mod:`aquasim_py.reporting.display`).

Which metrics: :func:`select` (shell patterns such as ``"*.rmse_m"``; by default every metric
but the packet counts, ``packets.*``, which a pattern selects explicitly).
"""

from __future__ import annotations

import fnmatch
import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.lines import Line2D
from matplotlib.ticker import NullLocator

from aquasim_py.reporting import display, intervals
from aquasim_py.reporting.figures import dodge, save_figure, subplots

__all__ = [
    "MAX_COLUMNS",
    "MAX_LINES",
    "Layout",
    "Line",
    "SweepData",
    "draw",
    "is_log_spaced",
    "layout",
    "lines",
    "load",
    "pick",
    "plot",
    "plot_all",
    "point_label",
    "select",
    "short_names",
    "summary",
    "text_keys",
]

#: metric families left out unless a pattern names them
DEFAULT_EXCLUDED = ("packets.*",)
_FIXED = ("run", "seed", "key", "error")


@dataclass
class SweepData:
    """A sweep's successful runs, its grid (key -> values as written in sweep.csv, in scenario
    order) and its numeric metric columns."""

    runs: pd.DataFrame
    grid: dict[str, list[str]]
    metrics: list[str]
    failed: int = 0


def load(sweep_dir: str | Path) -> SweepData:
    """Read ``sweep.csv`` (grid columns as text, so values compare as written)."""
    path = Path(sweep_dir) / "sweep.csv"
    head = pd.read_csv(path, nrows=0).columns.tolist()
    keys = head[: head.index("run")] if "run" in head else []
    df = pd.read_csv(path, dtype={**dict.fromkeys(keys, str), "key": str, "error": str}, keep_default_na=False)
    failed = 0
    if "error" in df.columns:
        ok = df["error"] == ""
        failed = int((~ok).sum())
        df = df[ok]
    metrics = []
    for c in df.columns:
        if c in keys or c in _FIXED:
            continue
        df[c] = pd.to_numeric(df[c].replace("", np.nan), errors="coerce")
        if df[c].notna().any():
            metrics.append(c)
    grid = {k: list(pd.unique(df[k])) for k in keys}
    return SweepData(df.reset_index(drop=True), grid, metrics, failed)


def select(metrics: Sequence[str], patterns: Sequence[str] | None = None) -> list[str]:
    """The metrics matching any shell pattern (``*``, ``?``, ``[...]``), in their order; with
    no patterns every metric but :data:`DEFAULT_EXCLUDED`."""
    if not patterns:
        return [m for m in metrics if not any(fnmatch.fnmatchcase(m, p) for p in DEFAULT_EXCLUDED)]
    return [m for m in metrics if any(fnmatch.fnmatchcase(m, p) for p in patterns)]


def pick(metrics: Mapping[str, Any], patterns: Sequence[str] | None, keep_all: bool = False) -> dict[str, Any]:
    """The entries of ``metrics`` (name -> value) that :func:`select` keeps; ``keep_all``:
    every one when no pattern is given (a single run's table shows its packet counts)."""
    if keep_all and not patterns:
        return dict(metrics)
    keep = set(select(list(metrics), patterns))
    return {k: v for k, v in metrics.items() if k in keep}


def short_names(keys: Sequence[str]) -> dict[str, str]:
    """Each grid key by its shortest distinct tail (``nodes.1.params.sigma_t_s`` -> ``sigma_t_s``)."""
    out: dict[str, str] = {}
    for k in keys:
        parts = k.split(".")
        for n in range(1, len(parts) + 1):
            tail = ".".join(parts[-n:])
            if sum(1 for other in keys if other == tail or other.endswith("." + tail)) == 1:
                out[k] = tail
                break
        else:
            out[k] = k
    return out


def _numbers(values: Sequence[str]) -> list[float] | None:
    """The values as numbers, or None if any is not one (booleans count as text)."""
    out = []
    for v in values:
        if v in ("True", "False"):
            return None
        try:
            out.append(float(v))
        except ValueError:
            return None
    return out


def is_log_spaced(values: Sequence[float]) -> bool:
    """Positive values whose spacing is more even in log than in linear terms (two values:
    a ratio of 10 or more)."""
    v = np.unique(np.asarray(values, dtype=float))
    if v.size < 2 or v[0] <= 0 or not np.all(np.isfinite(v)):
        return False
    if v.size == 2:
        return bool(v[1] / v[0] >= 10.0)
    lin, log = np.diff(v), np.diff(np.log(v))
    return bool(np.std(log) / np.mean(log) < np.std(lin) / np.mean(lin))


def value_texts(key: str, values: Sequence[str]) -> dict[str, str]:
    """Grid values as labels show them: numbers with 4 significant digits, a time or length in
    the display unit of all the key's values (``1e-05`` -> ``10 us``)."""
    nums = _numbers(values)
    if nums is None:
        return {v: v for v in values}
    u = display.unit_of(key.rsplit(".", 1)[-1], nums)
    return {v: f"{x / u.scale:.4g}" + (f" {u.unit}" if u.unit else "") for v, x in zip(values, nums)}


@dataclass
class Line:
    """One line of a sweep plot: the other grid keys' values it holds fixed, and per x value
    (in scenario order) the runs' statistic."""

    fixed: tuple[tuple[str, str], ...]
    x: list[str]
    n: np.ndarray
    center: np.ndarray
    low: np.ndarray
    high: np.ndarray
    stat: str

    def label(self, data: SweepData) -> str:
        """``model=essp, sigma_t=10 us`` (a variant by its name alone)."""
        return point_label(data, dict(self.fixed))


def summary(data: SweepData, metrics: Sequence[str]) -> pd.DataFrame:
    """:func:`aquasim_py.reporting.intervals.summarize` per grid point (every grid key) and metric."""
    return intervals.summarize(data.runs, list(data.grid), metrics)


def lines(data: SweepData, x: str, metric: str, table: pd.DataFrame | None = None) -> list[Line]:
    """The lines of ``metric`` against grid key ``x``: one per combination of the other grid
    keys present in the runs, in scenario order (``table``: :func:`summary`, if at hand)."""
    keys = list(data.grid)
    others = [k for k in keys if k != x]
    s = table if table is not None else summary(data, [metric])
    s = s[s["metric"] == metric]
    out: list[Line] = []
    for combo in itertools.product(*(data.grid[k] for k in others)):
        sel = s
        for k, v in zip(others, combo):
            sel = sel[sel[k] == v]
        if sel.empty:
            continue
        at = {row[x]: row for _, row in sel.iterrows()}
        xs = [v for v in data.grid[x] if v in at]
        out.append(
            Line(
                fixed=tuple(zip(others, combo)),
                x=xs,
                n=np.array([at[v]["n"] for v in xs], dtype=int),
                center=np.array([at[v]["center"] for v in xs], dtype=float),
                low=np.array([at[v]["low"] for v in xs], dtype=float),
                high=np.array([at[v]["high"] for v in xs], dtype=float),
                stat=str(sel["stat"].iloc[0]),
            )
        )
    return out


def text_keys(data: SweepData) -> list[str]:
    """The grid keys some of whose values are not numbers (a MAC's name, a variant)."""
    return [k for k, v in data.grid.items() if _numbers(v) is None]


def x_keys(data: SweepData) -> list[str]:
    """The keys plotted along x: the numeric grid keys, else the first grid key."""
    numeric = [k for k, v in data.grid.items() if _numbers(v) is not None]
    return numeric or list(data.grid)[:1]


#: at most this many lines in one panel; a key with more values gets panels of its own
MAX_LINES = 3
#: panels in one row before they wrap to the next (one key of panels)
MAX_COLUMNS = 4


@dataclass
class Layout:
    """How a plot against one grid key shows the others: in every panel one line per value of
    ``hue`` (None: one line), one column of panels per value of ``cols`` and one row per
    combination of ``rows`` (small multiples; one key of panels alone wraps after
    :data:`MAX_COLUMNS`)."""

    hue: str | None
    cols: str | None
    rows: list[str]

    @property
    def facets(self) -> list[str]:
        """The keys that choose a panel, in grid order of ``cols`` then ``rows``."""
        return ([self.cols] if self.cols else []) + self.rows


def layout(data: SweepData, x: str) -> Layout:
    """The :class:`Layout` of a plot against ``x``: the other key with the fewest values (the
    first in grid order among equals) as lines, if it has at most :data:`MAX_LINES`; every
    other key as panels, the first as columns, the rest as rows."""
    others = [k for k in data.grid if k != x]
    few = [k for k in others if len(data.grid[k]) <= MAX_LINES]
    hue = min(few, key=lambda k: len(data.grid[k])) if few else None
    panels = [k for k in others if k != hue]
    return Layout(hue, panels[0] if panels else None, panels[1:])


def _panel_grid(values: Mapping[str, list[str]], lay: Layout) -> tuple[int, int, list[tuple[str, ...]]]:
    """(rows, columns, the facet values of each panel in reading order), from the ``values`` of
    each facet key."""
    if lay.cols is None:
        return 1, 1, [()]
    cols = values[lay.cols]
    if not lay.rows:
        ncols = min(len(cols), MAX_COLUMNS)
        return -(-len(cols) // ncols), ncols, [(c,) for c in cols]
    row_combos = list(itertools.product(*(values[k] for k in lay.rows)))
    return len(row_combos), len(cols), [(c, *r) for r in row_combos for c in cols]


def draw(
    data: SweepData, x: str, metric: str, table: pd.DataFrame | None = None
) -> tuple[Any, dict[tuple[str, ...], Any]] | None:
    """The figure of ``metric`` against ``x`` (:func:`layout`: a line per value of one other
    grid key, a panel per combination of the rest; a value with no run that has the metric gets
    no panel, a combination without runs says so), not yet saved: (figure, panel axes by
    their facet values in :attr:`Layout.facets` order), or None when no run has the metric.
    Every panel shares the axes' scales; the lines of a panel are drawn a few points apart
    sideways (:func:`aquasim_py.reporting.figures.dodge`) so that their error bars stay apart. A caller may draw more into the panels before
    :func:`aquasim_py.reporting.figures.save_figure`."""
    ls = lines(data, x, metric, table)
    if not ls:
        return None
    lay = layout(data, x)
    names = short_names(list(data.grid))
    centers = np.concatenate([ln.center for ln in ls])
    u = display.unit_of(metric, centers)
    nums = _numbers(data.grid[x])
    xu = display.unit_of(names[x], nums or [])
    log_x = nums is not None and is_log_spaced(nums)
    # a facet value no run with the metric has gets no panel (a variant without the metric)
    present = {k: [v for v in data.grid[k] if any(dict(ln.fixed)[k] == v for ln in ls)] for k in lay.facets}
    nrows, ncols, combos = _panel_grid(present, lay)
    one = nrows * ncols == 1
    size = (7.0, 4.5) if one else (0.6 + 3.1 * ncols, 0.9 + 2.5 * nrows)
    fig, axes = subplots(nrows, ncols, figsize=size, sharex=True, sharey=True, squeeze=False)
    hues = data.grid[lay.hue] if lay.hue else []
    hue_text = value_texts(lay.hue, hues) if lay.hue else {}

    def hue_of(ln: Line) -> int:  # the line's place among the hue key's values (its colour)
        return hues.index(dict(ln.fixed)[lay.hue]) if lay.hue else 0

    panels: dict[tuple[str, ...], Any] = {}
    for ax, combo in zip(axes.flat, combos):
        panels[combo] = ax
        fixed = dict(zip(lay.facets, combo))
        drawn = sorted((ln for ln in ls if all(dict(ln.fixed)[k] == v for k, v in fixed.items())), key=hue_of)
        for j, ln in enumerate(drawn):
            i = hue_of(ln)
            if nums is not None:
                xv = np.array([float(v) for v in ln.x]) / xu.scale
            else:
                xv = np.array([data.grid[x].index(v) for v in ln.x], dtype=float)
            c, lo, hi = ln.center / u.scale, ln.low / u.scale, ln.high / u.scale
            err = np.nan_to_num(np.vstack([c - lo, hi - c]), nan=0.0)
            label = hue_text[hues[i]] if lay.hue else "_"
            # categories are not joined: a line between them would suggest an order
            style = "-" if nums is not None else "none"
            ax.errorbar(
                xv,
                c,
                yerr=err,
                marker="o",
                ms=4,
                capsize=3,
                lw=1.2,
                ls=style,
                color=f"C{i}",
                label=label,
                transform=dodge(ax, j, len(drawn)),
            )
            # matplotlib takes no data limits from a shifted transform: the points' own
            pts = np.column_stack([np.tile(xv, 3), np.concatenate([c, lo, hi])])
            ax.update_datalim(pts[np.isfinite(pts).all(axis=1)])
        if not drawn:  # a combination of present values that no run has
            ax.text(0.5, 0.5, "no runs", transform=ax.transAxes, ha="center", va="center", color="0.4")
        if fixed:
            ax.set_title(point_label(data, fixed), fontsize=9)
        ax.grid(True, which="both", alpha=0.25)
    for ax in axes.flat[len(combos) :]:
        ax.set_visible(False)
    ax0 = axes.flat[0]
    ax0.margins(x=0.08)  # room for the dodged points at the ends
    if log_x:
        ax0.set_xscale("log")
        ax0.xaxis.set_minor_locator(NullLocator())
    if nums is None:
        ax0.set_xticks(range(len(data.grid[x])), data.grid[x])
    elif len(nums) <= 10:  # ticks at the swept values
        ax0.set_xticks(np.asarray(nums) / xu.scale, [f"{v / xu.scale:.4g}" for v in nums])
    pos = centers[np.isfinite(centers)]
    if pos.size and pos.min() > 0 and pos.max() > 10 * pos.min():
        ax0.set_yscale("log")
    for col in range(ncols):  # x labels under the lowest panel of each column
        shown = [ax for ax in axes[:, col] if ax.get_visible()]
        if shown:
            shown[-1].xaxis.set_tick_params(labelbottom=True)
            shown[-1].set_xlabel(display.label(xu))
    for ax in axes[:, 0]:
        ax.set_ylabel(display.label(u))
    nmax = int(max(ln.n.max() for ln in ls))
    nmin = int(min(ln.n.min() for ln in ls))
    runs = f"n = {nmin}" if nmin == nmax else f"n = {nmin}-{nmax}"
    stat = ls[0].stat
    what = (
        f"{stat} over runs and its 95 % CI ({runs} per point; summary.csv: center)"
        if nmax > 1
        else "one run per point (no interval)"
    )
    fig.suptitle(f"{metric}\n{what}", fontsize=10)
    if lay.hue is not None:
        title = display.unit_of(names[lay.hue]).stem if lay.hue != "variant" else "variant"
        if one:
            ax0.legend(fontsize=8, title=title, title_fontsize=8)
        else:
            proxies = [
                Line2D([], [], color=f"C{i}", marker="o", ms=4, lw=1.2, label=hue_text[h]) for i, h in enumerate(hues)
            ]
            fig.legend(handles=proxies, loc="outside right center", fontsize=8, title=title, title_fontsize=8)
    return fig, panels


def plot(data: SweepData, x: str, metric: str, path: Path, table: pd.DataFrame | None = None) -> Path | None:
    """One PNG of ``metric`` against ``x`` (:func:`draw`); None when no run has the metric."""
    drawn = draw(data, x, metric, table)
    return None if drawn is None else save_figure(drawn[0], path)


def plot_all(data: SweepData, out: Path, metrics: Sequence[str], table: pd.DataFrame | None = None) -> list[Path]:
    """Every (metric, x key) plot, ``sweep_<metric>__<x>.png``."""
    paths = []
    s = table if table is not None else summary(data, metrics)
    for metric in metrics:
        for x in x_keys(data):
            safe = "".join(ch if ch.isalnum() or ch in "._-" else "_" for ch in f"{metric}__{x}")
            p = plot(data, x, metric, out / f"sweep_{safe}.png", s)
            if p is not None:
                paths.append(p)
    return paths


def point_label(data: SweepData, values: dict[str, str], sep: str = ", ") -> str:
    """Grid values (key -> value as written) as a label: ``model=essp, sigma_t=10 us``, a
    variant by its name alone, keys in grid order; "all runs" for none."""
    names = {k: display.unit_of(n).stem for k, n in short_names(list(data.grid)).items()}
    parts = []
    for k in data.grid:
        if k in values:
            text = value_texts(k, data.grid[k]).get(values[k], values[k])
            parts.append(text if k == "variant" else f"{names[k]}={text}")
    return sep.join(parts) or "all runs"
