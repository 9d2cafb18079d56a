"""Sound-speed fields c(x, y, z): m/s at horizontal position (x, y) (m) and depth z (m, down).

* :class:`DepthProfile`: one profile everywhere (the range-independent case; wraps any
  :class:`~.ssp.SoundSpeedProfile`).
* :class:`RangeProfiles`: profiles at several distances along a horizontal line (a section
  across a front or a slope), linear between them, constant across the line and beyond its
  ends.
* :class:`GriddedField`: a rectilinear (x, y, z) grid, bilinear horizontally; from speeds, or
  from temperature / salinity through TEOS-10 (:meth:`GriddedField.from_ts`), or from a netCDF
  file read with xarray (:meth:`GriddedField.from_netcdf`).

Every field is piecewise linear in depth between its ``depths`` (the last gradient continues
below them). For the ray tracer a field gives ``section_ranges``: the distances along a line at
which the line crosses the field's horizontal grid (profiles are sampled there; between them
the tracer's section is linear in range on each triangle of its (range, depth) grid, see
:mod:`.rangedep`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .bathymetry import line_crossings
from .ssp import SoundSpeedProfile

__all__ = ["DepthProfile", "GriddedField", "RangeProfiles", "SoundSpeedField"]

FloatArray = NDArray[np.float64]


def _depth_interp(depths: FloatArray, speeds: FloatArray, z: FloatArray) -> FloatArray:
    """Piecewise-linear interpolation in depth along the last axis of ``speeds`` (..., K) at z
    (broadcast against speeds[..., 0]); the end gradients continue beyond the nodes."""
    k = np.clip(np.searchsorted(depths, z, side="right") - 1, 0, depths.size - 2)
    z0, z1 = depths[k], depths[k + 1]
    c0 = np.take_along_axis(speeds, k[..., None], axis=-1)[..., 0]
    c1 = np.take_along_axis(speeds, (k + 1)[..., None], axis=-1)[..., 0]
    return c0 + (c1 - c0) * ((z - z0) / (z1 - z0))


def _check_depths(name: str, d: FloatArray) -> None:
    if d.size < 2 or d[0] != 0.0 or np.any(np.diff(d) <= 0.0) or not np.all(np.isfinite(d)):
        raise ValueError(f"{name}: depths must start at 0, increase strictly and be finite (at least 2)")


def _check_speeds(name: str, c: FloatArray) -> None:
    if not np.all(np.isfinite(c)) or np.any(c <= 0.0):
        raise ValueError(f"{name}: speeds must be positive and finite")


class SoundSpeedField:
    """Base class: c(x, y, z) piecewise linear in depth between ``depths``."""

    depths: FloatArray

    def speed(self, x: ArrayLike, y: ArrayLike, z: ArrayLike) -> FloatArray:
        raise NotImplementedError

    def columns(self, x: FloatArray, y: FloatArray) -> FloatArray:
        """The profiles (..., K) at horizontal positions x, y (...), on ``depths``."""
        raise NotImplementedError

    def section_ranges(
        self, x0: FloatArray, y0: FloatArray, ux: FloatArray, uy: FloatArray, length: FloatArray
    ) -> FloatArray:
        """Signed distances (n, m) along the lines (x0, y0) + r (ux, uy) at which the field's
        horizontal interpolation has a kink (anywhere on the line); NaN-padded."""
        return np.empty((np.size(x0), 0))

    @property
    def depth_only(self) -> bool:
        return False


@dataclass(frozen=True)
class DepthProfile(SoundSpeedField):
    """One profile everywhere: the range-independent field (its ``to_layered`` depths)."""

    profile: SoundSpeedProfile

    def __post_init__(self) -> None:
        lay = self.profile.to_layered()
        object.__setattr__(self, "depths", np.asarray(lay.depths))
        object.__setattr__(self, "_speeds", np.asarray(lay.speeds))

    def speed(self, x: ArrayLike, y: ArrayLike, z: ArrayLike) -> FloatArray:
        shape = np.broadcast(np.asarray(x), np.asarray(y), np.asarray(z)).shape
        return np.broadcast_to(self.profile.speed(np.asarray(z, float)), shape).astype(float)

    def columns(self, x: FloatArray, y: FloatArray) -> FloatArray:
        shape = np.broadcast(np.asarray(x), np.asarray(y)).shape
        return np.broadcast_to(self._speeds, (*shape, self.depths.size))  # type: ignore[attr-defined]

    @property
    def depth_only(self) -> bool:
        return True


@dataclass(frozen=True, eq=False, init=False)
class RangeProfiles(SoundSpeedField):
    """Profiles ``speeds`` (J, K) on ``depths`` (K,) at distances ``ranges`` (J,) along the
    horizontal line from ``origin`` (x, y) at ``azimuth_deg`` (counter-clockwise from +x):
    linear in that distance between profiles, constant across the line and beyond its ends."""

    ranges: FloatArray
    speeds: FloatArray
    origin: tuple[float, float]
    azimuth_deg: float

    def __init__(
        self,
        ranges: ArrayLike,
        depths: ArrayLike,
        speeds: ArrayLike,
        origin: tuple[float, float] = (0.0, 0.0),
        azimuth_deg: float = 0.0,
    ) -> None:
        r = np.asarray(ranges, float).ravel().copy()
        d = np.asarray(depths, float).ravel().copy()
        c = np.asarray(speeds, float).copy()
        if r.size < 1 or np.any(np.diff(r) <= 0.0) or not np.all(np.isfinite(r)):
            raise ValueError("RangeProfiles: ranges must be finite and increase strictly")
        _check_depths("RangeProfiles", d)
        if c.shape != (r.size, d.size):
            raise ValueError(
                f"RangeProfiles: speeds must have shape (len(ranges), len(depths)) = {(r.size, d.size)}, got {c.shape}"
            )
        _check_speeds("RangeProfiles", c)
        o = (float(origin[0]), float(origin[1]))
        az = float(azimuth_deg)
        if not (math.isfinite(o[0]) and math.isfinite(o[1]) and math.isfinite(az)):
            raise ValueError("RangeProfiles: origin and azimuth_deg must be finite")
        for a in (r, d, c):
            a.setflags(write=False)
        object.__setattr__(self, "ranges", r)
        object.__setattr__(self, "depths", d)
        object.__setattr__(self, "speeds", c)
        object.__setattr__(self, "origin", o)
        object.__setattr__(self, "azimuth_deg", az)

    @property
    def _axis(self) -> tuple[float, float]:
        a = math.radians(self.azimuth_deg)
        return math.cos(a), math.sin(a)

    def along(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        """Distance along the section's line of the points' projections (m)."""
        ax, ay = self._axis
        return (np.asarray(x, float) - self.origin[0]) * ax + (np.asarray(y, float) - self.origin[1]) * ay

    def columns(self, x: FloatArray, y: FloatArray) -> FloatArray:
        a = self.along(x, y)
        r, c = self.ranges, self.speeds
        if r.size == 1:
            return np.broadcast_to(c[0], (*np.shape(a), self.depths.size))
        j = np.clip(np.searchsorted(r, a, side="right") - 1, 0, r.size - 2)
        w = np.clip((a - r[j]) / (r[j + 1] - r[j]), 0.0, 1.0)[..., None]
        return c[j] * (1.0 - w) + c[j + 1] * w

    def speed(self, x: ArrayLike, y: ArrayLike, z: ArrayLike) -> FloatArray:
        x, y, z = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float), np.asarray(z, float))
        return _depth_interp(self.depths, self.columns(x, y), z)

    def section_ranges(self, x0, y0, ux, uy, length) -> FloatArray:
        ax, ay = self._axis
        return line_crossings(self.ranges, self.along(x0, y0), ux * ax + uy * ay, length)

    @property
    def depth_only(self) -> bool:
        return bool(self.ranges.size == 1 or np.all(self.speeds == self.speeds[0]))


@dataclass(frozen=True, eq=False, init=False)
class GriddedField(SoundSpeedField):
    """Speeds (nx, ny, K) on a rectilinear grid x (nx,), y (ny,), depths (K,): bilinear in
    (x, y) between grid columns (clamped at the edges), linear in depth."""

    x: FloatArray
    y: FloatArray
    speeds: FloatArray

    def __init__(self, x: ArrayLike, y: ArrayLike, depths: ArrayLike, speeds: ArrayLike) -> None:
        xs = np.asarray(x, float).ravel().copy()
        ys = np.asarray(y, float).ravel().copy()
        d = np.asarray(depths, float).ravel().copy()
        c = np.asarray(speeds, float).copy()
        for name, a in (("x", xs), ("y", ys)):
            if a.size < 1 or np.any(np.diff(a) <= 0.0) or not np.all(np.isfinite(a)):
                raise ValueError(f"GriddedField: {name} must be finite and increase strictly")
        _check_depths("GriddedField", d)
        if c.shape != (xs.size, ys.size, d.size):
            raise ValueError(f"GriddedField: speeds must have shape {(xs.size, ys.size, d.size)}, got {c.shape}")
        _check_speeds("GriddedField", c)
        for a in (xs, ys, d, c):
            a.setflags(write=False)
        object.__setattr__(self, "x", xs)
        object.__setattr__(self, "y", ys)
        object.__setattr__(self, "depths", d)
        object.__setattr__(self, "speeds", c)

    @classmethod
    def from_ts(
        cls,
        x: ArrayLike,
        y: ArrayLike,
        depths: ArrayLike,
        temperature: ArrayLike,
        salinity: ArrayLike,
        latitude: float = 40.0,
        longitude: float = -70.0,
    ) -> GriddedField:
        """From in-situ temperature (deg C) and practical salinity (nx, ny, K) via TEOS-10."""
        from .ssp import teos10_speed

        d = np.asarray(depths, float)
        return cls(x, y, d, teos10_speed(d, temperature, salinity, latitude, longitude))

    @classmethod
    def from_netcdf(
        cls,
        path: str | Path,
        *,
        x: str = "x",
        y: str = "y",
        depth: str = "depth",
        speed: str | None = None,
        temperature: str = "temperature",
        salinity: str = "salinity",
        latitude: float | None = None,
        longitude: float | None = None,
    ) -> GriddedField:
        """Read a grid with xarray: ``speed`` (m/s) if named, else ``temperature`` and
        ``salinity`` through TEOS-10 at the file's ``latitude`` / ``longitude`` attributes (or
        the arguments). A section (no ``y`` dimension) becomes a grid one column wide."""
        from .gridio import open_dataset

        with open_dataset(path) as ds:

            def grid(name: str) -> FloatArray:
                v = ds[name]
                dims = [dn for dn in (x, y, depth) if dn in v.dims]
                a = np.asarray(v.transpose(*dims).values, float)
                return a if y in v.dims else a[:, None, :]

            xs = np.asarray(ds[x].values, float)
            ys = np.asarray(ds[y].values, float) if y in ds.coords or y in ds.variables else np.array([0.0])
            zs = np.asarray(ds[depth].values, float)
            if speed is not None:
                return cls(xs, ys, zs, grid(speed))
            lat = float(ds.attrs.get("latitude", 40.0) if latitude is None else latitude)
            lon = float(ds.attrs.get("longitude", -70.0) if longitude is None else longitude)
            return cls.from_ts(xs, ys, zs, grid(temperature), grid(salinity), lat, lon)

    def columns(self, x: FloatArray, y: FloatArray) -> FloatArray:
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))

        def weights(g: FloatArray, q: FloatArray) -> tuple[NDArray[np.intp], FloatArray]:
            if g.size == 1:
                return np.zeros(q.shape, np.intp), np.zeros(q.shape)
            i = np.clip(np.searchsorted(g, q, side="right") - 1, 0, g.size - 2)
            return i, np.clip((q - g[i]) / (g[i + 1] - g[i]), 0.0, 1.0)

        i, wx = weights(self.x, x)
        j, wy = weights(self.y, y)
        i1 = np.minimum(i + 1, self.x.size - 1)
        j1 = np.minimum(j + 1, self.y.size - 1)
        c = self.speeds
        wx, wy = wx[..., None], wy[..., None]
        return (c[i, j] * (1 - wx) + c[i1, j] * wx) * (1 - wy) + (c[i, j1] * (1 - wx) + c[i1, j1] * wx) * wy

    def speed(self, x: ArrayLike, y: ArrayLike, z: ArrayLike) -> FloatArray:
        x, y, z = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float), np.asarray(z, float))
        return _depth_interp(self.depths, self.columns(x, y), z)

    def section_ranges(self, x0, y0, ux, uy, length) -> FloatArray:
        return np.concatenate([line_crossings(self.x, x0, ux, length), line_crossings(self.y, y0, uy, length)], axis=1)

    @property
    def depth_only(self) -> bool:
        return bool(np.all(self.speeds == self.speeds[:1, :1]))
