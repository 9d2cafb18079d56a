"""Node mobility: exact, deterministic trajectories inside the scenario volume.

Coordinates are metres, (x, y, z) with z = depth, positive down; times are seconds of true
simulation time. One :class:`Mobility` object drives a group of ``n`` nodes, vectorized over
them: ``position(t)`` and ``velocity(t)`` return ``(n, 3)`` arrays, exact at any ``t >= 0``
and independent of the order of queries (queries never advance hidden state; random legs and
integrated current tables are extended lazily, always in the same fixed blocks from ``t = 0``).

Walls, surface and bottom reflect like mirrors: each model computes its *unconstrained*
trajectory and :meth:`Box.fold` folds it into the box coordinate-wise (a triangle wave per
axis). Folding is an exact specular reflection for any path, and the velocity is the folded
derivative (each component's sign flips on every bounce).

Models: :class:`Static`, :class:`ConstantVelocity`, :class:`CoordinatedTurn` (circle arcs in
x-y), :class:`RandomWalk` (piecewise-constant random legs), :class:`Kinematic` (the
kinematic ocean-current model of SLMP used in STVF's Table 1; ``MeanderingCurrent`` is its
deprecated alias), :class:`MeanderingJet` (Bower's meandering jet, the meandering current
mobility model of Caruso et al. 2008) and :class:`Waypoints`.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import solve_ivp

__all__ = [
    "Box",
    "ConstantVelocity",
    "CoordinatedTurn",
    "Kinematic",
    "MeanderingCurrent",
    "MeanderingJet",
    "Mobility",
    "NoisyConstantVelocity",
    "RandomWalk",
    "Static",
    "Waypoints",
]

Array = NDArray[np.float64]


# ---------------------------------------------------------------------------------------------
# Scenario volume


class Box:
    """Axis-aligned scenario volume ``lo <= p <= hi`` (m); ``lo[2] >= 0`` is the surface side."""

    __slots__ = ("_cache", "_inv_period", "_period", "hi", "lo", "size")

    def __init__(self, lo: ArrayLike, hi: ArrayLike) -> None:
        lo_a = np.array(lo, dtype=float).reshape(-1)
        hi_a = np.array(hi, dtype=float).reshape(-1)
        if lo_a.shape != (3,) or hi_a.shape != (3,):
            raise ValueError(f"Box corners must be 3-vectors (x, y, z), got {lo!r} and {hi!r}")
        if not (np.all(np.isfinite(lo_a)) and np.all(np.isfinite(hi_a))):
            raise ValueError("Box corners must be finite")
        if np.any(hi_a <= lo_a):
            raise ValueError(f"Box needs hi > lo on every axis, got lo={lo_a}, hi={hi_a}")
        if lo_a[2] < 0.0:
            raise ValueError(f"Box lo[2] is a depth and must be >= 0 (surface at z = 0), got {lo_a[2]}")
        lo_a.flags.writeable = False
        hi_a.flags.writeable = False
        self.lo = lo_a
        self.hi = hi_a
        self.size = hi_a - lo_a
        self._period = 2.0 * self.size
        self._inv_period = 1.0 / self._period
        self._cache: dict[tuple[int, ...], tuple[Array, ...]] = {}

    def __repr__(self) -> str:
        return f"Box(lo={self.lo.tolist()}, hi={self.hi.tolist()})"

    def contains(self, p: ArrayLike) -> NDArray[np.bool_]:
        """Whether each point of ``p`` (..., 3) lies in the closed box."""
        pa = np.asarray(p, dtype=float)
        return np.all((pa >= self.lo) & (pa <= self.hi), axis=-1)

    def fold(self, p: ArrayLike) -> tuple[Array, Array]:
        """Mirror-fold points (..., 3) into the box: (folded points, d folded / d p per axis).

        Triangle wave of period 2 * size per axis, exact for any overshoot (multiple bounces).
        The sign is -1 where the point sits in a mirrored copy of the box.
        """
        d, lo, hi = self._centred(p)
        sign = np.copysign(1.0, d)
        np.negative(sign, out=sign)
        return self._finish(d, lo, hi), sign

    def reflect(self, p: ArrayLike) -> Array:
        """Points (..., 3) folded back into the box like a mirror (see :meth:`fold`)."""
        return self._finish(*self._centred(p))

    def _consts(self, shape: tuple[int, ...]) -> tuple[Array, ...]:
        # Broadcasting against a length-3 last axis runs numpy's inner loop 3 elements at a
        # time (several times slower); materialize the constants at the query's shape once.
        c = self._cache.get(shape)
        if c is None:
            c = tuple(
                np.ascontiguousarray(np.broadcast_to(a, shape))
                for a in (self.lo, self.hi, self.size, self._period, self._inv_period)
            )
            if len(self._cache) < 64:
                self._cache[shape] = c
        return c

    def _centred(self, p: ArrayLike) -> tuple[Array, Array, Array]:
        # Phase within one period minus size: in [-size, size), > 0 in the mirrored copy.
        # floor-based remainder: np.mod costs several times more on the per-reception hot path.
        pa = np.asarray(p, dtype=float)
        lo, hi, size, period, inv_period = self._consts(pa.shape)
        d = pa - lo
        q = d * inv_period
        np.floor(q, out=q)
        q *= period
        d -= q
        d -= size
        return d, lo, hi

    @staticmethod
    def _finish(d: Array, lo: Array, hi: Array) -> Array:
        np.abs(d, out=d)
        out = np.subtract(hi, d, out=d)
        # Rounding of the remainder can land one ulp below lo.
        np.maximum(out, lo, out=out)
        return out


# ---------------------------------------------------------------------------------------------
# Helpers


def _time(t: float) -> float:
    tf = float(t)
    if not (0.0 <= tf < math.inf):
        raise ValueError(f"time must be finite and >= 0 s, got {t!r}")
    return tf


def _per_node(name: str, value: ArrayLike, n: int, *, minimum: float | None = None) -> Array:
    """A scalar or (n,) parameter as a finite (n,) array."""
    a = np.asarray(value, dtype=float)
    if a.ndim == 0:
        a = np.full(n, float(a))
    if a.shape != (n,):
        raise ValueError(f"{name} must be a scalar or have shape ({n},), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite")
    if minimum is not None and np.any(a < minimum):
        raise ValueError(f"{name} must be >= {minimum}, got min {a.min()}")
    return a.copy()


def _positive(name: str, value: float) -> float:
    v = float(value)
    if not (0.0 < v < math.inf):
        raise ValueError(f"{name} must be positive and finite, got {value!r}")
    return v


def _need_rng(rng: np.random.Generator | None, who: str) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"{who} needs rng, a numpy.random.Generator (got {type(rng).__name__})")
    return rng


def _readonly(a: Array) -> Array:
    a.flags.writeable = False
    return a


class _Table:
    """Growable array of per-knot states (K, n, ...) with capacity doubling."""

    __slots__ = ("count", "data")

    def __init__(self, first: Array) -> None:
        self.data = np.empty((16,) + first.shape)
        self.data[0] = first
        self.count = 1

    def append(self, rows: Array) -> None:
        need = self.count + len(rows)
        if need > len(self.data):
            cap = max(need, 2 * len(self.data))
            grown = np.empty((cap,) + self.data.shape[1:])
            grown[: self.count] = self.data[: self.count]
            self.data = grown
        self.data[self.count : need] = rows
        self.count = need

    @property
    def last(self) -> Array:
        return self.data[self.count - 1]


# ---------------------------------------------------------------------------------------------
# Base class


class Mobility:
    """Trajectories of a group of ``n`` nodes, built as ``Cls(initial_positions, box, rng, **params)``.

    Subclasses implement the unconstrained motion in ``_raw_position(t)`` and
    ``_raw_velocity(t)`` (each (n, 3)); the base class folds it into the box. Returned arrays
    may be read-only views of internal state (e.g. ``Static``): copy before modifying.
    """

    #: False for models whose unconstrained path provably stays in the (convex) box.
    _folds: bool = True

    def __init__(
        self,
        initial_positions: ArrayLike,
        box: Box,
        rng: np.random.Generator | None = None,
    ) -> None:
        if not isinstance(box, Box):
            raise ValueError(f"box must be a mobility.Box, got {type(box).__name__}")
        p0 = np.array(initial_positions, dtype=float)
        if p0.ndim != 2 or p0.shape[1] != 3 or p0.shape[0] < 1:
            raise ValueError(f"initial_positions must have shape (n, 3) with n >= 1, got {p0.shape}")
        if not np.all(np.isfinite(p0)):
            raise ValueError("initial_positions must be finite")
        outside = np.flatnonzero(~box.contains(p0))
        if outside.size:
            i = int(outside[0])
            raise ValueError(f"initial position of node {i} {p0[i].tolist()} is outside {box!r}")
        self.box = box
        self._p0 = _readonly(p0)
        self._rng = rng

    @property
    def n(self) -> int:
        """Number of nodes in the group."""
        return self._p0.shape[0]

    @property
    def initial_positions(self) -> Array:
        return self._p0

    def position(self, t: float) -> Array:
        """Positions (n, 3) in m at true time ``t`` (s)."""
        raw = self._raw_position(_time(t))
        return self.box.reflect(raw) if self._folds else raw

    def velocity(self, t: float) -> Array:
        """Velocities (n, 3) in m/s at true time ``t`` (s) (right derivative at bounces)."""
        return self.state(t)[1]

    def state(self, t: float) -> tuple[Array, Array]:
        """``(position(t), velocity(t))`` from one evaluation of the trajectory."""
        tf = _time(t)
        raw_p = self._raw_position(tf)
        raw_v = self._raw_velocity(tf)
        if not self._folds:
            return raw_p, raw_v
        pos, sign = self.box.fold(raw_p)
        return pos, raw_v * sign

    def position_at(self, idx: ArrayLike, t: ArrayLike) -> Array:
        """Positions (m, 3) of nodes ``idx`` (m,) at their own times ``t`` (s, (m,) or scalar).

        One call for a batch of (receiver, arrival time) pairs, e.g. a broadcast's receivers.
        """
        i, ts = self._pairs(idx, t)
        raw = self._raw_position_at(i, ts)
        return self.box.reflect(raw) if self._folds else raw

    def velocity_at(self, idx: ArrayLike, t: ArrayLike) -> Array:
        """Velocities (m, 3) in m/s of nodes ``idx`` at times ``t`` (see :meth:`position_at`)."""
        i, ts = self._pairs(idx, t)
        raw_v = self._raw_velocity_at(i, ts)
        if not self._folds:
            return raw_v
        return raw_v * self.box.fold(self._raw_position_at(i, ts))[1]

    def state_at(self, idx: ArrayLike, t: ArrayLike) -> tuple[Array, Array]:
        """``(position_at(idx, t), velocity_at(idx, t))`` from one evaluation of the trajectories."""
        return self._state_at(*self._pairs(idx, t))

    def _state_at(self, idx: NDArray[np.intp], t: Array) -> tuple[Array, Array]:
        # No argument checks (the kernel's hot path passes valid ids and times, (m,) each); the
        # same operations as position_at / velocity_at, so the same bits.
        raw_p, raw_v = self._raw_state_at(idx, t)
        if not self._folds:
            return raw_p, raw_v
        pos, sign = self.box.fold(raw_p)
        return pos, raw_v * sign

    def _raw_state_at(self, idx: NDArray[np.intp], t: Array) -> tuple[Array, Array]:
        # (_raw_position_at, _raw_velocity_at); a model may share work between the two
        return self._raw_position_at(idx, t), self._raw_velocity_at(idx, t)

    def _position_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        # position_at without argument checks (see _state_at)
        raw = self._raw_position_at(idx, t)
        return self.box.reflect(raw) if self._folds else raw

    def _pairs(self, idx: ArrayLike, t: ArrayLike) -> tuple[NDArray[np.intp], Array]:
        i = np.asarray(idx)
        if i.ndim != 1 or (i.size and i.dtype.kind not in "iu"):
            raise ValueError("idx must be a 1-D array of node indices")
        i = i.astype(np.intp, copy=False)
        ts = np.asarray(t, dtype=float)
        if ts.shape != i.shape:
            ts = np.broadcast_to(ts, i.shape)
        if i.size:
            lo, hi = i.min(), i.max()
            if lo < 0 or hi >= self.n:
                raise ValueError(f"node indices must be in [0, {self.n}), got {lo}..{hi}")
            # NaN fails both comparisons.
            if not (ts.min() >= 0.0 and ts.max() < math.inf):
                raise ValueError("times must be finite and >= 0 s")
        return i, ts

    def max_speed(self) -> float:
        """An upper bound (m/s) on every node's speed at all times (``inf`` if the model has
        none); folding into the box keeps speeds. Used by the channel's neighbour index."""
        return math.inf

    def track(self, times: ArrayLike) -> Array:
        """Positions (m, n, 3) at each of ``times`` (convenience, loops over times)."""
        ts = np.asarray(times, dtype=float).reshape(-1)
        return np.stack([self.position(t) for t in ts]) if ts.size else np.empty((0, self.n, 3))

    # Subclass hooks ------------------------------------------------------------------------

    def _raw_position(self, t: float) -> Array:
        raise NotImplementedError

    def _raw_velocity(self, t: float) -> Array:
        raise NotImplementedError

    def _raw_position_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        raise NotImplementedError

    def _raw_velocity_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        raise NotImplementedError


# ---------------------------------------------------------------------------------------------
# Models


class Static(Mobility):
    """Nodes that never move (moored anchors, buoys)."""

    _folds = False

    def __init__(self, initial_positions: ArrayLike, box: Box, rng: np.random.Generator | None = None) -> None:
        super().__init__(initial_positions, box, rng)
        self._zero = _readonly(np.zeros_like(self._p0))

    def _raw_position(self, t: float) -> Array:
        return self._p0

    def _raw_velocity(self, t: float) -> Array:
        return self._zero

    def _raw_position_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        return self._p0[idx]

    def max_speed(self) -> float:
        return 0.0

    def _raw_velocity_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        return np.zeros((idx.size, 3))


class ConstantVelocity(Mobility):
    """Straight lines at constant velocity (m/s), ``velocity`` a 3-vector or (n, 3)."""

    def __init__(
        self,
        initial_positions: ArrayLike,
        box: Box,
        rng: np.random.Generator | None = None,
        *,
        velocity: ArrayLike = (0.0, 0.0, 0.0),
    ) -> None:
        super().__init__(initial_positions, box, rng)
        v = np.asarray(velocity, dtype=float)
        try:
            v = np.broadcast_to(v, (self.n, 3)).copy()
        except ValueError:
            raise ValueError(f"velocity must be a 3-vector or shape ({self.n}, 3), got {v.shape}") from None
        if not np.all(np.isfinite(v)):
            raise ValueError("velocity must be finite")
        self._v = _readonly(v)

    def _raw_position(self, t: float) -> Array:
        return self._p0 + self._v * t

    def max_speed(self) -> float:
        return float(np.sqrt(np.einsum("ij,ij->i", self._v, self._v)).max())

    def _raw_velocity(self, t: float) -> Array:
        return self._v

    def _raw_position_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        return self._p0[idx] + self._v[idx] * t[:, None]

    def _raw_velocity_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        return self._v[idx]

    def line_records(self) -> Array:
        """Each node's trajectory as a record (n, 7, 3): start position (m), velocity (m/s),
        and the box's lo, hi, size, 2 size, 1 / (2 size) (m, 1/m), the constants
        :meth:`Box.fold` uses (for the channel's compiled links, ``channel.straight``)."""
        b = self.box
        consts = (b.lo, b.hi, b.size, b._period, b._inv_period)
        return np.stack([self._p0, self._v, *(np.broadcast_to(a, (self.n, 3)) for a in consts)], axis=1)


class CoordinatedTurn(Mobility):
    """Constant horizontal speed on circles in x-y plus a constant vertical speed.

    Heading h(t) = heading + turn_rate t (rad, from +x towards +y); the horizontal velocity is
    speed (cos h, sin h), so the circle radius is speed / |turn_rate|. Positions use the exact
    arc integral written with sinc so turn_rate -> 0 is the straight line without cancellation.

    Parameters (scalars or per node (n,)): ``speed`` (m/s, >= 0), ``turn_rate`` (rad/s),
    ``heading`` (rad; uniform on [0, 2 pi) from ``rng`` when None), ``vz`` (m/s, down positive).
    """

    def __init__(
        self,
        initial_positions: ArrayLike,
        box: Box,
        rng: np.random.Generator | None = None,
        *,
        speed: ArrayLike = 1.0,
        turn_rate: ArrayLike = 0.0,
        heading: ArrayLike | None = None,
        vz: ArrayLike = 0.0,
    ) -> None:
        super().__init__(initial_positions, box, rng)
        n = self.n
        self.speed = _readonly(_per_node("speed", speed, n, minimum=0.0))
        self.turn_rate = _readonly(_per_node("turn_rate", turn_rate, n))
        if heading is None:
            heading = _need_rng(rng, "CoordinatedTurn with heading=None").uniform(0.0, 2.0 * np.pi, n)
        self.heading = _readonly(_per_node("heading", heading, n))
        self.vz = _readonly(_per_node("vz", vz, n))

    @staticmethod
    def _arc(p0: Array, speed: Array, rate: Array, heading: Array, vz: Array, t: float | Array) -> Array:
        half = rate * (0.5 * t)
        mid = heading + half
        # sin(h0 + w t) - sin(h0) = 2 cos(h0 + w t / 2) sin(w t / 2) (and likewise for cos):
        # chord = speed t sinc(w t / 2), no cancellation as w -> 0.
        chord = np.ones(len(p0))
        np.divide(np.sin(half), half, out=chord, where=half != 0.0)
        chord *= speed * t
        d = np.empty((3, len(p0)))
        np.cos(mid, out=d[0])
        np.sin(mid, out=d[1])
        d[:2] *= chord
        np.multiply(vz, t, out=d[2])
        return p0 + d.T

    @staticmethod
    def _tangent(speed: Array, rate: Array, heading: Array, vz: Array, t: float | Array) -> Array:
        h = heading + rate * t
        d = np.empty((3, len(speed)))
        np.cos(h, out=d[0])
        np.sin(h, out=d[1])
        d[:2] *= speed
        d[2] = vz
        return np.ascontiguousarray(d.T)

    def max_speed(self) -> float:
        return float(np.hypot(self.speed, self.vz).max())

    def _raw_position(self, t: float) -> Array:
        return self._arc(self._p0, self.speed, self.turn_rate, self.heading, self.vz, t)

    def _raw_velocity(self, t: float) -> Array:
        return self._tangent(self.speed, self.turn_rate, self.heading, self.vz, t)

    def _raw_position_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        return self._arc(self._p0[idx], self.speed[idx], self.turn_rate[idx], self.heading[idx], self.vz[idx], t)

    def _raw_velocity_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        return self._tangent(self.speed[idx], self.turn_rate[idx], self.heading[idx], self.vz[idx], t)


class RandomWalk(Mobility):
    """Piecewise-constant velocity legs of ``leg_duration`` s, each drawn afresh.

    Leg speeds are uniform on [speed_min, speed_max] (m/s); directions are uniform on the
    horizontal circle (``vertical=False``, vz = 0) or on the sphere (``vertical=True``). Legs are
    drawn from ``rng`` in fixed blocks of 64, all nodes at once, as far as queries reach.
    """

    _BLOCK = 64

    def __init__(
        self,
        initial_positions: ArrayLike,
        box: Box,
        rng: np.random.Generator | None = None,
        *,
        speed_min: float = 0.0,
        speed_max: float = 1.0,
        leg_duration: float = 10.0,
        vertical: bool = False,
    ) -> None:
        super().__init__(initial_positions, box, rng)
        self._legs_rng = _need_rng(rng, "RandomWalk")
        self.speed_min = float(speed_min)
        self.speed_max = float(speed_max)
        if not (0.0 <= self.speed_min <= self.speed_max < math.inf):
            raise ValueError(f"need 0 <= speed_min <= speed_max < inf, got {speed_min!r}, {speed_max!r}")
        self.leg_duration = _positive("leg_duration", leg_duration)
        self.vertical = bool(vertical)
        # Leg k: raw start position _starts[k], velocity _vels[k].
        self._starts = _Table(self._p0)
        self._vels: _Table | None = None

    def _draw_block(self) -> None:
        rng, n, b = self._legs_rng, self.n, self._BLOCK
        speed = rng.uniform(self.speed_min, self.speed_max, (b, n))
        azimuth = rng.uniform(0.0, 2.0 * np.pi, (b, n))
        if self.vertical:
            cos_polar = rng.uniform(-1.0, 1.0, (b, n))  # uniform on the sphere (Archimedes)
            horiz = np.sqrt(1.0 - cos_polar**2)
        else:
            cos_polar = np.zeros((b, n))
            horiz = np.ones((b, n))
        vel = speed[..., None] * np.stack((horiz * np.cos(azimuth), horiz * np.sin(azimuth), cos_polar), axis=-1)
        ends = self._starts.last + np.cumsum(vel * self.leg_duration, axis=0)
        if self._vels is None:
            self._vels = _Table(vel[0])
            self._vels.append(vel[1:])
        else:
            self._vels.append(vel)
        self._starts.append(ends)

    @property
    def _vel_data(self) -> Array:
        # _leg / _legs_at have drawn at least one block before any read
        assert self._vels is not None
        return self._vels.data

    def _leg(self, t: float) -> tuple[int, float]:
        k = int(t // self.leg_duration)
        while self._vels is None or k >= self._vels.count:
            self._draw_block()
        return k, t - k * self.leg_duration

    def max_speed(self) -> float:
        return self.speed_max  # every leg: speed <= speed_max along a unit direction

    def _raw_position(self, t: float) -> Array:
        k, dt = self._leg(t)
        return self._starts.data[k] + self._vel_data[k] * dt

    def _raw_velocity(self, t: float) -> Array:
        k, _ = self._leg(t)
        return self._vel_data[k]

    def _legs_at(self, t: Array) -> tuple[NDArray[np.intp], Array]:
        k = np.floor(t / self.leg_duration).astype(np.intp)
        self._leg(float(k.max()) * self.leg_duration if k.size else 0.0)
        return k, t - k * self.leg_duration

    def _raw_position_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        k, dt = self._legs_at(t)
        return self._starts.data[k, idx] + self._vel_data[k, idx] * dt[:, None]

    def _raw_velocity_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        k, _ = self._legs_at(t)
        return self._vel_data[k, idx]

    def leg_velocities(self, count: int) -> Array:
        """Unconstrained velocities (count, n, 3) of the first ``count`` legs (for analysis)."""
        if count <= 0:
            return np.empty((0, self.n, 3))
        self._leg((count - 1) * self.leg_duration)
        return self._vel_data[:count].copy()


class NoisyConstantVelocity(Mobility):
    """The discrete-time nearly-constant-velocity target of tracking papers (e.g. MSWPF eqs 1-3,
    38-40): states sampled every ``dt`` s from ``start_s`` on, x_{k+1} = F x_k + w_k with the
    exactly discretized white-noise-acceleration covariance of density ``q`` (m^2/s^3) on each
    moving axis (x, y; and z with ``vertical``). Between samples the node moves in a straight
    line (the reported velocity is that segment's), so positions at the sample instants are
    exactly the model's; before ``start_s`` it rests at its initial position. Steps are drawn
    from ``rng`` in fixed blocks of 64, all nodes at once, as far as queries reach.

    ``confine_steps`` > 0: the first that many steps of a node are drawn again (from the same
    stream) until its track stays inside the box: the CV model conditioned on staying in the
    scenario volume (rejection sampling, so each accepted track is an exact draw of the
    conditioned model; e.g. a tracking paper's target that stays in its sensor field). Later
    steps, if queried, continue unconditioned. ``max_redraws`` bounds the attempts per node.
    """

    _BLOCK = 64

    def __init__(
        self,
        initial_positions: ArrayLike,
        box: Box,
        rng: np.random.Generator | None = None,
        *,
        velocity: ArrayLike = (0.0, 0.0, 0.0),
        q: float = 1.0,
        dt: float = 1.0,
        start_s: float = 0.0,
        vertical: bool = False,
        confine_steps: int = 0,
        max_redraws: int = 100000,
    ) -> None:
        super().__init__(initial_positions, box, rng)
        self._steps_rng = _need_rng(rng, "NoisyConstantVelocity")
        v = np.asarray(velocity, dtype=float)
        try:
            v = np.broadcast_to(v, (self.n, 3)).copy()
        except ValueError:
            raise ValueError(f"velocity must be a 3-vector or shape ({self.n}, 3), got {v.shape}") from None
        if not np.all(np.isfinite(v)):
            raise ValueError("velocity must be finite")
        if not (math.isfinite(q) and q >= 0.0):
            raise ValueError(f"q must be >= 0 and finite, got {q!r}")
        self.dt = _positive("dt", dt)
        self.start_s = float(start_s)
        if not (math.isfinite(self.start_s) and self.start_s >= 0.0):
            raise ValueError(f"start_s must be >= 0 and finite, got {start_s!r}")
        self.vertical = bool(vertical)
        if not self.vertical:
            v[:, 2] = 0.0
        self.q = float(q)
        T = self.dt
        # per axis: [p, v] covariance of the exact CWNA discretization, as a Cholesky factor
        self._L = np.linalg.cholesky(q * np.array([[T**3 / 3.0, T**2 / 2.0], [T**2 / 2.0, T]]) + 1e-300 * np.eye(2))
        self._P = _Table(self._p0)
        self._V = _Table(v)
        self.redraws = 0  # tracks drawn again by the confinement, all nodes
        if int(confine_steps) < 0 or int(max_redraws) < 1:
            raise ValueError(f"confine_steps must be >= 0 and max_redraws >= 1, got {confine_steps!r}, {max_redraws!r}")
        if confine_steps:
            self._confine(int(confine_steps), int(max_redraws))

    def _steps(self, z: Array, p: Array, v: Array) -> tuple[Array, Array]:
        """States after each of the steps of standard normals ``z`` (b, n, 3, 2) from (p, v)."""
        w = z @ self._L.T  # (b, n, 3, [p, v])
        if not self.vertical:
            w[:, :, 2, :] = 0.0
        ps, vs = np.empty(z.shape[:3]), np.empty(z.shape[:3])
        for j in range(z.shape[0]):  # a recursion in time (over steps, not nodes)
            p = p + self.dt * v + w[j, :, :, 0]
            v = v + w[j, :, :, 1]
            ps[j], vs[j] = p, v
        return ps, vs

    def _confine(self, steps: int, max_redraws: int) -> None:
        """Draw the first ``steps`` steps, each node's again until its track stays in the box."""
        p0, v0 = self._P.last.copy(), self._V.last.copy()
        ps, vs = self._steps(self._steps_rng.standard_normal((steps, self.n, 3, 2)), p0, v0)
        out: NDArray[np.bool_] = np.asarray(~self.box.contains(ps).all(axis=0))  # (n,)
        tries = 1
        while out.any():
            if tries >= max_redraws:
                raise ValueError(
                    f"no track of node(s) {np.flatnonzero(out).tolist()} stayed in {self.box!r} for "
                    f"{steps} steps in {max_redraws} draws: a larger volume, fewer confine_steps or a smaller q"
                )
            idx = np.flatnonzero(out)
            z = self._steps_rng.standard_normal((steps, idx.size, 3, 2))
            ps[:, idx], vs[:, idx] = self._steps(z, p0[idx], v0[idx])
            out[idx] = ~self.box.contains(ps[:, idx]).all(axis=0)
            self.redraws += idx.size
            tries += 1
        self._P.append(ps)
        self._V.append(vs)

    def _draw_block(self) -> None:
        z = self._steps_rng.standard_normal((self._BLOCK, self.n, 3, 2))
        ps, vs = self._steps(z, self._P.last.copy(), self._V.last.copy())
        self._P.append(ps)
        self._V.append(vs)

    def _seg(self, t: Array) -> tuple[NDArray[np.intp], Array]:
        """Segment index k (-1 before the start) and time into it."""
        u = (t - self.start_s) / self.dt
        k = np.where(u < 0.0, -1, np.floor(u)).astype(np.intp)
        kmax = int(k.max()) if k.size else 0
        while self._P.count <= kmax + 1:
            self._draw_block()
        return k, t - self.start_s - np.maximum(k, 0) * self.dt

    def _at(self, idx: NDArray[np.intp], t: Array) -> tuple[Array, Array]:
        k, tau = self._seg(t)
        kk = np.maximum(k, 0)
        p0 = self._P.data[kk, idx]
        seg_v = (self._P.data[kk + 1, idx] - p0) / self.dt
        before = (k < 0)[:, None]
        pos = np.where(before, self._p0[idx], p0 + seg_v * tau[:, None])
        return pos, np.where(before, 0.0, seg_v)

    def _raw_position(self, t: float) -> Array:
        idx = np.arange(self.n)
        return self._at(idx, np.full(self.n, t))[0]

    def _raw_velocity(self, t: float) -> Array:
        idx = np.arange(self.n)
        return self._at(idx, np.full(self.n, t))[1]

    def _raw_position_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        return self._at(idx, t)[0]

    def _raw_velocity_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        return self._at(idx, t)[1]


class Waypoints(Mobility):
    """Constant speed along straight segments: initial position -> waypoints[i][0] -> ... .

    ``waypoints``: per node a sequence of points (array (n, m, 3) or a list of n arrays
    (m_i, 3)), all inside the box (the box is convex, so paths never need folding). ``speed``
    (m/s, scalar or (n,)). After the last point a node stops (``loop=False``) or heads back to
    its initial position and repeats the cycle (``loop=True``).
    """

    _folds = False

    def __init__(
        self,
        initial_positions: ArrayLike,
        box: Box,
        rng: np.random.Generator | None = None,
        *,
        waypoints: ArrayLike | Sequence[ArrayLike],
        speed: ArrayLike = 1.0,
        loop: bool = False,
    ) -> None:
        super().__init__(initial_positions, box, rng)
        n = self.n
        wps: Sequence[ArrayLike] = waypoints  # type: ignore[assignment]  # an (n, m, 3) array is a sequence too
        if len(wps) != n:
            raise ValueError(f"waypoints must give one list of points per node ({n}), got {len(wps)}")
        self.speed = _readonly(_per_node("speed", speed, n, minimum=0.0))
        self.loop = bool(loop)
        paths = []
        for i, w in enumerate(wps):
            wa = np.asarray(w, dtype=float)
            if wa.ndim != 2 or wa.shape[1] != 3 or wa.shape[0] < 1:
                raise ValueError(f"waypoints of node {i} must have shape (m, 3) with m >= 1, got {wa.shape}")
            if not np.all(np.isfinite(wa)) or not np.all(box.contains(wa)):
                raise ValueError(f"waypoints of node {i} must be finite and inside {box!r}")
            legs = [self._p0[i : i + 1], wa] + ([self._p0[i : i + 1]] if self.loop else [])
            paths.append(np.concatenate(legs))
        m = max(len(p) for p in paths)
        # Pad with repeats of the last point: zero-length segments take no time.
        pts = np.stack([np.concatenate([p, np.repeat(p[-1:], m - len(p), axis=0)]) for p in paths])
        #: Path corners per node (n, M + 1, 3), starting at the initial position.
        self.points = _readonly(pts)
        seg = np.diff(pts, axis=1)  # (n, M, 3)
        length = np.linalg.norm(seg, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            unit = np.where(length[..., None] > 0.0, seg / length[..., None], 0.0)
        self._starts = _readonly(pts[:, :-1])
        self._unit = _readonly(unit)
        self._cum = _readonly(np.concatenate([np.zeros((n, 1)), np.cumsum(length, axis=1)[:, :-1]], axis=1))
        self.path_length = _readonly(length.sum(axis=1))
        segs = self._cum.shape[1]
        self._row_base = np.arange(n) * segs - 1
        self._starts_flat = self._starts.reshape(n * segs, 3)
        self._unit_flat = self._unit.reshape(n * segs, 3)
        self._cum_flat = self._cum.reshape(n * segs)
        self._closed = self.path_length > 0.0
        self._safe_total = np.where(self._closed, self.path_length, 1.0)

    def _locate(self, idx: NDArray[np.intp] | slice, t: float | Array) -> tuple[Array, NDArray[np.intp], Array]:
        """(arc length travelled, flat segment index, speed now) for nodes ``idx`` at ``t``."""
        speed = self.speed[idx]
        s = speed * t
        if self.loop:
            closed = self._closed[idx]
            s = np.where(closed, np.mod(s, self._safe_total[idx]), 0.0)
            speed_now = np.where(closed, speed, 0.0)
        else:
            total = self.path_length[idx]
            speed_now = np.where(s < total, speed, 0.0)
            np.minimum(s, total, out=s)
        # Last segment starting at or before s: skips zero-length segments.
        k = np.count_nonzero(self._cum[idx] <= s[:, None], axis=1)
        k += self._row_base[idx]  # row * M - 1
        return s, k, speed_now

    def _place(self, s: Array, k: NDArray[np.intp]) -> Array:
        along = s - np.take(self._cum_flat, k)
        return np.take(self._starts_flat, k, axis=0) + np.take(self._unit_flat, k, axis=0) * along[:, None]

    def _raw_position(self, t: float) -> Array:
        s, k, _ = self._locate(slice(None), t)
        return self._place(s, k)

    def _raw_velocity(self, t: float) -> Array:
        _, k, speed_now = self._locate(slice(None), t)
        return np.take(self._unit_flat, k, axis=0) * speed_now[:, None]

    def _raw_position_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        s, k, _ = self._locate(idx, t)
        return self._place(s, k)

    def _raw_velocity_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        _, k, speed_now = self._locate(idx, t)
        return np.take(self._unit_flat, k, axis=0) * speed_now[:, None]


class _CurrentDrift(Mobility):
    """Passive drift in a 2-D velocity field given in dimensionless units (shared machinery).

    Physical units: x = origin_x + length_scale x', y = origin_y + length_scale y',
    t = time_scale (t' - phase), v = (length_scale / time_scale) v'. Subclasses give the field
    in :meth:`_dimensionless` (per-node parameters broadcast on the last axis).

    Trajectories are integrated once, in fixed chunks of ``_CHUNK`` table steps from t = 0
    (scipy DOP853, rtol 1e-12, all nodes in one state vector), into a table of positions and
    velocities every ``time_scale / steps_per_unit`` seconds (packed: one (2, 3) row per knot
    and node, so a batch of queries gathers each knot's position and velocity at once), and
    read back by cubic Hermite interpolation: ``position`` is C1, ``velocity`` its exact
    derivative, a query costs microseconds and the result does not depend on the order of
    queries. The field acts on the unconstrained path, which is then folded into the box
    (mirror walls). Depth is constant.
    """

    _CHUNK = 256
    _NAME = "current"

    def _init_scales(
        self, length_scale: float, time_scale: float, phase: float, steps_per_unit: int, origin: ArrayLike
    ) -> None:
        self.length_scale = _positive("length_scale", length_scale)
        self.time_scale = _positive("time_scale", time_scale)
        self.phase = float(phase)
        if not math.isfinite(self.phase):
            raise ValueError(f"phase must be finite, got {phase!r}")
        if int(steps_per_unit) != steps_per_unit or steps_per_unit < 16:
            raise ValueError(f"steps_per_unit must be an integer >= 16, got {steps_per_unit!r}")
        self.steps_per_unit = int(steps_per_unit)
        o = np.asarray(origin, dtype=float).reshape(-1)
        if o.shape != (2,) or not np.all(np.isfinite(o)):
            raise ValueError(f"origin must be a finite (x, y) pair in m, got {origin!r}")
        self.origin = _readonly(o)
        self._ox, self._oy = float(o[0]), float(o[1])

    def _init_table(self) -> None:
        self._speed_scale = self.length_scale / self.time_scale
        self._h = self.time_scale / self.steps_per_unit  # table step, s
        self._inv_h = 1.0 / self._h
        p0 = self._p0.copy()
        self._pv = _Table(np.stack((p0, self.field(p0, 0.0)), axis=1))  # (K, n, 2, 3): position, velocity
        self._state_t = math.nan  # the time of the kept state (see state)
        self._state: tuple[Array, Array] = (p0, p0)

    def _dimensionless(self, x: Array, y: Array, tp: Array | float) -> tuple[Array, Array]:
        raise NotImplementedError

    def field(self, p: ArrayLike, t: ArrayLike) -> Array:
        """Current velocity (m/s), shape (..., n, 3) with vz = 0, at unfolded positions ``p`` (..., n, 3), time ``t`` (s, broadcast to p[..., 0])."""
        pa = np.asarray(p, dtype=float)
        tp = np.asarray(t, dtype=float) / self.time_scale + self.phase
        L = self.length_scale
        # origin 0 leaves x exactly as it is (x - 0.0 == x): the kinematic model's traces
        # stayed byte-identical when the origin was introduced.
        vx, vy = self._dimensionless((pa[..., 0] - self._ox) / L, (pa[..., 1] - self._oy) / L, tp)
        return np.stack((vx, vy, np.zeros_like(vx)), axis=-1) * self._speed_scale

    def _rhs(self, tp: float, s: Array) -> Array:
        """Dimensionless ODE right-hand side, state (x'_1..x'_n, y'_1..y'_n)."""
        n = self.n
        return np.concatenate(self._dimensionless(s[:n], s[n:], tp))

    def _extend(self) -> None:
        """Integrate one more chunk of ``_CHUNK`` table steps from the last knot."""
        n, spu, L = self.n, self.steps_per_unit, self.length_scale
        k0 = self._pv.count - 1
        last = self._pv.last[:, 0]
        s0 = np.concatenate(((last[:, 0] - self._ox) / L, (last[:, 1] - self._oy) / L))
        # Knot times in dimensionless units; computed from integers so chunks tile exactly.
        tgrid = self.phase + np.arange(k0, k0 + self._CHUNK + 1) / spu
        sol = solve_ivp(self._rhs, (tgrid[0], tgrid[-1]), s0, method="DOP853", t_eval=tgrid[1:], rtol=1e-12, atol=1e-13)
        if not sol.success:  # pragma: no cover - the fields are smooth and bounded
            raise RuntimeError(f"{type(self).__name__} integration failed: {sol.message}")
        xy = sol.y.T * L  # (C, 2n)
        pos = np.empty((self._CHUNK, n, 3))
        pos[:, :, 0] = xy[:, :n] + self._ox
        pos[:, :, 1] = xy[:, n:] + self._oy
        pos[:, :, 2] = self._p0[:, 2]
        times = (np.arange(k0 + 1, k0 + self._CHUNK + 1)) * self._h
        vel = self.field(pos, times[:, None])
        self._pv.append(np.stack((pos, vel), axis=2))

    def _knots_at(self, idx: NDArray[np.intp], t: Array) -> tuple[NDArray[np.intp], NDArray[np.intp], Array]:
        """Flat row indices of (knot i, knot i + 1) per pair, and the fraction u (m, 1)."""
        x = t * self._inv_h
        i = x.astype(np.intp)  # t >= 0: truncation is floor
        if i.size:
            self._knot(float(t.max()))
        flat = i * self.n + idx
        return flat, flat + self.n, (x - i)[:, None]

    def _gather(self, idx: NDArray[np.intp], t: Array) -> tuple[Array, Array, Array, Array, Array]:
        """(P_a, V_a, P_b, V_b, u): position and velocity at the knots around each (node, time)
        pair (each (m, 3), strided views of two gathers) and the fraction u (m, 1)."""
        a, b, u = self._knots_at(idx, t)
        pv = self._pv.data.reshape(-1, 2, 3)
        ga, gb = pv.take(a, 0), pv.take(b, 0)
        return ga[:, 0], ga[:, 1], gb[:, 0], gb[:, 1], u

    def _hermite(self, pa: Array, va: Array, pb: Array, vb: Array, u: Array | float) -> Array:
        um = 1.0 - u
        h00 = (1.0 + 2.0 * u) * um * um
        h10 = u * um * um * self._h
        h01 = u * u * (3.0 - 2.0 * u)
        h11 = -u * u * um * self._h
        return h00 * pa + h10 * va + h01 * pb + h11 * vb

    def _hermite_derivative(self, pa: Array, va: Array, pb: Array, vb: Array, u: Array | float) -> Array:
        um = 1.0 - u
        d00 = 6.0 * u * um * self._inv_h
        d10 = um * (1.0 - 3.0 * u)
        d11 = u * (3.0 * u - 2.0)
        return d00 * (pb - pa) + d10 * va + d11 * vb

    def state(self, t: float) -> tuple[Array, Array]:
        """``Mobility.state``, kept for the last time asked (read-only arrays): at one instant
        a group's positions and velocities are asked for several times (a beacon's position
        fix, depth and velocity sensors, then the channel), each a full evaluation before."""
        tf = _time(t)
        if tf != self._state_t:
            pos, vel = super().state(tf)
            pos.flags.writeable = False
            vel.flags.writeable = False
            self._state_t, self._state = tf, (pos, vel)
        return self._state

    def position(self, t: float) -> Array:
        """Positions (n, 3) in m at true time ``t`` (s), read-only (see :meth:`state`)."""
        return self.state(t)[0]

    def _raw_position_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        return self._hermite(*self._gather(idx, t))

    def _raw_velocity_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        return self._hermite_derivative(*self._gather(idx, t))

    def _raw_state_at(self, idx: NDArray[np.intp], t: Array) -> tuple[Array, Array]:
        g = self._gather(idx, t)
        return self._hermite(*g), self._hermite_derivative(*g)

    def _knot(self, t: float) -> tuple[int, float]:
        x = t * self._inv_h
        i = int(x)
        while i + 1 >= self._pv.count:
            self._extend()
        return i, x - i

    def _raw_position(self, t: float) -> Array:
        # cubic Hermite on [t_i, t_i + h], every node (the rows of the knots i and i + 1)
        i, u = self._knot(t)
        a, b = self._pv.data[i], self._pv.data[i + 1]
        return self._hermite(a[:, 0], a[:, 1], b[:, 0], b[:, 1], u)

    def _raw_velocity(self, t: float) -> Array:
        i, u = self._knot(t)
        a, b = self._pv.data[i], self._pv.data[i + 1]
        return self._hermite_derivative(a[:, 0], a[:, 1], b[:, 0], b[:, 1], u)


class Kinematic(_CurrentDrift):
    """Drift in the kinematic ocean-current model of SLMP (STVF, Sensors 2018, Sec. 5.1).

    Scenario name ``kinematic`` (``meandering_current`` is its deprecated alias). Dimensionless
    velocity field (STVF's unnumbered equation after Table 1), x, y, t dimensionless::

        Vx = k1 iota omega sin(k2 x) cos(k3 y) + k1 iota cos(2 k1 t) + k4
        Vy = -iota omega cos(k2 x) sin(k3 y) + k5

    Each node draws its own k1..k5, iota, omega from N(mean, (rel_std * mean)^2) (Table 1 gives
    N(mean, precision) with std 10 % of the mean). Physical units: see :class:`_CurrentDrift`
    (``origin`` defaults to (0, 0)). Defaults: ``time_scale`` = 44712 s (12.42 h, the
    semidiurnal M2 tide: cos(2 k1 t') then has the tidal period at the mean k1 = pi) and
    ``length_scale`` = 4471.2 m (speed scale 0.1 m/s), which give a mean speed of about
    1.0 m/s at phase 0 and about 105 m covered in 100 s, as in STVF's sample trajectory
    (~110 m in 100 s). Depth stays constant (the model is 2-D).
    """

    _PARAMS = ("k1", "k2", "k3", "iota", "omega", "k4", "k5")
    # per-node draws (n,), set in __init__ by name
    k1: Array
    k2: Array
    k3: Array
    k4: Array
    k5: Array
    iota: Array
    omega: Array

    def __init__(
        self,
        initial_positions: ArrayLike,
        box: Box,
        rng: np.random.Generator | None = None,
        *,
        length_scale: float = 4471.2,
        time_scale: float = 44712.0,
        phase: float = 0.0,
        origin: ArrayLike = (0.0, 0.0),
        k1: float = math.pi,
        k2: float = math.pi,
        k3: float = 2.0 * math.pi,
        iota: float = 3.0,
        omega: float = 1.0,
        k4: float = 1.0,
        k5: float = 1.0,
        rel_std: float = 0.1,
        steps_per_unit: int = 2048,
    ) -> None:
        super().__init__(initial_positions, box, rng)
        self._init_scales(length_scale, time_scale, phase, steps_per_unit, origin)
        self.rel_std = float(rel_std)
        if not (0.0 <= self.rel_std < math.inf):
            raise ValueError(f"rel_std must be >= 0, got {rel_std!r}")
        means = dict(k1=k1, k2=k2, k3=k3, iota=iota, omega=omega, k4=k4, k5=k5)
        gen = _need_rng(rng, type(self).__name__) if self.rel_std > 0.0 else None
        for name in self._PARAMS:  # fixed draw order: the same seed gives the same nodes
            mean = float(means[name])
            if not math.isfinite(mean):
                raise ValueError(f"{name} must be finite, got {means[name]!r}")
            vals = gen.normal(mean, self.rel_std * abs(mean), self.n) if gen is not None else np.full(self.n, mean)
            setattr(self, name, _readonly(vals))
        self._init_table()

    def _dimensionless(self, x: Array, y: Array, tp: Array | float) -> tuple[Array, Array]:
        """(Vx', Vy') of the STVF field at dimensionless x', y', t' (per-node parameters broadcast on the last axis)."""
        a = self.iota * self.omega
        tide = self.k1 * self.iota * np.cos(2.0 * self.k1 * tp)
        vx = self.k1 * a * np.sin(self.k2 * x) * np.cos(self.k3 * y) + tide + self.k4
        vy = -a * np.cos(self.k2 * x) * np.sin(self.k3 * y) + self.k5
        return vx, vy


class MeanderingCurrent(Kinematic):
    """Deprecated name of :class:`Kinematic` (the STVF/SLMP model, not Caruso's meandering
    current): warns on construction. The Bower/Caruso model is :class:`MeanderingJet`."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        warnings.warn(
            "mobility.MeanderingCurrent is deprecated: it is the STVF/SLMP kinematic model, now "
            "mobility.Kinematic; the Bower/Caruso meandering current is mobility.MeanderingJet",
            DeprecationWarning,
            stacklevel=2,
        )
        super().__init__(*args, **kwargs)


class MeanderingJet(_CurrentDrift):
    """Drift in Bower's (1991) kinematic meandering jet, the "meandering current mobility
    model" of Caruso, Paparella, Vieira, Erol and Gerla (IEEE INFOCOM 2008).

    Scenario name ``meandering_jet``. Dimensionless stream function (Bower 1991, as used by
    Caruso et al.), with theta = k (x' - c t') and B(t') = A + epsilon cos(omega t')::

        psi(x', y', t') = 1 - tanh( (y' - B cos theta) / sqrt(1 + k^2 B^2 sin^2 theta) )

    and velocity u' = -d psi / d y', v' = d psi / d x' (analytic derivatives below): an
    eastward jet of unit peak speed and unit half-width whose axis y' = B cos(theta) meanders
    with wavelength 2 pi / k, moves east at c and breathes with period 2 pi / omega (the
    breathing makes fluid cross between jet and recirculation cells: chaotic transport).
    The authors' SmmLib code writes the same field as sin theta over sqrt(1 + k^2 B^2 cos^2),
    i.e. shifted by a quarter wavelength in x.

    Defaults are Caruso et al.'s: A = 1.2, c = 0.12, k = 2 pi / 7.5 (``wavelength`` 7.5),
    omega = 0.4, epsilon = 0.3, with the authors' scaling (their SmmLib, README and test
    driver) of one length unit = 1 km and one time unit = 0.03 days = 2592 s: peak jet speed
    1000 / 2592 = 0.386 m/s, meander wavelength 7.5 km, amplitude 1.2 km, phase speed
    0.046 m/s, breathing period 2 pi / 0.4 units = 11.3 h. ``origin`` (m) is where x' = y' = 0
    (default: the box centre in x-y, so the jet axis crosses the scenario volume); ``phase`` is
    t' at t = 0 (Caruso et al. draw it uniformly on [0, 2 pi / (c k)); ``random_phase=True``
    or ``phase=None`` does so from ``rng``). All nodes share one field (no per-node parameters); depth stays constant.
    The field is divergence-free, so the flow preserves area in x-y.
    """

    def __init__(
        self,
        initial_positions: ArrayLike,
        box: Box,
        rng: np.random.Generator | None = None,
        *,
        amplitude: float = 1.2,
        phase_speed: float = 0.12,
        wavelength: float = 7.5,
        omega: float = 0.4,
        epsilon: float = 0.3,
        length_scale: float = 1000.0,
        time_scale: float = 2592.0,
        phase: float | None = 0.0,
        random_phase: bool = False,
        origin: ArrayLike | None = None,
        steps_per_unit: int = 128,
    ) -> None:
        super().__init__(initial_positions, box, rng)
        vals = dict(amplitude=amplitude, phase_speed=phase_speed, omega=omega, epsilon=epsilon)
        for name, v in vals.items():
            if not math.isfinite(float(v)):
                raise ValueError(f"{name} must be finite, got {v!r}")
        self.amplitude = float(amplitude)
        self.phase_speed = float(phase_speed)
        self.wavelength = _positive("wavelength", wavelength)
        self.k = 2.0 * math.pi / self.wavelength
        self.omega = float(omega)
        self.epsilon = float(epsilon)
        if phase is None or random_phase:
            # Caruso et al.: a random shift over one meander passage period 2 pi / (c k).
            period = 2.0 * math.pi / (abs(self.phase_speed) * self.k) if self.phase_speed else 2.0 * math.pi
            phase = float(_need_rng(rng, "MeanderingJet with a random phase").uniform(0.0, period))
        if origin is None:
            origin = 0.5 * (box.lo[:2] + box.hi[:2])
        self._init_scales(length_scale, time_scale, phase, steps_per_unit, origin)
        self._init_table()

    def _axis(self, x: Array, y: Array, tp: Array | float) -> tuple[Array, Array, Array, Array, Array]:
        """(B, sin theta, cos theta, D, eta) with eta = (y' - B cos theta) / D."""
        B = self.amplitude + self.epsilon * np.cos(self.omega * np.asarray(tp, dtype=float))
        th = self.k * (x - self.phase_speed * tp)
        s, c = np.sin(th), np.cos(th)
        D = np.sqrt(1.0 + (self.k * B * s) ** 2)
        return B, s, c, D, (y - B * c) / D

    def stream_function(self, p: ArrayLike, t: ArrayLike) -> Array:
        """Dimensionless psi at positions ``p`` (..., 3) in m and times ``t`` (s, broadcast)."""
        pa = np.asarray(p, dtype=float)
        L = self.length_scale
        tp = np.asarray(t, dtype=float) / self.time_scale + self.phase
        eta = self._axis((pa[..., 0] - self._ox) / L, (pa[..., 1] - self._oy) / L, tp)[4]
        return 1.0 - np.tanh(eta)

    def _dimensionless(self, x: Array, y: Array, tp: Array | float) -> tuple[Array, Array]:
        B, s, c, D, eta = self._axis(x, y, tp)
        # sech^2 eta = 4 e^{-2|eta|} / (1 + e^{-2|eta|})^2: no overflow far from the jet.
        e = np.exp(-2.0 * np.abs(eta))
        sech2 = 4.0 * e / (1.0 + e) ** 2
        k = self.k
        # d eta / d y' = 1 / D;  d eta / d x' = k B sin / D - eta k^3 B^2 sin cos / D^2
        u = sech2 / D
        deta_dx = k * B * s / D - eta * (k**3 * B * B * s * c) / (D * D)
        return u, -sech2 * deta_dx
