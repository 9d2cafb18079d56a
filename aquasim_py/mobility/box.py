"""The scenario volume: a box whose walls, surface and bottom reflect like mirrors."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["Box"]

Array = NDArray[np.float64]


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
