"""Ocean data on latitude / longitude grids, placed in a scenario's local east-north frame.

A scenario placed on the globe has an origin (latitude, longitude) and works in metres: x east,
y north, z depth. :class:`LocalFrame` is that map: the azimuthal equidistant projection about
the origin on the WGS 84 ellipsoid (pyproj / PROJ ``aeqd``), so that distances and bearings from
the origin are true and, within 20 km of it, distances between any two points are true to a few
1e-6 (the scale across the radius is ~1 + (r / R)^2 / 6; the x / y axes point east / north at
the origin).

Data files (World Ocean Atlas temperature and salinity, GEBCO or ETOPO bathymetry,
:mod:`.oceanfiles`) stay on their own grid: :class:`LatLonGrid` takes a point of the frame back
to latitude / longitude (exactly, through the projection) and interpolates bilinearly in
latitude and longitude between the four grid nodes around it (clamped at the grid's edges); the
floor is bicubic there instead (:class:`GeographicBathymetry`: a continuous slope for the ray
tracer's smooth floor). So a grid node's value is the file's, wherever the node lands in the frame.

In the frame the grid's parallels and meridians are curves (the meridians converge). The ray
tracer samples a field along a straight line at its kinks (:meth:`LatLonGrid.crossings`): the
points where the line crosses a grid parallel or meridian, found by Newton's method on the
exact projection to ~1e-8 m (the projection's own round trip is good to ~4e-9 m), so that they
are geographic points (moving an end of a link along its line does not move them). One crossing per grid line and link is kept; a line that runs
within metres of a parallel and nearly along it can cross it twice, and then only one of the two
crossings is a column of the section (the field along such a line is nearly linear there).

:class:`GeographicField` (sound speed) and :class:`GeographicBathymetry` (sea-floor depth) are
the :mod:`.fields` / :mod:`.bathymetry` classes of such grids; the readers build them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .bathymetry import Bathymetry, bicubic, ghost_padded
from .fields import SoundSpeedField, _check_depths, _check_speeds, _depth_interp

__all__ = ["GeographicBathymetry", "GeographicField", "LatLonGrid", "LocalFrame"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

_NEWTON_STEPS = 4
_NEWTON_TOL_M = 1e-6  # a crossing whose residual stays above this (in metres along the line) is dropped


@dataclass(frozen=True)
class LocalFrame:
    """The local east-north frame about ``origin`` = (latitude, longitude) in degrees (WGS 84):
    x east, y north (m), the azimuthal equidistant projection about the origin."""

    latitude: float
    longitude: float

    def __post_init__(self) -> None:
        lat, lon = float(self.latitude), float(self.longitude)
        if not (math.isfinite(lat) and -90.0 < lat < 90.0):
            raise ValueError(f"LocalFrame: latitude must lie strictly between -90 and 90 deg, got {lat!r}")
        if not (math.isfinite(lon) and -360.0 <= lon <= 360.0):
            raise ValueError(f"LocalFrame: longitude must be finite degrees in [-360, 360], got {lon!r}")
        object.__setattr__(self, "latitude", lat)
        object.__setattr__(self, "longitude", lon)

    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        state.pop("_transformer", None)  # PROJ's handle is rebuilt where the frame is unpickled
        return state

    @cached_property
    def _transformer(self) -> Any:
        try:
            from pyproj import CRS, Transformer
        except ImportError as e:  # pragma: no cover - depends on the environment
            raise ImportError(
                "a scenario placed by latitude / longitude needs pyproj: pip install 'aquasim-py[ocean]'"
            ) from e
        local = CRS.from_proj4(
            f"+proj=aeqd +lat_0={self.latitude!r} +lon_0={self.longitude!r} +datum=WGS84 +units=m +no_defs"
        )
        return Transformer.from_crs(CRS.from_epsg(4326), local, always_xy=True)

    def to_xy(self, latitude: ArrayLike, longitude: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """(x, y) in metres of points given in degrees (broadcast)."""
        lat, lon = np.broadcast_arrays(np.asarray(latitude, float), np.asarray(longitude, float))
        x, y = self._transformer.transform(lon, lat)
        return np.asarray(x, float).reshape(lat.shape), np.asarray(y, float).reshape(lat.shape)

    def to_latlon(self, x: ArrayLike, y: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """(latitude, longitude) in degrees of frame points (m, broadcast); longitudes in
        (-180, 180]."""
        xx, yy = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        lon, lat = self._transformer.transform(xx, yy, direction="INVERSE")
        return np.asarray(lat, float).reshape(xx.shape), np.asarray(lon, float).reshape(xx.shape)

    def footprint(self, lo: ArrayLike, hi: ArrayLike, samples: int = 65) -> tuple[float, float, float, float]:
        """(lat_min, lat_max, lon_min, lon_max) of the rectangle lo..hi ((x, y), m) of the frame
        (its boundary sampled: latitude and longitude have no extremum inside so small a box)."""
        (x0, y0), (x1, y1) = np.asarray(lo, float)[:2], np.asarray(hi, float)[:2]
        t = np.linspace(0.0, 1.0, samples)
        xs = np.concatenate([x0 + (x1 - x0) * t, np.full(samples, x1), x1 + (x0 - x1) * t, np.full(samples, x0)])
        ys = np.concatenate([np.full(samples, y0), y0 + (y1 - y0) * t, np.full(samples, y1), y1 + (y0 - y1) * t])
        lat, lon = self.to_latlon(xs, ys)
        lon = _unwrap_to(lon, self.longitude)
        return float(lat.min()), float(lat.max()), float(lon.min()), float(lon.max())


def _unwrap_to(lon: FloatArray, centre: float) -> FloatArray:
    """Longitudes shifted by whole turns to lie within 180 deg of ``centre``."""
    return centre + np.mod(np.asarray(lon, float) - centre + 180.0, 360.0) - 180.0


def _axis_weights(grid: FloatArray, q: FloatArray) -> tuple[IntArray, IntArray, FloatArray]:
    """Bilinear indices (i, i + 1) and weight of q on an increasing axis, clamped at its ends."""
    if grid.size == 1:
        zero = np.zeros(q.shape, np.intp)
        return zero, zero, np.zeros(q.shape)
    i = np.clip(np.searchsorted(grid, q, side="right") - 1, 0, grid.size - 2)
    w = np.clip((q - grid[i]) / (grid[i + 1] - grid[i]), 0.0, 1.0)
    return i, i + 1, w


class LatLonGrid:
    """Nodes at ``latitude`` (m,) x ``longitude`` (n,) degrees, both strictly increasing (the
    longitudes may run past 180: a grid across the antimeridian), placed in ``frame``."""

    def __init__(self, frame: LocalFrame, latitude: ArrayLike, longitude: ArrayLike) -> None:
        lat = np.asarray(latitude, float).ravel().copy()
        lon = np.asarray(longitude, float).ravel().copy()
        # a subset across the antimeridian (179.75, 180.0, -179.75 ...) runs on past 180
        lon = lon + 360.0 * np.concatenate([[0], np.cumsum(np.diff(lon) < -180.0)])
        for name, a in (("latitude", lat), ("longitude", lon)):
            if a.size < 1 or not np.all(np.isfinite(a)) or np.any(np.diff(a) <= 0.0):
                raise ValueError(f"LatLonGrid: {name} must be finite and strictly increasing")
        if lat[0] <= -90.0 or lat[-1] >= 90.0:
            raise ValueError("LatLonGrid: latitudes must lie strictly between -90 and 90 deg")
        for a in (lat, lon):
            a.setflags(write=False)
        self.frame = frame
        self.latitude = lat
        self.longitude = lon
        self._lon_centre = 0.5 * (float(lon[0]) + float(lon[-1]))

    @property
    def shape(self) -> tuple[int, int]:
        return self.latitude.size, self.longitude.size

    def latlon(self, x: ArrayLike, y: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """(latitude, longitude) of frame points, longitudes on the grid's own turn."""
        lat, lon = self.frame.to_latlon(x, y)
        return lat, _unwrap_to(lon, self._lon_centre)

    def nodes_xy(self) -> tuple[FloatArray, FloatArray]:
        """(x, y) (m, shape (m, n)) of every node in the frame."""
        return self.frame.to_xy(self.latitude[:, None], self.longitude[None, :])

    def bilinear(self, values: FloatArray, x: ArrayLike, y: ArrayLike) -> FloatArray:
        """``values`` (m, n, ...) interpolated at frame points x, y (...): shape (..., *rest)."""
        lat, lon = self.latlon(x, y)
        i0, i1, wi = _axis_weights(self.latitude, lat)
        j0, j1, wj = _axis_weights(self.longitude, lon)
        extra = (None,) * (values.ndim - 2)
        wi, wj = wi[(..., *extra)], wj[(..., *extra)]
        return (values[i0, j0] * (1 - wj) + values[i0, j1] * wj) * (1 - wi) + (
            values[i1, j0] * (1 - wj) + values[i1, j1] * wj
        ) * wi

    @cached_property
    def cell_m(self) -> float:
        """The longest diagonal of a grid cell in the frame (m); one node apart on a one-node axis."""
        x, y = self.nodes_xy()
        if min(self.shape) == 1:
            return float(np.max(np.hypot(np.diff(x.ravel()), np.diff(y.ravel())), initial=1.0))
        d1 = np.hypot(x[1:, 1:] - x[:-1, :-1], y[1:, 1:] - y[:-1, :-1])
        d2 = np.hypot(x[1:, :-1] - x[:-1, 1:], y[1:, :-1] - y[:-1, 1:])
        return float(max(d1.max(), d2.max()))

    def covers(self, lat_min: float, lat_max: float, lon_min: float, lon_max: float) -> bool:
        """Whether the box lies inside the grid's nodes (where it interpolates, not clamps)."""
        lo = _unwrap_to(np.array([lon_min, lon_max]), self._lon_centre)
        return bool(
            self.latitude[0] <= lat_min
            and lat_max <= self.latitude[-1]
            and self.longitude[0] <= lo[0]
            and lo[1] <= self.longitude[-1]
        )

    def extent(self) -> str:
        """The grid's span, for messages."""
        return (
            f"lat {self.latitude[0]:.4f}..{self.latitude[-1]:.4f}, "
            f"lon {self.longitude[0]:.4f}..{self.longitude[-1]:.4f}"
        )

    def crop(
        self, lat_min: float, lat_max: float, lon_min: float, lon_max: float, margin: int = 2
    ) -> tuple[slice, slice]:
        """Index slices of the nodes over the box and ``margin`` nodes around it."""
        lo = _unwrap_to(np.array([lon_min, lon_max]), self._lon_centre)

        def span(g: FloatArray, a: float, b: float) -> slice:
            i = max(int(np.searchsorted(g, a, side="right")) - 1 - margin, 0)
            j = min(int(np.searchsorted(g, b, side="left")) + 1 + margin, g.size)
            return slice(i, j)

        return span(self.latitude, lat_min, lat_max), span(self.longitude, float(lo[0]), float(lo[1]))

    def crossings(
        self, x0: FloatArray, y0: FloatArray, ux: FloatArray, uy: FloatArray, length: FloatArray
    ) -> FloatArray:
        """Distances (n, m + n_lon) along the lines (x0, y0) + r (ux, uy) at which each crosses
        each grid parallel (first m columns) and meridian, within 1.5 cells of [0, length] (NaN
        elsewhere and for grid lines not crossed there); to ~1e-8 m (Newton on the projection)."""
        x0, y0, ux, uy, length = (np.asarray(a, float).ravel() for a in (x0, y0, ux, uy, length))
        n = x0.size
        m_lat, m_lon = self.shape
        out = np.full((n, m_lat + m_lon), np.nan)
        if n == 0:
            return out
        pad = 1.5 * self.cell_m
        ra, rb = np.full(n, -pad), length + pad
        # the window's latitude / longitude at a few points: the grid lines it may cross
        t = np.linspace(0.0, 1.0, 5)
        rs = ra[:, None] + (rb - ra)[:, None] * t[None, :]
        lat_s, lon_s = self.latlon(x0[:, None] + rs * ux[:, None], y0[:, None] + rs * uy[:, None])
        for col, grid, vals, which in ((0, self.latitude, lat_s, 0), (m_lat, self.longitude, lon_s, 1)):
            if grid.size < 2:
                continue
            i0 = np.clip(np.searchsorted(grid, vals.min(axis=1), side="left") - 1, 0, grid.size - 1)
            i1 = np.clip(np.searchsorted(grid, vals.max(axis=1), side="right"), 0, grid.size - 1)
            cnt = i1 - i0 + 1
            link = np.repeat(np.arange(n), cnt)
            first = np.repeat(np.cumsum(cnt) - cnt, cnt)
            idx = i0[link] + np.arange(link.size) - first
            r = self._solve(x0[link], y0[link], ux[link], uy[link], grid[idx], which, rs[link], vals[link])
            ok = np.isfinite(r) & (r >= ra[link]) & (r <= rb[link])
            out[link[ok], col + idx[ok]] = r[ok]
        return out

    def _coord(self, x: FloatArray, y: FloatArray, which: int) -> FloatArray:
        return self.latlon(x, y)[which]

    def _solve(
        self,
        x0: FloatArray,
        y0: FloatArray,
        ux: FloatArray,
        uy: FloatArray,
        target: FloatArray,
        which: int,
        rs: FloatArray,
        vals: FloatArray,
    ) -> FloatArray:
        """r where the coordinate ``which`` (0 latitude, 1 longitude) of (x0, y0) + r (ux, uy)
        equals ``target``: Newton from the sampled window's nearest chord, the slope taken once at
        the start (the slope varies by ~1e-5 over a window, so 4 steps reach the projection's
        own precision)."""
        if target.size == 0:
            return target.copy()
        # start: the chord of the window's samples that brackets the target (else the whole window)
        lo, hi = vals[:, :-1], vals[:, 1:]
        brackets = (np.minimum(lo, hi) <= target[:, None]) & (target[:, None] <= np.maximum(lo, hi))
        k = np.where(brackets.any(axis=1), np.argmax(brackets, axis=1), 0)
        rows = np.arange(target.size)
        r_lo, r_hi = rs[rows, k], rs[rows, k + 1]
        v_lo, v_hi = vals[rows, k], vals[rows, k + 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            r = r_lo + (target - v_lo) * (r_hi - r_lo) / (v_hi - v_lo)
            h = 1.0
            v = self._coord(x0 + r * ux, y0 + r * uy, which)
            slope = (self._coord(x0 + (r + h) * ux, y0 + (r + h) * uy, which) - v) / h
            for _ in range(_NEWTON_STEPS):
                step = (v - target) / slope
                r = r - step
                v = self._coord(x0 + r * ux, y0 + r * uy, which)
            miss = np.abs((v - target) / slope)
        return np.where(np.isfinite(r) & (miss <= _NEWTON_TOL_M), r, np.nan)


@dataclass(frozen=True, eq=False, init=False)
class GeographicField(SoundSpeedField):
    """Sound speeds ``speeds`` (m, n, K) on a :class:`LatLonGrid` and ``depths`` (K,):
    bilinear in latitude and longitude, linear in depth (the last gradient continues below)."""

    grid: LatLonGrid
    speeds: FloatArray

    def __init__(self, grid: LatLonGrid, depths: ArrayLike, speeds: ArrayLike) -> None:
        d = np.asarray(depths, float).ravel().copy()
        c = np.asarray(speeds, float).copy()
        _check_depths("GeographicField", d)
        if c.shape != (*grid.shape, d.size):
            raise ValueError(f"GeographicField: speeds must have shape {(*grid.shape, d.size)}, got {c.shape}")
        _check_speeds("GeographicField", c)
        for a in (d, c):
            a.setflags(write=False)
        object.__setattr__(self, "grid", grid)
        object.__setattr__(self, "depths", d)
        object.__setattr__(self, "speeds", c)

    @classmethod
    def from_ts(
        cls, grid: LatLonGrid, depths: ArrayLike, temperature: ArrayLike, salinity: ArrayLike
    ) -> GeographicField:
        """From in-situ temperature (deg C, ITS-90) and practical salinity (PSS-78), both (m, n, K),
        through TEOS-10 at each node's own latitude and longitude
        (:func:`aquasim_py.channel.ssp.teos10_speed`)."""
        from .ssp import teos10_speed

        d = np.asarray(depths, float)
        lat = grid.latitude[:, None, None]
        lon = grid.longitude[None, :, None]
        return cls(grid, d, teos10_speed(d, temperature, salinity, lat, lon))

    def columns(self, x: FloatArray, y: FloatArray) -> FloatArray:
        return self.grid.bilinear(self.speeds, x, y)

    def speed(self, x: ArrayLike, y: ArrayLike, z: ArrayLike) -> FloatArray:
        x, y, z = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float), np.asarray(z, float))
        return _depth_interp(self.depths, self.columns(x, y), z)

    def section_ranges(self, x0, y0, ux, uy, length) -> FloatArray:
        return self.grid.crossings(x0, y0, ux, uy, length)

    @property
    def depth_only(self) -> bool:
        return bool(np.all(self.speeds == self.speeds[:1, :1]))


@dataclass(frozen=True, eq=False)
class GeographicBathymetry(Bathymetry):
    """Sea-floor depths ``depths`` (m, n; m, positive down, 0 on land) on a :class:`LatLonGrid`,
    bicubic in latitude and longitude between the nodes (as :class:`~.bathymetry.GriddedBathymetry`
    in x and y: Hermite with the slopes of the parabola through each node and its neighbours,
    through every node, with a continuous slope), the edge values beyond. The ray tracer's floor
    is then the smooth curve through its samples with their slopes (:meth:`slope_along`); a grid
    with a single latitude or longitude is bilinear (linear along its one axis), and its section
    the polyline of the samples."""

    grid: LatLonGrid
    depths: FloatArray

    def __post_init__(self) -> None:
        d = np.asarray(self.depths, float).copy()
        if d.shape != self.grid.shape:
            raise ValueError(f"GeographicBathymetry: depths must have shape {self.grid.shape}, got {d.shape}")
        if not np.all(np.isfinite(d)) or np.any(d < 0.0):
            raise ValueError("GeographicBathymetry: depths must be finite and >= 0 (positive down, 0 on land)")
        d.setflags(write=False)
        object.__setattr__(self, "depths", d)

    @cached_property
    def _padded(self) -> FloatArray | None:
        """The depths with ghost nodes (:func:`~.bathymetry.ghost_padded`); None on a one-node axis."""
        return ghost_padded(self.depths) if min(self.grid.shape) >= 2 else None

    def depth(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        if self._padded is None:
            return self.grid.bilinear(self.depths, x, y)
        lat, lon = self.grid.latlon(x, y)
        return bicubic(self.grid.latitude, self.grid.longitude, self._padded, lat, lon)[0]

    def slope_along(self, x, y, ux, uy) -> FloatArray | None:
        """d depth / d r along (ux, uy): the bicubic's latitude and longitude slopes times the
        rates of latitude and longitude along the line (central differences of the exact inverse
        projection over +-1 m: the projection's curvature makes their error ~1e-12 relative,
        rounding ~1e-9)."""
        if self._padded is None:
            return None
        x, y, ux, uy = (np.asarray(a, float) for a in (x, y, ux, uy))
        lat, lon = self.grid.latlon(x, y)
        _d, g_lat, g_lon = bicubic(self.grid.latitude, self.grid.longitude, self._padded, lat, lon)
        lat_p, lon_p = self.grid.latlon(x + ux, y + uy)
        lat_m, lon_m = self.grid.latlon(x - ux, y - uy)
        return g_lat * 0.5 * (lat_p - lat_m) + g_lon * 0.5 * (lon_p - lon_m)

    def max_depth(self) -> float:
        return float(self.depths.max())

    def section_ranges(self, x0, y0, ux, uy, length) -> FloatArray:
        return self.grid.crossings(x0, y0, ux, uy, length)

    @property
    def is_flat(self) -> bool:
        return bool(np.all(self.depths == self.depths.flat[0]))
