"""Sound-speed profiles c(z): depth z in metres (positive down), speed in m/s.

Every profile answers ``speed(z)`` (vectorized) and knows the water column it lives in:
the surface is z = 0 and ``bottom`` is the sea-floor depth in metres (``None`` = no bottom
modelled). Profiles other than :class:`Constant` and :class:`Isogradient` are ray traced as a
stack of isogradient layers, so each one can give that stack with :meth:`to_layered`.

A profile can also come from temperature / salinity through TEOS-10 (:func:`from_ts`, the
``gsw`` package of the ``ocean`` extra, imported only then).

The CTD profile uses Mackenzie's nine-term equation (J. Acoust. Soc. Am. 70(3), 807-812,
1981) rather than TEOS-10: it is the standard equation of underwater acoustics, needs only
depth, in-situ temperature and practical salinity (what a CTD cast reports), adds no
dependency, and its standard error (0.07 m/s) is far below what a ray-traced delay can
resolve at network ranges.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "Constant",
    "Isogradient",
    "Layered",
    "Munk",
    "SoundSpeedProfile",
    "from_ctd",
    "from_ts",
    "mackenzie",
    "teos10_speed",
]


def _check_bottom(bottom: float | None) -> float | None:
    if bottom is None:
        return None
    b = float(bottom)
    if not math.isfinite(b) or b <= 0.0:
        raise ValueError(f"bottom must be a positive finite depth in metres, got {bottom!r}")
    return b


class SoundSpeedProfile:
    """Base class: a depth-dependent sound speed in a water column [0, bottom]."""

    bottom: float | None

    def speed(self, z: ArrayLike) -> NDArray[np.float64]:
        """Sound speed (m/s) at depth ``z`` (m, positive down)."""
        raise NotImplementedError

    def to_layered(self) -> Layered:
        """The profile as a stack of isogradient layers (exact for piecewise-linear ones)."""
        raise NotImplementedError

    def speed_bounds(self, z_max: float | None = None) -> tuple[float, float]:
        """(min, max) sound speed over [0, z_max] (default: the water column / profile extent)."""
        lay = self.to_layered()
        zs = lay.depths
        top = z_max if z_max is not None else (self.bottom if self.bottom is not None else zs[-1])
        pts = np.concatenate([zs[zs <= top], [top]])
        cs = self.speed(pts)
        return float(cs.min()), float(cs.max())


@dataclass(frozen=True)
class Constant(SoundSpeedProfile):
    """c(z) = speed (m/s): the homogeneous medium; rays are straight lines."""

    speed_mps: float = 1500.0
    bottom: float | None = None

    def __post_init__(self) -> None:
        s = float(self.speed_mps)
        if not math.isfinite(s) or s <= 0.0:
            raise ValueError(f"Constant: speed must be positive and finite, got {self.speed_mps!r}")
        object.__setattr__(self, "speed_mps", s)
        object.__setattr__(self, "bottom", _check_bottom(self.bottom))

    def speed(self, z: ArrayLike) -> NDArray[np.float64]:
        return np.full(np.shape(z), self.speed_mps, dtype=float)

    def to_layered(self) -> Layered:
        zmax = self.bottom if self.bottom is not None else 1.0
        return Layered([0.0, zmax], [self.speed_mps, self.speed_mps], bottom=self.bottom)


@dataclass(frozen=True)
class Isogradient(SoundSpeedProfile):
    """c(z) = b + a z (Ramezani et al., eq 1): surface speed b (m/s), gradient a (1/s), any sign.

    With a > 0 rays are arcs of circles centred at the depth -b/a where c would vanish, and they
    bend upwards. The profile must stay positive over the water column: with a < 0 a bottom is
    required (or b + a z > 0 is checked only down to it).
    """

    surface_speed: float = 1480.0
    gradient: float = 0.0
    bottom: float | None = None

    def __post_init__(self) -> None:
        b, a = float(self.surface_speed), float(self.gradient)
        if not (math.isfinite(b) and math.isfinite(a)):
            raise ValueError(f"Isogradient: surface_speed and gradient must be finite, got {b!r}, {a!r}")
        if b <= 0.0:
            raise ValueError(f"Isogradient: surface_speed must be positive, got {b!r}")
        bottom = _check_bottom(self.bottom)
        if a < 0.0 and bottom is not None and b + a * bottom <= 0.0:
            raise ValueError(f"Isogradient: speed b + a*z becomes non-positive above the bottom ({bottom} m)")
        object.__setattr__(self, "surface_speed", b)
        object.__setattr__(self, "gradient", a)
        object.__setattr__(self, "bottom", bottom)

    def speed(self, z: ArrayLike) -> NDArray[np.float64]:
        return self.surface_speed + self.gradient * np.asarray(z, dtype=float)

    def to_layered(self) -> Layered:
        if self.bottom is not None:
            zmax = self.bottom
        elif self.gradient < 0.0:
            # deepest depth where the speed is still 1 % of the surface value
            zmax = 0.99 * self.surface_speed / -self.gradient
        else:
            zmax = 1.0e4
        return Layered([0.0, zmax], [self.surface_speed, self.surface_speed + self.gradient * zmax], bottom=self.bottom)


@dataclass(frozen=True, eq=False, init=False)
class Layered(SoundSpeedProfile):
    """Piecewise-linear c(z) through (depths[i], speeds[i]): a stack of isogradient layers.

    ``depths`` must start at 0 (the surface) and increase strictly. Below the last depth the
    last layer's gradient continues (a deep isogradient tail), so the profile is defined for
    every z >= 0; set ``bottom`` to close the water column.
    """

    depths: NDArray[np.float64]
    speeds: NDArray[np.float64]
    bottom: float | None = None

    # Written out rather than generated: the arguments are any array-likes (lists, tuples,
    # arrays), the fields the validated read-only float64 copies.
    def __init__(
        self,
        depths: ArrayLike = (0.0, 1.0),
        speeds: ArrayLike = (1500.0, 1500.0),
        bottom: float | None = None,
    ) -> None:
        d = np.asarray(depths, dtype=float).ravel().copy()
        c = np.asarray(speeds, dtype=float).ravel().copy()
        if d.size != c.size:
            raise ValueError(f"Layered: {d.size} depths but {c.size} speeds")
        if d.size < 2:
            raise ValueError("Layered: need at least two (depth, speed) points")
        if not (np.all(np.isfinite(d)) and np.all(np.isfinite(c))):
            raise ValueError("Layered: depths and speeds must be finite (no NaN or inf)")
        if d[0] != 0.0:
            raise ValueError(f"Layered: depths must start at 0 (the surface), got {d[0]!r}")
        if np.any(np.diff(d) <= 0.0):
            raise ValueError("Layered: depths must increase strictly")
        if np.any(c <= 0.0):
            raise ValueError("Layered: speeds must be positive")
        bottom = _check_bottom(bottom)
        if bottom is not None and d[-1] < bottom:
            g = (c[-1] - c[-2]) / (d[-1] - d[-2])
            if c[-1] + g * (bottom - d[-1]) <= 0.0:
                raise ValueError("Layered: extrapolated speed becomes non-positive above the bottom")
        d.setflags(write=False)
        c.setflags(write=False)
        object.__setattr__(self, "depths", d)
        object.__setattr__(self, "speeds", c)
        object.__setattr__(self, "bottom", bottom)

    @property
    def gradients(self) -> NDArray[np.float64]:
        """Per-layer gradient dc/dz (1/s), one per interval between depths."""
        return np.diff(self.speeds) / np.diff(self.depths)

    def speed(self, z: ArrayLike) -> NDArray[np.float64]:
        z = np.asarray(z, dtype=float)
        d, c = self.depths, self.speeds
        i = np.clip(np.searchsorted(d, z, side="right") - 1, 0, d.size - 2)
        g = (c[i + 1] - c[i]) / (d[i + 1] - d[i])
        return c[i] + g * (z - d[i])

    def to_layered(self) -> Layered:
        return self

    def __repr__(self) -> str:
        return f"Layered(depths={self.depths.tolist()}, speeds={self.speeds.tolist()}, bottom={self.bottom})"


@dataclass(frozen=True)
class Munk(SoundSpeedProfile):
    """Canonical Munk profile (Munk 1974): c = c_axis [1 + eps (eta - 1 + e^-eta)],
    eta = 2 (z - z_axis) / scale.

    Defaults are the textbook deep-ocean values: axis at 1300 m, 1500 m/s on the axis,
    eps = 0.00737, scale depth 1300 m, bottom at 5000 m. Ray traced through ``n_layers``
    piecewise-linear layers (:meth:`to_layered`).
    """

    axis_depth: float = 1300.0
    axis_speed: float = 1500.0
    epsilon: float = 0.00737
    scale: float = 1300.0
    bottom: float | None = 5000.0
    n_layers: int = 200

    def __post_init__(self) -> None:
        for name in ("axis_depth", "axis_speed", "epsilon", "scale"):
            v = float(getattr(self, name))
            if not math.isfinite(v):
                raise ValueError(f"Munk: {name} must be finite, got {v!r}")
        if self.axis_speed <= 0.0 or self.scale <= 0.0 or self.epsilon < 0.0:
            raise ValueError("Munk: axis_speed and scale must be positive, epsilon non-negative")
        if int(self.n_layers) < 1:
            raise ValueError("Munk: n_layers must be >= 1")
        object.__setattr__(self, "bottom", _check_bottom(self.bottom))

    def speed(self, z: ArrayLike) -> NDArray[np.float64]:
        eta = 2.0 * (np.asarray(z, dtype=float) - self.axis_depth) / self.scale
        return self.axis_speed * (1.0 + self.epsilon * (eta - 1.0 + np.exp(-eta)))

    def to_layered(self) -> Layered:
        zmax = self.bottom if self.bottom is not None else 2.0 * self.axis_depth + 2.0 * self.scale
        z = np.linspace(0.0, zmax, int(self.n_layers) + 1)
        return Layered(z, self.speed(z), bottom=self.bottom)


def mackenzie(depth: ArrayLike, temperature: ArrayLike, salinity: ArrayLike) -> NDArray[np.float64]:
    """Mackenzie (1981) sound speed (m/s) from depth (m), temperature (deg C), salinity (PSU).

    Valid for 2-30 deg C, 25-40 PSU, 0-8000 m; standard error 0.07 m/s.
    """
    D = np.asarray(depth, dtype=float)
    T = np.asarray(temperature, dtype=float)
    S = np.asarray(salinity, dtype=float)
    return (
        1448.96
        + 4.591 * T
        - 5.304e-2 * T**2
        + 2.374e-4 * T**3
        + 1.340 * (S - 35.0)
        + 1.630e-2 * D
        + 1.675e-7 * D**2
        - 1.025e-2 * T * (S - 35.0)
        - 7.139e-13 * T * D**3
    )


def from_ctd(
    depth: ArrayLike,
    temperature: ArrayLike,
    salinity: ArrayLike,
    bottom: float | None = None,
) -> Layered:
    """A :class:`Layered` profile from a CTD cast (depth m, temperature deg C, salinity PSU).

    The cast's shallowest sample is extended to the surface with the same speed when it
    does not start at z = 0 (a cast usually starts a metre or two down).
    """
    d, T, S = _cast(depth, temperature, salinity)
    return _from_surface(d, mackenzie(d, T, S), bottom)


def _cast(depth: ArrayLike, temperature: ArrayLike, salinity: ArrayLike) -> tuple[NDArray[np.float64], ...]:
    """The checked columns of a cast (depth m, temperature deg C, salinity)."""
    d = np.asarray(depth, dtype=float).ravel()
    T = np.asarray(temperature, dtype=float).ravel()
    S = np.asarray(salinity, dtype=float).ravel()
    if not (d.size == T.size == S.size):
        raise ValueError(f"CTD cast: depth, temperature and salinity lengths differ ({d.size}, {T.size}, {S.size})")
    if d.size < 2:
        raise ValueError("CTD cast: need at least two samples")
    if not (np.all(np.isfinite(d)) and np.all(np.isfinite(T)) and np.all(np.isfinite(S))):
        raise ValueError("CTD cast: values must be finite (no NaN)")
    if d[0] < 0.0 or np.any(np.diff(d) <= 0.0):
        raise ValueError("CTD cast: depths must be non-negative and increase strictly")
    return d, T, S


def _from_surface(d: NDArray[np.float64], c: NDArray[np.float64], bottom: float | None) -> Layered:
    """The cast's speeds as a Layered profile, its shallowest sample extended to the surface."""
    if d[0] > 0.0:
        d = np.concatenate([[0.0], d])
        c = np.concatenate([[c[0]], c])
    return Layered(d, c, bottom=bottom)


def teos10_speed(
    depth: ArrayLike,
    temperature: ArrayLike,
    salinity: ArrayLike,
    latitude: ArrayLike = 40.0,
    longitude: ArrayLike = -70.0,
) -> NDArray[np.float64]:
    """TEOS-10 sound speed (m/s) from depth (m), in-situ temperature (deg C, ITS-90) and
    practical salinity (PSS-78), at a latitude / longitude (deg): pressure from depth
    (gsw.p_from_z), Absolute Salinity (gsw.SA_from_SP), Conservative Temperature
    (gsw.CT_from_t), then gsw.sound_speed (the 75-term Gibbs function expression)."""
    try:
        import gsw
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError("TEOS-10 sound speed needs the gsw package: pip install 'aquasim-py[ocean]'") from e
    z = np.asarray(depth, dtype=float)
    p = gsw.p_from_z(-z, latitude)
    sa = gsw.SA_from_SP(salinity, p, longitude, latitude)
    ct = gsw.CT_from_t(sa, temperature, p)
    return np.asarray(gsw.sound_speed(sa, ct, p), dtype=float)


def from_ts(
    depth: ArrayLike,
    temperature: ArrayLike,
    salinity: ArrayLike,
    latitude: float = 40.0,
    longitude: float = -70.0,
    bottom: float | None = None,
    equation: str = "teos10",
) -> Layered:
    """A :class:`Layered` profile from a T/S cast (depth m, in-situ temperature deg C,
    practical salinity) through TEOS-10 (``equation="teos10"``) or Mackenzie 1981
    (``"mackenzie"``, the same as :func:`from_ctd`)."""
    if equation == "mackenzie":
        return from_ctd(depth, temperature, salinity, bottom=bottom)
    if equation != "teos10":
        raise ValueError(f"equation must be 'teos10' or 'mackenzie', got {equation!r}")
    d, T, S = _cast(depth, temperature, salinity)
    c = teos10_speed(d, T, S, latitude, longitude)
    if not np.all(np.isfinite(c)):
        raise ValueError("T/S cast: TEOS-10 gives no sound speed for some samples (values out of range?)")
    return _from_surface(d, c, bottom)
