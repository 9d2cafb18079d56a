"""The mobility base class: a group of nodes' exact trajectories, folded into the box."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .box import Box

__all__ = ["Mobility"]

Array = NDArray[np.float64]


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
