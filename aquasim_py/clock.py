"""Per-node local clocks: local = (1 + skew) t + offset, with optional skew drift and jitter.

True simulation time ``t`` (s) maps to a node's local time ``T`` (s). Without drift the map is
the affine clock of the ITMTL / TSHL papers, ``T = (1 + skew) t + offset`` (skew dimensionless,
e.g. 40e-6 = 40 ppm; offset in s). With drift the skew performs a Gaussian random walk on a
fixed grid of ``drift_interval`` seconds, ``skew_k = skew + e_1 + ... + e_k`` on
``[k D, (k+1) D)`` with ``e_j ~ N(0, drift_std)``, so ``T(t)`` is the exact piecewise-linear
integral of ``1 + skew(t)``: continuous, monotone increasing, exactly invertible.

Determinism: the drift increments are drawn in fixed-size blocks from a stream spawned from the
given generator, and the jitter from a second spawned stream, so ``to_local`` / ``to_true``
return the same values whatever the order (or number) of earlier queries and stamps.
Negative times use the first segment (the drift starts at t = 0).
"""

from __future__ import annotations

import math
from typing import overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["Clock"]

_SCALARS = (float, int, np.floating, np.integer)

# Drift increments are drawn this many at a time, always, so the stream never depends on how
# far the queries happened to reach.
_BLOCK = 256


def _finite(name: str, value: float) -> float:
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return v


def _spawn_two(rng: np.random.Generator) -> tuple[np.random.Generator, np.random.Generator]:
    """Two independent child streams of ``rng`` (drift, jitter), reproducible from its seed."""
    try:
        a, b = rng.spawn(2)
    except (AttributeError, TypeError, ValueError):  # bit generator without a SeedSequence
        seeds = rng.integers(0, 2**63, size=(2, 4), dtype=np.uint64)
        a, b = np.random.default_rng(seeds[0]), np.random.default_rng(seeds[1])
    return a, b


class Clock:
    """A node's local clock (see module docstring).

    Parameters
    ----------
    skew : initial skew (dimensionless, > -1), e.g. 40e-6.
    offset : local time at t = 0 (s).
    drift_std : std of the skew increment per drift step (dimensionless); 0 = no drift.
    drift_interval : length of one drift step (s).
    jitter_std : std of the Gaussian timestamp jitter added by :meth:`stamp` (s).
    rng : numpy Generator; required when ``drift_std`` or ``jitter_std`` is positive.
    """

    __slots__ = (
        "_count",
        "_drift_rng",
        "_jitter_rng",
        "_knots",
        "_skews",
        "drift_interval",
        "drift_std",
        "jitter_std",
        "offset",
        "skew",
    )

    # None only without drift and jitter (checked in __init__), when they are never drawn from
    _drift_rng: np.random.Generator | None
    _jitter_rng: np.random.Generator | None

    def __init__(
        self,
        skew: float = 0.0,
        offset: float = 0.0,
        drift_std: float = 0.0,
        drift_interval: float = 10.0,
        jitter_std: float = 0.0,
        rng: np.random.Generator | None = None,
    ) -> None:
        self.skew = _finite("skew", skew)
        if self.skew <= -1.0:
            raise ValueError(f"skew must be > -1 (local time must advance), got {skew!r}")
        self.offset = _finite("offset", offset)
        self.drift_std = _finite("drift_std", drift_std)
        if self.drift_std < 0.0:
            raise ValueError(f"drift_std must be >= 0, got {drift_std!r}")
        self.drift_interval = _finite("drift_interval", drift_interval)
        if self.drift_interval <= 0.0:
            raise ValueError(f"drift_interval must be > 0 s, got {drift_interval!r}")
        self.jitter_std = _finite("jitter_std", jitter_std)
        if self.jitter_std < 0.0:
            raise ValueError(f"jitter_std must be >= 0 s, got {jitter_std!r}")
        if rng is not None and not isinstance(rng, np.random.Generator):
            raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        if rng is None and (self.drift_std > 0.0 or self.jitter_std > 0.0):
            raise ValueError("rng (a numpy Generator) is required when drift_std or jitter_std > 0")
        if rng is not None:
            self._drift_rng, self._jitter_rng = _spawn_two(rng)
        else:
            self._drift_rng = self._jitter_rng = None
        # Segment k covers [k D, (k+1) D): skew _skews[k], local time _knots[k] at its start.
        # Both arrays hold _count segments; earlier entries never change once drawn.
        self._skews = np.array([self.skew])
        self._knots = np.array([self.offset])
        self._count = 1

    @classmethod
    def perfect(cls) -> Clock:
        """A clock on true time (buoys, anchors): local == true."""
        return cls()

    @property
    def drifts(self) -> bool:
        return self.drift_std > 0.0

    def __repr__(self) -> str:
        return (
            f"Clock(skew={self.skew!r}, offset={self.offset!r}, drift_std={self.drift_std!r}, "
            f"drift_interval={self.drift_interval!r}, jitter_std={self.jitter_std!r})"
        )

    # -- drift table ---------------------------------------------------------------------------

    def _extend(self, segments: int) -> None:
        """Make at least ``segments`` drift segments available (whole blocks at a time)."""
        rng = self._drift_rng
        if rng is None:  # unreachable: __init__ requires an rng when drift_std > 0
            raise RuntimeError("a drifting clock needs an rng")
        while self._count < segments:
            steps = rng.normal(0.0, self.drift_std, _BLOCK)
            new_skews = self._skews[self._count - 1] + np.cumsum(steps)
            if np.any(new_skews <= -1.0):
                raise ValueError(
                    "the skew random walk reached -1 (clock would stop): drift_std "
                    f"{self.drift_std!r} is far too large for drift_interval {self.drift_interval!r}"
                )
            prev = np.concatenate(([self._skews[self._count - 1]], new_skews[:-1]))
            new_knots = self._knots[self._count - 1] + np.cumsum((1.0 + prev) * self.drift_interval)
            self._skews = np.concatenate((self._skews[: self._count], new_skews))
            self._knots = np.concatenate((self._knots[: self._count], new_knots))
            self._count += _BLOCK

    def _segment(self, t: NDArray[np.float64]) -> NDArray[np.intp]:
        k = np.floor(t / self.drift_interval)
        k = np.clip(k, 0, None).astype(np.intp)
        if k.size:
            self._extend(int(k.max()) + 1)
        return k

    # -- public maps -----------------------------------------------------------------------------

    @overload
    def to_local(self, t: float) -> float: ...
    @overload
    def to_local(self, t: ArrayLike) -> NDArray[np.float64] | float: ...
    def to_local(self, t: ArrayLike) -> NDArray[np.float64] | float:
        """Local time (s) at true time(s) ``t`` (s); exact, vectorized."""
        if isinstance(t, _SCALARS):
            # Per-packet hot path: plain floats, the same operations as the array branch.
            tf = float(t)
            if not math.isfinite(tf):
                raise ValueError("true times must be finite")
            if not self.drifts:
                return (1.0 + self.skew) * tf + self.offset
            i = max(math.floor(tf / self.drift_interval), 0)
            if i >= self._count:
                self._extend(i + 1)
            return float(self._knots[i] + (1.0 + self._skews[i]) * (tf - i * self.drift_interval))
        ta = np.asarray(t, dtype=float)
        if not np.all(np.isfinite(ta)):
            raise ValueError("true times must be finite")
        if not self.drifts:
            out = (1.0 + self.skew) * ta + self.offset
        else:
            k = self._segment(ta)
            out = self._knots[k] + (1.0 + self._skews[k]) * (ta - k * self.drift_interval)
        return float(out) if out.ndim == 0 else out

    @overload
    def to_true(self, local: float) -> float: ...
    @overload
    def to_true(self, local: ArrayLike) -> NDArray[np.float64] | float: ...
    def to_true(self, local: ArrayLike) -> NDArray[np.float64] | float:
        """True time (s) at which the clock reads ``local`` (s): exact inverse of ``to_local``."""
        if isinstance(local, _SCALARS) and not self.drifts:
            lf = float(local)
            if not math.isfinite(lf):
                raise ValueError("local times must be finite")
            return (lf - self.offset) / (1.0 + self.skew)
        la = np.asarray(local, dtype=float)
        if not np.all(np.isfinite(la)):
            raise ValueError("local times must be finite")
        if not self.drifts:
            out = (la - self.offset) / (1.0 + self.skew)
        else:
            if la.size:
                top = float(la.max())
                # Extend until the last knot passes the largest query; the skew is > -1, so the
                # knots grow and this ends.
                while self._knots[self._count - 1] <= top:
                    self._extend(self._count + 1)
            knots = self._knots[: self._count]
            k = np.searchsorted(knots, la, side="right") - 1
            k = np.clip(k, 0, None)
            out = k * self.drift_interval + (la - knots[k]) / (1.0 + self._skews[k])
        return float(out) if out.ndim == 0 else out

    @overload
    def skew_at(self, t: float) -> float: ...
    @overload
    def skew_at(self, t: ArrayLike) -> NDArray[np.float64] | float: ...
    def skew_at(self, t: ArrayLike) -> NDArray[np.float64] | float:
        """Instantaneous skew (dimensionless) at true time(s) ``t``."""
        ta = np.asarray(t, dtype=float)
        if not self.drifts:
            out = np.full(ta.shape, self.skew)
        else:
            k = self._segment(ta)  # extends (and rebinds) the tables first
            out = self._skews[k]
        return float(out) if out.ndim == 0 else out

    @overload
    def offset_at(self, t: float) -> float: ...
    @overload
    def offset_at(self, t: ArrayLike) -> NDArray[np.float64] | float: ...
    def offset_at(self, t: ArrayLike) -> NDArray[np.float64] | float:
        """Offset (s) of the affine clock in force at ``t``: local = (1 + skew_at) t + offset_at."""
        ta = np.asarray(t, dtype=float)
        if not self.drifts:
            out = np.full(ta.shape, self.offset)
        else:
            k = self._segment(ta)
            out = self._knots[k] - (1.0 + self._skews[k]) * (k * self.drift_interval)
        return float(out) if out.ndim == 0 else out

    @overload
    def stamp(self, t: float) -> float: ...
    @overload
    def stamp(self, t: ArrayLike) -> NDArray[np.float64] | float: ...
    def stamp(self, t: ArrayLike) -> NDArray[np.float64] | float:
        """A timestamp taken at true time(s) ``t``: ``to_local(t)`` plus N(0, jitter_std) jitter."""
        local = self.to_local(t)
        if self.jitter_std == 0.0:
            return local
        rng = self._jitter_rng
        if rng is None:  # unreachable: __init__ requires an rng when jitter_std > 0
            raise RuntimeError("a jittering clock needs an rng")
        if isinstance(local, float):
            return local + float(rng.normal(0.0, self.jitter_std))
        noise = rng.normal(0.0, self.jitter_std, np.shape(local))
        out = local + noise
        return float(out) if np.ndim(out) == 0 else out
