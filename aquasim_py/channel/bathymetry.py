"""Sea-floor depth as a function of horizontal position, and the bottom's reflection loss.

A bathymetry answers ``depth(x, y)`` (m, positive down; vectorized) and, for the ray tracer,
``section_ranges(...)``: the horizontal distances along a straight line at which the tracer
samples its depth profile along that line, and ``slope_along(...)``: the floor's slope there.
Flat and planar bottoms are straight along every line, so they need no samples and no slopes
(the tracer's floor is then the polyline of the samples, exact). A curved floor (a seamount, a
ridge: sampled at a stated resolution; a grid: at the line's crossings of its grid lines) gives
its slope at each sample, and the tracer's floor is the smooth curve of circular arcs through the
samples with those slopes (:mod:`.rangedep`): a polyline of a curved floor would reflect a fan
of rays into beams with gaps between them at its vertices (and overlaps at concave ones), losing
and inventing eigenrays whatever the resolution.

The bottom type is a fluid half-space (sediment sound speed, density and attenuation), whose
plane-wave reflection coefficient is Rayleigh's (e.g. Jensen, Kuperman, Porter & Schmidt,
*Computational Ocean Acoustics*, 2nd ed. 2011, eq 1.52 with a complex sediment speed for the
attenuation, eq 1.46). Presets from the same book's Table 1.3 (speeds as ratios to 1500 m/s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "SEDIMENTS",
    "Bathymetry",
    "Flat",
    "FluidBottom",
    "GriddedBathymetry",
    "Plane",
    "Ridge",
    "Seamount",
    "line_crossings",
]

FloatArray = NDArray[np.float64]


def _positive(name: str, v: float) -> float:
    v = float(v)
    if not (math.isfinite(v) and v > 0.0):
        raise ValueError(f"{name} must be positive and finite, got {v!r}")
    return v


def line_crossings(grid: FloatArray, start: FloatArray, step: FloatArray, length: FloatArray) -> FloatArray:
    """Signed distances (n, len(grid)) along the lines ``start + r * step`` (one axis; ``step``
    the unit direction's component) at which the coordinate crosses each value of ``grid``,
    NaN where the line runs parallel to the axis (``length`` is unused: crossings anywhere on
    the line count)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        r = (grid[None, :] - start[:, None]) / step[:, None]
    return np.where(np.isfinite(r), r, np.nan)


def hermite_weights(axis: FloatArray, q: FloatArray) -> tuple[NDArray[np.int64], FloatArray, FloatArray]:
    """Node indices (n, 4) into the ghost-padded axis (:func:`ghost_padded`), the interpolation
    weights (n, 4) and their derivatives by q (n, 4) at the points q (clamped to the axis: beyond
    it the caller zeroes the slope along that axis): the cubic Hermite polynomial of each interval
    with the slopes at its nodes of the parabola through them and their neighbours (Catmull-Rom
    on a uniform axis; exact for quadratics on any). ``axis``: at least 2 increasing values."""
    q = np.clip(q, axis[0], axis[-1])
    ax = np.concatenate([[2 * axis[0] - axis[1]], axis, [2 * axis[-1] - axis[-2]]])
    i = np.clip(np.searchsorted(axis, q, side="right") - 1, 0, axis.size - 2) + 1  # padded
    hp, hc, hn = ax[i] - ax[i - 1], ax[i + 1] - ax[i], ax[i + 2] - ax[i + 1]
    u = (q - ax[i]) / hc
    u2, u3 = u * u, u * u * u
    # node slopes as weights of the four values: m_i = a . f[i-1 .. i+1], m_i+1 = b . f[i .. i+2]
    am1, ap1 = -hc / (hp * (hp + hc)), hp / (hc * (hp + hc))
    b0, b2 = -hn / (hc * (hc + hn)), hc / (hn * (hc + hn))
    h00, h10, h01, h11 = 2 * u3 - 3 * u2 + 1, u3 - 2 * u2 + u, -2 * u3 + 3 * u2, u3 - u2
    d00, d10, d01, d11 = 6 * u2 - 6 * u, 3 * u2 - 4 * u + 1, -6 * u2 + 6 * u, 3 * u2 - 2 * u

    def combine(c00, c10, c01, c11, scale):
        return (
            np.stack(
                [
                    c10 * hc * am1,
                    c00 - c10 * hc * (am1 + ap1) + c11 * hc * b0,
                    c01 + c10 * hc * ap1 - c11 * hc * (b0 + b2),
                    c11 * hc * b2,
                ],
                axis=-1,
            )
            * scale[:, None]
        )

    w = combine(h00, h10, h01, h11, np.ones_like(hc))
    dw = combine(d00, d10, d01, d11, 1.0 / hc)
    return (i - 1)[:, None] + np.arange(4)[None, :], w, dw


def ghost_padded(values: FloatArray) -> FloatArray:
    """Grid values (m, n) with one ghost node beyond each edge, continuing the edge's slope."""
    d = values
    d = np.concatenate([2 * d[:1] - d[1:2], d, 2 * d[-1:] - d[-2:-1]], axis=0)
    return np.concatenate([2 * d[:, :1] - d[:, 1:2], d, 2 * d[:, -1:] - d[:, -2:-1]], axis=1)


def bicubic(
    axis0: FloatArray, axis1: FloatArray, padded: FloatArray, q0: ArrayLike, q1: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(value, d value / d q0, d value / d q1) at (q0, q1), broadcast: the tensor product of
    :func:`hermite_weights` on the grid ``axis0`` x ``axis1`` (``padded``: its values through
    :func:`ghost_padded`), the edge values beyond the grid with no slope across its edge."""
    aa, bb = np.broadcast_arrays(np.asarray(q0, float), np.asarray(q1, float))
    shape = aa.shape
    af, bf = aa.ravel(), bb.ravel()
    i0, w0, dw0 = hermite_weights(axis0, af)
    i1, w1, dw1 = hermite_weights(axis1, bf)
    patch = padded[i0[:, :, None], i1[:, None, :]]  # (n, 4, 4)
    v = np.einsum("ni,nik,nk->n", w0, patch, w1)
    g0 = np.einsum("ni,nik,nk->n", dw0, patch, w1)
    g1 = np.einsum("ni,nik,nk->n", w0, patch, dw1)
    g0 = np.where((af < axis0[0]) | (af > axis0[-1]), 0.0, g0)
    g1 = np.where((bf < axis1[0]) | (bf > axis1[-1]), 0.0, g1)
    return v.reshape(shape), g0.reshape(shape), g1.reshape(shape)


class Bathymetry:
    """Base class: sea-floor depth (m, positive down) over the horizontal plane."""

    def depth(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        raise NotImplementedError

    def max_depth(self) -> float:
        """An upper bound of the depth anywhere (m): the ray tracer's depth grid reaches it."""
        raise NotImplementedError

    def section_ranges(
        self, x0: FloatArray, y0: FloatArray, ux: FloatArray, uy: FloatArray, length: FloatArray
    ) -> FloatArray:
        """Kinks (n, m) of the depth along the lines (x0, y0) + r (ux, uy), at signed distances
        r anywhere on the line (at least those near [0, length]), NaN-padded; an empty second
        axis when the depth is linear along every line. They are geographic points: moving an
        end along its line does not move them (the traced section then changes smoothly)."""
        return np.empty((np.size(x0), 0))

    def slope_along(self, x: FloatArray, y: FloatArray, ux: FloatArray, uy: FloatArray) -> FloatArray | None:
        """d depth / d r (m/m, positive deepening) at the points (x, y) along the horizontal unit
        directions (ux, uy), for the tracer's smooth floor between the samples of
        :meth:`section_ranges`; None: the depth is linear between those samples along every line
        (the tracer's floor is their polyline)."""
        return None

    @property
    def is_flat(self) -> bool:
        return False


@dataclass(frozen=True)
class Flat(Bathymetry):
    """A flat sea floor at ``depth_m``."""

    depth_m: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "depth_m", _positive("Flat: depth_m", self.depth_m))

    def depth(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        return np.full(np.broadcast(np.asarray(x), np.asarray(y)).shape, self.depth_m)

    def max_depth(self) -> float:
        return self.depth_m

    @property
    def is_flat(self) -> bool:
        return True


@dataclass(frozen=True)
class Plane(Bathymetry):
    """A planar sloping floor: depth = depth_m + slope_x (x - x0) + slope_y (y - y0), clipped at
    0 (land, where the plane would rise above the surface) and at ``max_depth_m``.

    The ASA wedge benchmark is ``Plane(200, slope_x=-0.05)`` (200 m at x = 0, the apex at 4 km).
    """

    depth_m: float
    slope_x: float = 0.0
    slope_y: float = 0.0
    x0: float = 0.0
    y0: float = 0.0
    max_depth_m: float = 11000.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "depth_m", _positive("Plane: depth_m", self.depth_m))
        for name in ("slope_x", "slope_y", "x0", "y0"):
            v = float(getattr(self, name))
            if not math.isfinite(v):
                raise ValueError(f"Plane: {name} must be finite, got {v!r}")
            object.__setattr__(self, name, v)
        object.__setattr__(self, "max_depth_m", _positive("Plane: max_depth_m", self.max_depth_m))

    def depth(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        d = (
            self.depth_m
            + self.slope_x * (np.asarray(x, float) - self.x0)
            + self.slope_y * (np.asarray(y, float) - self.y0)
        )
        return np.clip(d, 0.0, self.max_depth_m)

    def max_depth(self) -> float:
        return self.max_depth_m if (self.slope_x or self.slope_y) else self.depth_m

    def section_ranges(self, x0, y0, ux, uy, length) -> FloatArray:
        # the clips at 0 and max_depth_m are kinks
        g = self.slope_x * ux + self.slope_y * uy
        d0 = self.depth_m + self.slope_x * (x0 - self.x0) + self.slope_y * (y0 - self.y0)
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.stack([-d0 / g, (self.max_depth_m - d0) / g], axis=1)
        return np.where(np.isfinite(r), r, np.nan)


@dataclass(frozen=True)
class Seamount(Bathymetry):
    """A Gaussian seamount on a flat floor: depth = base_m - height_m exp(-rho^2 / (2 width_m^2)),
    rho the horizontal distance from (x0, y0). Along a line the depth and its slope are sampled
    every ``resolution_m``; the ray tracer's floor is the smooth curve of circular arcs through
    those samples with those slopes (:mod:`.rangedep`; its departure from the Gaussian is at most
    resolution_m^2 / 8 times the largest difference of the two curves' second derivatives, in
    practice of order resolution_m^3 height_m / width_m^3: 4e-4 m for a 400 m high, 1 km wide
    mount sampled every 50 m, against 0.1 m for the polyline of the same samples)."""

    base_m: float
    height_m: float
    width_m: float
    x0: float = 0.0
    y0: float = 0.0
    resolution_m: float = 50.0

    def __post_init__(self) -> None:
        for name in ("base_m", "width_m", "resolution_m"):
            object.__setattr__(self, name, _positive(f"Seamount: {name}", getattr(self, name)))
        h = float(self.height_m)
        if not (math.isfinite(h) and 0.0 <= h < self.base_m):
            raise ValueError(f"Seamount: height_m must be in [0, base_m), got {h!r}")
        object.__setattr__(self, "height_m", h)

    def depth(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        rho2 = (np.asarray(x, float) - self.x0) ** 2 + (np.asarray(y, float) - self.y0) ** 2
        return self.base_m - self.height_m * np.exp(-0.5 * rho2 / self.width_m**2)

    def max_depth(self) -> float:
        return self.base_m

    def section_ranges(self, x0, y0, ux, uy, length) -> FloatArray:
        # samples at fixed points of the line (multiples of the resolution from the foot of the
        # mount's centre on it), near [0, length] and where the mount is felt (5 widths)
        res = self.resolution_m
        foot = (self.x0 - x0) * ux + (self.y0 - y0) * uy  # signed distance of the centre's foot
        kmin = np.floor((-res - foot) / res)
        m = int(np.ceil(np.max(length, initial=0.0) / res)) + 3
        r = foot[:, None] + (kmin[:, None] + np.arange(m)[None, :]) * res
        px = x0[:, None] + r * ux[:, None] - self.x0
        py = y0[:, None] + r * uy[:, None] - self.y0
        near = px**2 + py**2 < (5.0 * self.width_m) ** 2
        return np.where((r <= length[:, None] + res) & near, r, np.nan)

    def slope_along(self, x, y, ux, uy) -> FloatArray:
        dx, dy = np.asarray(x, float) - self.x0, np.asarray(y, float) - self.y0
        g = self.height_m / self.width_m**2 * np.exp(-0.5 * (dx * dx + dy * dy) / self.width_m**2)
        return g * (dx * ux + dy * uy)


@dataclass(frozen=True)
class Ridge(Bathymetry):
    """A Gaussian ridge on a flat floor: depth = base_m - height_m exp(-d^2 / (2 width_m^2)), d
    the horizontal distance from its crest line through (x0, y0) at ``azimuth_deg`` (from the x
    axis towards y). A negative ``height_m`` makes a trough (a canyon of that depth). Along a line
    crossing it the depth and slope are sampled every ``resolution_m`` (as :class:`Seamount`)."""

    base_m: float
    height_m: float
    width_m: float
    x0: float = 0.0
    y0: float = 0.0
    azimuth_deg: float = 90.0
    resolution_m: float = 50.0

    def __post_init__(self) -> None:
        for name in ("base_m", "width_m", "resolution_m"):
            object.__setattr__(self, name, _positive(f"Ridge: {name}", getattr(self, name)))
        h = float(self.height_m)
        if not (math.isfinite(h) and h < self.base_m):
            raise ValueError(f"Ridge: height_m must be finite and below base_m, got {h!r}")
        az = float(self.azimuth_deg)
        if not math.isfinite(az):
            raise ValueError(f"Ridge: azimuth_deg must be finite, got {az!r}")
        object.__setattr__(self, "height_m", h)
        object.__setattr__(self, "azimuth_deg", az)

    def _across(self) -> tuple[float, float]:
        """The unit vector across the crest line."""
        a = math.radians(self.azimuth_deg)
        return -math.sin(a), math.cos(a)

    def depth(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        nx, ny = self._across()
        d = (np.asarray(x, float) - self.x0) * nx + (np.asarray(y, float) - self.y0) * ny
        return self.base_m - self.height_m * np.exp(-0.5 * d * d / self.width_m**2)

    def max_depth(self) -> float:
        return self.base_m - min(self.height_m, 0.0)

    def section_ranges(self, x0, y0, ux, uy, length) -> FloatArray:
        # samples at fixed points of the line: multiples of the resolution from its crossing with
        # the crest line (none where it runs along the crest: the depth is then constant on it)
        nx, ny = self._across()
        rate = ux * nx + uy * ny  # d distance / d r
        d0 = (x0 - self.x0) * nx + (y0 - self.y0) * ny
        with np.errstate(divide="ignore", invalid="ignore"):
            foot = np.where(np.abs(rate) > 1e-12, -d0 / rate, np.nan)
        res = self.resolution_m
        kmin = np.floor((-res - foot) / res)
        m = int(np.ceil(np.max(length, initial=0.0) / res)) + 3
        r = foot[:, None] + (np.nan_to_num(kmin)[:, None] + np.arange(m)[None, :]) * res
        d = d0[:, None] + r * rate[:, None]
        near = np.abs(d) < 5.0 * self.width_m
        return np.where((r <= length[:, None] + res) & near & np.isfinite(foot)[:, None], r, np.nan)

    def slope_along(self, x, y, ux, uy) -> FloatArray:
        nx, ny = self._across()
        d = (np.asarray(x, float) - self.x0) * nx + (np.asarray(y, float) - self.y0) * ny
        g = self.height_m / self.width_m**2 * np.exp(-0.5 * d * d / self.width_m**2) * d
        return g * (ux * nx + uy * ny)


@dataclass(frozen=True, eq=False)
class GriddedBathymetry(Bathymetry):
    """Depth on a rectilinear (x, y) grid, the edge values beyond it. Between the nodes it is
    bicubic: along each axis the cubic Hermite polynomial of each interval with the slopes at
    its nodes of the parabola through them and their neighbours (Catmull-Rom, Keys 1981, on a
    uniform grid; a ghost node beyond each edge continues its last slope). It passes through
    every node, reproduces planes (and quadratics), its error is third order in the spacing, and
    its slope is continuous, so a reflected fan of rays turns smoothly over it (bilinear
    interpolation has kinks along every grid line, which scatter a reflected fan into beams with
    gaps and overlaps, as the facets of a polyline do).
    The ray tracer samples it where a line crosses the grid lines, with its depth and slope
    there (:meth:`slope_along`)."""

    x: FloatArray
    y: FloatArray
    depths: FloatArray  #: (len(x), len(y)), m

    def __post_init__(self) -> None:
        x = np.asarray(self.x, float).ravel()
        y = np.asarray(self.y, float).ravel()
        d = np.asarray(self.depths, float)
        if d.shape != (x.size, y.size):
            raise ValueError(
                f"GriddedBathymetry: depths must have shape (len(x), len(y)) = {(x.size, y.size)}, got {d.shape}"
            )
        for name, a in (("x", x), ("y", y)):
            if a.size < 2 or np.any(np.diff(a) <= 0.0) or not np.all(np.isfinite(a)):
                raise ValueError(f"GriddedBathymetry: {name} must hold at least 2 finite, strictly increasing values")
        if not np.all(np.isfinite(d)):
            raise ValueError("GriddedBathymetry: depths must be finite (mask land with a depth of 0)")
        if np.any(d < 0.0):
            raise ValueError("GriddedBathymetry: depths must be >= 0 (positive down)")
        for name, a in (("x", x), ("y", y), ("depths", d)):
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    @classmethod
    def from_netcdf(cls, path: str | Path, variable: str = "depth", x: str = "x", y: str = "y") -> GriddedBathymetry:
        """Read a grid with xarray (netCDF3 through scipy; netCDF4 needs the netCDF4 package).
        A variable named ``elevation`` (GEBCO style, negative below sea level) is negated."""
        from .gridio import open_dataset

        with open_dataset(path) as ds:
            var = ds[variable].transpose(x, y)
            d = np.asarray(var.values, float)
            if variable == "elevation":
                d = np.maximum(-d, 0.0)
            return cls(np.asarray(ds[x].values, float), np.asarray(ds[y].values, float), d)

    def _eval(self, x: ArrayLike, y: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(depth, d depth / dx, d depth / dy) at (x, y), broadcast."""
        return bicubic(self.x, self.y, ghost_padded(self.depths), x, y)

    def depth(self, x: ArrayLike, y: ArrayLike) -> FloatArray:
        return self._eval(x, y)[0]

    def max_depth(self) -> float:
        return float(self.depths.max())

    def section_ranges(self, x0, y0, ux, uy, length) -> FloatArray:
        return np.concatenate([line_crossings(self.x, x0, ux, length), line_crossings(self.y, y0, uy, length)], axis=1)

    def slope_along(self, x, y, ux, uy) -> FloatArray:
        _d, gx, gy = self._eval(x, y)
        return gx * ux + gy * uy


# --------------------------------------------------------------------------- bottom type


@dataclass(frozen=True)
class FluidBottom:
    """A fluid sediment half-space: sound speed (m/s), density (ratio to water, i.e. g/cm^3)
    and compressional attenuation (dB per wavelength). ``reflection_loss_db`` is Rayleigh's."""

    sound_speed_mps: float = 1650.0
    density: float = 1.9
    attenuation_db_per_wavelength: float = 0.8
    name: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        _positive("FluidBottom: sound_speed_mps", self.sound_speed_mps)
        _positive("FluidBottom: density", self.density)
        a = float(self.attenuation_db_per_wavelength)
        if not (math.isfinite(a) and a >= 0.0):
            raise ValueError(f"FluidBottom: attenuation_db_per_wavelength must be >= 0, got {a!r}")

    @property
    def params(self) -> tuple[float, float, float]:
        """(sound speed m/s, density ratio, loss tangent delta): the sediment wavenumber is
        (omega / c_b)(1 + i delta), delta = attenuation / (40 pi log10 e) (Jensen et al. eq 1.46)."""
        delta = self.attenuation_db_per_wavelength / (40.0 * math.pi * math.log10(math.e))
        return float(self.sound_speed_mps), float(self.density), delta

    def reflection_coefficient(self, grazing_rad: ArrayLike, water_speed_mps: ArrayLike) -> NDArray[np.complex128]:
        """Complex plane-wave reflection coefficient R = (rho k_zw - k_zb) / (rho k_zw + k_zb)
        (eq 1.52, water of unit density) at grazing angle(s) (rad) in water of the given speed."""
        from ._rangedep_jit import rayleigh_array

        th, cw = np.broadcast_arrays(np.abs(np.asarray(grazing_rad, float)), np.asarray(water_speed_mps, float))
        cb, rho, delta = self.params
        out = rayleigh_array(np.ascontiguousarray(th).ravel(), np.ascontiguousarray(cw).ravel(), cb, rho, delta)
        return out.reshape(th.shape)

    def reflection_loss_db(self, grazing_rad: ArrayLike, water_speed_mps: ArrayLike) -> FloatArray:
        """-20 log10 |R| (dB, >= 0)."""
        r = np.abs(self.reflection_coefficient(grazing_rad, water_speed_mps))
        with np.errstate(divide="ignore"):
            return -20.0 * np.log10(r)


#: Jensen et al. (2011) Table 1.3, compressional speeds as ratio x 1500 m/s
SEDIMENTS: dict[str, FluidBottom] = {
    "clay": FluidBottom(1500.0, 1.5, 0.2, name="clay"),
    "silt": FluidBottom(1575.0, 1.7, 1.0, name="silt"),
    "sand": FluidBottom(1650.0, 1.9, 0.8, name="sand"),
    "gravel": FluidBottom(1800.0, 2.0, 0.6, name="gravel"),
}
