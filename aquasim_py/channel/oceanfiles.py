"""The ocean from standard files, read as they are distributed (netCDF, their own names).

* World Ocean Atlas (WOA18, WOA23) temperature and salinity: the objectively analysed
  climatological means ``t_an`` (in-situ temperature, deg C, ITS-90) and ``s_an`` (practical
  salinity, PSS-78) on ``time``, ``depth`` (m, positive down), ``lat``, ``lon`` (CF-1.6; WOA ships
  them in two files, one per variable, one period each: a month, a season or the year).
  :func:`read_woa` builds the sound-speed field through TEOS-10 at every grid node
  (:meth:`.geographic.GeographicField.from_ts`: pressure from depth and the node's latitude,
  Absolute Salinity and Conservative Temperature from the file's values, ``gsw.sound_speed``).
* GEBCO (``elevation``, m above sea level, on ``lat`` / ``lon``) or ETOPO 2022 (``z``) bathymetry:
  :func:`read_gebco` builds the sea floor, depth = -elevation (0 on land).

Axes are recognised by their CF attributes (standard_name, units, axis) or their usual names;
time periods by CF's ``climatology`` bounds (WOA's "months since 1955-01-01 00:00:00" with
``climatology_bounds``: a month, WOA's seasons January-March ... October-December, or the
year). A problem with a file is a :class:`DataFileError` naming the file and the variable.

Cells WOA leaves empty (below its own sea floor, over its land) take the temperature and
salinity of the deepest value above them in the column, and columns with none at all those of
the nearest column with values (in grid steps): the water the files give no value for is the
nearest water they do.
"""

from __future__ import annotations

import calendar
import re
from collections.abc import Sequence
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .geographic import GeographicBathymetry, GeographicField, LatLonGrid, LocalFrame

__all__ = ["SEASONS", "DataFileError", "period_months", "read_gebco", "read_woa"]

FloatArray = NDArray[np.float64]
Box = tuple[float, float, float, float]  # lat_min, lat_max, lon_min, lon_max (deg)

#: WOA's seasons (calendar quarters, as the atlas defines them)
SEASONS: dict[str, tuple[int, ...]] = {
    "winter": (1, 2, 3),
    "spring": (4, 5, 6),
    "summer": (7, 8, 9),
    "autumn": (10, 11, 12),
}


#: what TEOS-10 is asked about: in-situ temperature and practical salinity of sea water
_PLAUSIBLE_T = (-5.0, 45.0, "an in-situ temperature in deg C")
_PLAUSIBLE_S = (0.0, 50.0, "a practical salinity")


class DataFileError(ValueError):
    """A data file lacks what is needed, or does not cover what is asked: ``path: variable: problem``."""

    def __init__(self, path: str | Path, variable: str, problem: str) -> None:
        self.path, self.variable, self.problem = str(path), variable, problem
        super().__init__(f"{self.path}: {variable}: {problem}")


# --------------------------------------------------------------------------- axes

_AXES: dict[str, tuple[str, set[str], set[str]]] = {
    # kind: (CF axis, usual names, units)
    "latitude": ("Y", {"lat", "latitude"}, {"degrees_north", "degree_north", "degrees_n", "degree_n"}),
    "longitude": ("X", {"lon", "longitude"}, {"degrees_east", "degree_east", "degrees_e", "degree_e"}),
    "depth": ("Z", {"depth", "z", "lev", "level"}, set()),
    "time": ("T", {"time"}, set()),
}


def _dim(ds: Any, da: Any, kind: str) -> str | None:
    """The dimension of ``da`` that is the ``kind`` axis (CF standard_name, units, axis, name)."""
    axis, names, units = _AXES[kind]
    for d in da.dims:
        attrs = ds[d].attrs if d in ds.variables else {}
        if attrs.get("standard_name") == kind or str(attrs.get("units", "")).lower() in units:
            return str(d)
    for d in da.dims:
        attrs = ds[d].attrs if d in ds.variables else {}
        if attrs.get("axis") == axis or str(d).lower() in names:
            return str(d)
    return None


def _coordinate(ds: Any, path: Path, name: str, dim: str) -> FloatArray:
    if dim not in ds.variables:
        raise DataFileError(path, dim, f"no coordinate values for the dimension of {name}")
    v = np.asarray(ds[dim].values, float)
    if not np.all(np.isfinite(v)):
        raise DataFileError(path, dim, "coordinate values are not all finite")
    return v


# --------------------------------------------------------------------------- periods


def _describe(months: frozenset[int]) -> str:
    if len(months) == 12:
        return "the year"
    for name, ms in SEASONS.items():
        if months == frozenset(ms):
            return f"{name} ({calendar.month_abbr[ms[0]]}-{calendar.month_abbr[ms[-1]]})"
    return "+".join(calendar.month_name[m] for m in sorted(months))


def requested_period(month: int | None = None, season: str | None = None) -> frozenset[int] | None:
    """The months a scenario asks for: one month (1-12), a WOA season, or None (the file's one period)."""
    if month is not None and season is not None:
        raise ValueError("give month or season, not both")
    if month is not None:
        if not 1 <= int(month) <= 12:
            raise ValueError(f"month must be 1..12, got {month!r}")
        return frozenset({int(month)})
    if season is not None:
        if season not in SEASONS:
            raise ValueError(f"season must be one of {', '.join(SEASONS)}, got {season!r}")
        return frozenset(SEASONS[season])
    return None


_SINCE = re.compile(
    r"^\s*(months?|days?|hours?|minutes?|seconds?)\s+since\s+(-?\d{1,4})-(\d{1,2})(?:-(\d{1,2}))?", re.IGNORECASE
)
_GREGORIAN = {"standard", "gregorian", "proleptic_gregorian"}


def period_months(ds: Any, path: str | Path, time_dim: str) -> list[frozenset[int]]:
    """The calendar months each step of the time axis covers: from its CF ``climatology`` (or
    ``bounds``) variable, [start, end) per step, else the month of the time value itself."""
    tv = ds[time_dim]
    units = str(tv.attrs.get("units", ""))
    m = _SINCE.match(units)
    if m is None:
        raise DataFileError(path, time_dim, f"time units {units!r} are not '<unit> since <date>'")
    unit, year, month, day = m.group(1).lower().rstrip("s"), int(m.group(2)), int(m.group(3)), int(m.group(4) or 1)
    cal = str(tv.attrs.get("calendar", "standard")).lower()
    if unit != "month" and cal not in _GREGORIAN:
        raise DataFileError(path, time_dim, f"calendar {cal!r}: only the Gregorian calendar is read")

    def month_index(v: float) -> int:
        """Months since year 0 of the instant v (in the axis' units)."""
        if unit == "month":
            return year * 12 + month - 1 + int(np.floor(v))
        step = {"day": 86400.0, "hour": 3600.0, "minute": 60.0, "second": 1.0}[unit]
        t = datetime(year, month, day) + timedelta(seconds=float(v) * step)
        return t.year * 12 + t.month - 1

    values = np.atleast_1d(np.asarray(tv.values, float))
    clim = tv.attrs.get("climatology")
    bname = clim or tv.attrs.get("bounds")
    out = []
    for k, v in enumerate(values):
        if bname and bname in ds.variables:
            b0, b1 = (float(b) for b in np.asarray(ds[bname].values, float).reshape(values.size, 2)[k])
            first, last = month_index(b0), month_index(b1 - 1e-6)  # the end is exclusive
            # a climatology's bounds run from the first year's period to the last one's: the
            # period is that within each year (CF 7.4); plain bounds are one span of time
            count = (last - first) % 12 + 1 if clim else min(last - first + 1, 12)
        else:
            first, count = month_index(float(v)), 1
        out.append(frozenset((first + i) % 12 + 1 for i in range(max(count, 1))))
    return out


def _time_index(ds: Any, path: Path, name: str, time_dim: str | None, period: frozenset[int] | None) -> int | None:
    if time_dim is None:
        if period is None:
            return None
        raise DataFileError(path, name, f"has no time axis: cannot tell whether it is {_describe(period)}")
    steps = period_months(ds, path, time_dim)
    if period is None:
        if len(steps) == 1:
            return 0
        held = ", ".join(_describe(s) for s in steps)
        raise DataFileError(path, name, f"holds {len(steps)} periods ({held}): choose one with month or season")
    for k, s in enumerate(steps):
        if s == period:
            return k
    held = ", ".join(_describe(s) for s in steps)
    raise DataFileError(path, name, f"holds {held}, not {_describe(period)}")


# --------------------------------------------------------------------------- reading


def _grid(frame: LocalFrame, path: Path, name: str, lat: FloatArray, lon: FloatArray) -> LatLonGrid:
    try:
        return LatLonGrid(frame, lat, lon)
    except ValueError as e:
        raise DataFileError(path, name, str(e).replace("LatLonGrid: ", "")) from None


def _covering(grid: LatLonGrid, path: Path, name: str, box: Box | None) -> tuple[slice, slice]:
    """Checks that the grid covers the box; the index slices of the nodes over it (and around)."""
    if box is None:
        return slice(None), slice(None)
    if not grid.covers(*box):
        raise DataFileError(
            path,
            name,
            f"covers {grid.extent()}, not the scenario's volume (lat {box[0]:.4f}..{box[1]:.4f}, "
            f"lon {box[2]:.4f}..{box[3]:.4f})",
        )
    return grid.crop(*box)


def _variable_grid(
    ds: Any,
    path: Path,
    name: str,
    frame: LocalFrame,
    kinds: Sequence[str],
    period: frozenset[int] | None,
    box: Box | None,
) -> tuple[FloatArray, LatLonGrid, FloatArray | None]:
    """(values (lat, lon[, depth]) ascending in each, the grid cropped to the box, depths or None)."""
    da = ds[name]
    dims = {}
    for kind in kinds:
        d = _dim(ds, da, kind)
        if d is None:
            raise DataFileError(path, name, f"has no {kind} axis (its dimensions: {', '.join(map(str, da.dims))})")
        dims[kind] = d
    time_dim = _dim(ds, da, "time")
    t = _time_index(ds, path, name, time_dim, period)
    if time_dim is not None:
        da = da.isel({time_dim: t})
    extra = [d for d in da.dims if d not in dims.values()]
    if any(da.sizes[d] > 1 for d in extra):
        raise DataFileError(path, name, f"has dimensions besides {', '.join(kinds)}: {', '.join(map(str, extra))}")
    da = da.isel(dict.fromkeys(extra, 0)).transpose(*(dims[k] for k in kinds))
    lat = _coordinate(ds, path, name, dims["latitude"])
    lon = _coordinate(ds, path, name, dims["longitude"])
    values = np.asarray(da.values, float)
    # ascending latitude and longitude (some grids run north to south)
    if lat.size > 1 and lat[0] > lat[-1]:
        lat, values = lat[::-1], values[::-1]
    if lon.size > 1 and lon[0] > lon[-1] and np.all(np.diff(lon) < 0):
        lon, values = lon[::-1], values[:, ::-1]
    depth = None
    if "depth" in dims:
        depth = _coordinate(ds, path, name, dims["depth"])
        if str(ds[dims["depth"]].attrs.get("positive", "down")).lower() == "up" or np.all(depth <= 0.0):
            depth = -depth
        order = np.argsort(depth)
        depth, values = depth[order], values[..., order]
        if depth[0] != 0.0:
            raise DataFileError(
                path, dims["depth"], f"starts at {depth[0]:g} m: the subset must include the surface (0 m)"
            )
    grid = _grid(frame, path, name, lat, lon)
    si, sj = _covering(grid, path, name, box)
    return values[si, sj], _grid(frame, path, name, lat[si], lon[sj]), depth


def _fill(values: FloatArray) -> FloatArray | None:
    """NaN cells (m, n, K) filled: down each column from the deepest value above, up from the
    shallowest below; empty columns from the nearest column with values (grid steps). None
    where no column has any value."""
    a = np.array(values, float)
    ok = np.isfinite(a)
    k = np.arange(a.shape[-1])
    down = np.maximum.accumulate(np.where(ok, k, 0), axis=-1)
    a = np.where(ok, a, np.take_along_axis(a, down, axis=-1))
    ok = np.isfinite(a)
    up = np.minimum.accumulate(np.where(ok, k, k[-1])[..., ::-1], axis=-1)[..., ::-1]
    a = np.where(ok, a, np.take_along_axis(a, up, axis=-1))
    wet = np.isfinite(a).all(axis=-1)
    if not wet.any():
        return None
    if not wet.all():
        from scipy.ndimage import distance_transform_edt

        _, (ii, jj) = distance_transform_edt(~wet, return_indices=True)
        a = a[ii, jj]
    return a


def _paths(paths: str | Path | Sequence[str | Path]) -> list[Path]:
    return [Path(paths)] if isinstance(paths, (str, Path)) else [Path(p) for p in paths]


def _read(
    paths: list[Path],
    name: str,
    frame: LocalFrame,
    kinds: Sequence[str],
    period: frozenset[int] | None,
    box: Box | None,
) -> tuple[Path, FloatArray, LatLonGrid, FloatArray | None]:
    """The first of the files that has the variable ``name``: (its path, values, grid, depths)."""
    from .gridio import open_dataset

    seen: list[str] = []
    for p in paths:
        with open_dataset(p, decode_times=False) as ds:
            if name in ds.variables:
                return (p, *_variable_grid(ds, p, name, frame, kinds, period, box))
            seen += [v for v in _gridded(ds) if v not in seen]
    where = ", ".join(str(p) for p in paths)
    raise DataFileError(where, name, f"no such variable (gridded variables there: {', '.join(seen) or 'none'})")


def _gridded(ds: Any) -> list[str]:
    """The data variables of two or more dimensions but bounds: for messages."""
    return [str(v) for v, da in ds.data_vars.items() if da.ndim >= 2 and not str(v).endswith(("_bnds", "_bounds"))]


def read_woa(
    paths: str | Path | Sequence[str | Path],
    frame: LocalFrame,
    *,
    month: int | None = None,
    season: str | None = None,
    box: Box | None = None,
    temperature: str = "t_an",
    salinity: str = "s_an",
) -> GeographicField:
    """The TEOS-10 sound-speed field of WOA temperature and salinity (one file holding both, or
    WOA's two), for ``month`` (1-12) or ``season`` (winter, spring, summer, autumn), or the files'
    one period when neither is given. ``box`` = (lat_min, lat_max, lon_min, lon_max): the
    files must cover it (between grid nodes, where they interpolate), and the field keeps the
    nodes over it and two around."""
    ps = _paths(paths)
    period = requested_period(month, season)
    kinds = ("latitude", "longitude", "depth")
    t_path, t, grid, depth = _read(ps, temperature, frame, kinds, period, box)
    s_path, s, s_grid, s_depth = _read(ps, salinity, frame, kinds, period, box)
    assert depth is not None and s_depth is not None
    same = (
        s_grid.shape == grid.shape
        and np.array_equal(s_grid.latitude, grid.latitude)
        and np.array_equal(s_grid.longitude, grid.longitude)
        and np.array_equal(s_depth, depth)
    )
    if not same:
        raise DataFileError(s_path, salinity, f"is not on the grid of {temperature} in {t_path}")
    filled = []
    for path, name, v, (lo, hi, what) in (
        (t_path, temperature, t, _PLAUSIBLE_T),
        (s_path, salinity, s, _PLAUSIBLE_S),
    ):
        f = _fill(v)
        if f is None:
            raise DataFileError(path, name, "has no value over the scenario's volume (all cells masked)")
        if f.min() < lo or f.max() > hi:
            raise DataFileError(path, name, f"values {f.min():g} .. {f.max():g} are not {what} ({lo:g} .. {hi:g})")
        filled.append(f)
    return GeographicField.from_ts(grid, depth, filled[0], filled[1])


def read_gebco(
    path: str | Path, frame: LocalFrame, *, box: Box | None = None, variable: str | None = None
) -> GeographicBathymetry:
    """The sea floor of a GEBCO (``elevation``) or ETOPO 2022 (``z``) grid: depth = -elevation
    (a variable whose CF attributes say positive down, or whose standard name is a depth, is
    taken as depth), 0 where the grid is land. ``box`` as in :func:`read_woa`."""
    p = Path(path)
    names = [variable] if variable else ["elevation", "z"]
    from .gridio import open_dataset

    with open_dataset(p, decode_times=False) as ds:
        name = next((n for n in names if n in ds.variables), None)
        if name is None:
            held = ", ".join(_gridded(ds)) or "none"
            want = names[0] if variable else "elevation"
            raise DataFileError(
                p, want, f"no such variable (GEBCO's elevation or ETOPO's z; gridded variables there: {held})"
            )
        values, grid, _ = _variable_grid(ds, p, name, frame, ("latitude", "longitude"), None, box)
        attrs = ds[name].attrs
    if not np.all(np.isfinite(values)):
        raise DataFileError(p, name, "has missing values over the scenario's volume")
    positive_down = str(attrs.get("positive", "up")).lower() == "down" or "depth" in str(attrs.get("standard_name", ""))
    depth = values if positive_down else -values
    return GeographicBathymetry(grid, np.maximum(depth, 0.0))
