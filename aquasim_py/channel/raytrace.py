"""Public eigenray API, for any sound-speed profile (dispatch to the closed forms or the
layered solver). See docs/internals.md for the contract."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .rays import Eigenray, PathKind
from .ssp import Constant, SoundSpeedProfile

__all__ = [
    "travel_time",
    "travel_time_gradient",
    "eigenray",
    "straight_line_time",
    "why_no_path",
]


def _pairs(src: ArrayLike, dst: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    s = np.asarray(src, dtype=float)
    d = np.asarray(dst, dtype=float)
    if s.shape[-1:] != (3,) or d.shape[-1:] != (3,):
        raise ValueError("src and dst must have a last axis of length 3 (x, y, z)")
    s, d = np.broadcast_arrays(s, d)
    return s, d


def eigenray(ssp: SoundSpeedProfile, src: ArrayLike, dst: ArrayLike, *, reflections: str = "fallback") -> Eigenray:
    """First-arrival eigenray from ``src`` to ``dst`` (..., 3)."""
    s, d = _pairs(src, dst)
    if isinstance(ssp, Constant):
        diff = d - s
        dist = np.linalg.norm(diff, axis=-1)
        horiz = np.hypot(diff[..., 0], diff[..., 1])
        ang = np.arctan2(diff[..., 2], horiz)
        return Eigenray(
            time=dist / ssp.speed_mps,
            length=dist,
            launch_angle=ang,
            arrival_angle=ang.copy(),
            turning_depth=np.full(dist.shape, np.nan),
            path=np.full(dist.shape, PathKind.DIRECT, dtype=np.int8),
        )
    raise NotImplementedError(f"eigenray for {type(ssp).__name__} not implemented yet")


def travel_time(ssp: SoundSpeedProfile, src: ArrayLike, dst: ArrayLike, *, reflections: str = "fallback") -> NDArray[np.float64]:
    """First-arrival travel time (s) from ``src`` to ``dst`` (..., 3); NaN where no path."""
    return eigenray(ssp, src, dst, reflections=reflections).time


def travel_time_gradient(ssp: SoundSpeedProfile, src: ArrayLike, dst: ArrayLike) -> NDArray[np.float64]:
    """d travel_time / d dst (s/m), shape (..., 3)."""
    s, d = _pairs(src, dst)
    if isinstance(ssp, Constant):
        diff = d - s
        dist = np.linalg.norm(diff, axis=-1, keepdims=True)
        return diff / (dist * ssp.speed_mps)
    raise NotImplementedError(f"travel_time_gradient for {type(ssp).__name__} not implemented yet")


def straight_line_time(ssp: SoundSpeedProfile, src: ArrayLike, dst: ArrayLike) -> NDArray[np.float64]:
    """Straight-ray approximation of the travel time (s) (Ramezani et al., eqs 23-24)."""
    s, d = _pairs(src, dst)
    if isinstance(ssp, Constant):
        return np.linalg.norm(d - s, axis=-1) / ssp.speed_mps
    raise NotImplementedError(f"straight_line_time for {type(ssp).__name__} not implemented yet")


def why_no_path(ssp: SoundSpeedProfile, src: ArrayLike, dst: ArrayLike) -> NDArray[np.str_]:
    """Reason per pair there is no direct eigenray ("" where there is one)."""
    s, d = _pairs(src, dst)
    return np.full(s.shape[:-1], "", dtype=object)
