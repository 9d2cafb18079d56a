"""The sweep report: each metric against each numeric swept value, every comparison kept.

Drawn from ``sweep.csv`` alone (plan order, so the first appearance of each grid value is its
order in the scenario). For a metric and an x key (each numeric grid key; with none, the
first grid key), the runs are grouped by x and by every other grid key: one line per
combination of the other keys (and variant), in scenario order, so a grid ``model x sigma_t``
draws ESSP and ASSP apart against sigma_t instead of pooling them. Each point is the
sign-respecting centre and 95 % interval of :mod:`aquasim_py.reporting.intervals` over its runs.

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

from aquasim_py.reporting import display, intervals
from aquasim_py.reporting.figures import plt, save_figure

__all__ = [
    "Line",
    "SweepData",
    "is_log_spaced",
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


def plot(data: SweepData, x: str, metric: str, path: Path, table: pd.DataFrame | None = None) -> Path | None:
    """One PNG: ``metric`` against ``x``, a line per combination of the other grid keys."""
    ls = lines(data, x, metric, table)
    if not ls:
        return None
    names = short_names(list(data.grid))
    centers = np.concatenate([ln.center for ln in ls])
    u = display.unit_of(metric, centers)
    nums = _numbers(data.grid[x])
    xu = display.unit_of(names[x], nums or [])
    fig, ax = plt.subplots(figsize=(7.0, 4.5))
    many = len(ls) > 1
    for i, ln in enumerate(ls):
        if nums is not None:
            xv = np.array([float(v) for v in ln.x]) / xu.scale
        else:  # categories, each line nudged sideways so that its bars stay apart
            xv = np.array([data.grid[x].index(v) for v in ln.x], dtype=float)
            xv = xv + (i - (len(ls) - 1) / 2) * (0.25 / max(1, len(ls) - 1)) if many else xv
        c, lo, hi = ln.center / u.scale, ln.low / u.scale, ln.high / u.scale
        err = np.nan_to_num(np.vstack([c - lo, hi - c]), nan=0.0)
        ax.errorbar(xv, c, yerr=err, marker="o", ms=4, capsize=3, lw=1.2, label=ln.label(data))
    if nums is not None and is_log_spaced(nums):
        ax.set_xscale("log")
    if nums is None:
        ax.set_xticks(range(len(data.grid[x])), data.grid[x])
    pos = centers[np.isfinite(centers)]
    if pos.size and pos.min() > 0 and pos.max() > 10 * pos.min():
        ax.set_yscale("log")
    ax.set_xlabel(display.label(xu))
    ax.set_ylabel(display.label(u))
    nmax = int(max(ln.n.max() for ln in ls))
    nmin = int(min(ln.n.min() for ln in ls))
    runs = f"n = {nmin}" if nmin == nmax else f"n = {nmin}-{nmax}"
    what = f"{ls[0].stat} and 95 % CI over runs ({runs} per point)" if nmax > 1 else "one run per point (no interval)"
    ax.set_title(f"{metric}\n{what}", fontsize=10)
    if many or ls[0].fixed:
        ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.25)
    return save_figure(fig, path)


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
