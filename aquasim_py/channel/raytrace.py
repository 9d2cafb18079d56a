"""Public eigenray API, for any sound-speed profile (dispatch to the closed forms or the
layered solver). See docs/internals.md for the contract.

* :class:`~.ssp.Constant`: straight lines (t = distance / c).
* :class:`~.ssp.Isogradient`: the closed forms of :mod:`.isogradient` (Ramezani et al.,
  eqs 1-22) for the direct arc; its reflected arrivals come from the layered solver on the
  one-layer stack (mirroring the profile about a boundary makes it two-layered).
* everything else (:class:`~.ssp.Layered`, :class:`~.ssp.Munk`, CTD casts): the layered
  solver of :mod:`.layered` on ``ssp.to_layered()``.

``reflections`` (for every profile): ``"none"`` (direct path only), ``"fallback"`` (the first
surface- or bottom-reflected arrival where there is no direct path), ``"all"`` (the earliest
of direct and reflected arrivals). ``Eigenray.path`` tells which path was used.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import isogradient, layered
from .rays import Eigenray, PathKind
from .ssp import Constant, Isogradient, SoundSpeedProfile

__all__ = [
    "eigenray",
    "reflected_eigenray",
    "straight_line_time",
    "travel_time",
    "travel_time_gradient",
    "why_no_path",
]

Reflections = Literal["none", "fallback", "all"]


def _pairs(src: ArrayLike, dst: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    s = np.asarray(src, dtype=float)
    d = np.asarray(dst, dtype=float)
    if s.shape[-1:] != (3,) or d.shape[-1:] != (3,):
        raise ValueError("src and dst must have a last axis of length 3 (x, y, z)")
    s, d = np.broadcast_arrays(s, d)
    return s, d


def _check_mode(reflections: str) -> None:
    if reflections not in ("none", "fallback", "all"):
        raise ValueError(f"reflections must be 'none', 'fallback' or 'all', got {reflections!r}")


def _outside(ssp: SoundSpeedProfile, s: NDArray[np.float64], d: NDArray[np.float64]) -> NDArray[np.bool_]:
    z = np.stack([s[..., 2], d[..., 2]])
    # asarray: for a single pair the reductions give a numpy bool scalar; keep it a 0-d array
    bad = np.asarray(~(z >= 0.0).all(axis=0))
    if ssp.bottom is not None:
        bad |= (z > ssp.bottom).any(axis=0)
    return bad | ~(np.isfinite(s).all(axis=-1) & np.isfinite(d).all(axis=-1))


def _constant_direct(ssp: Constant, s: NDArray[np.float64], d: NDArray[np.float64]) -> Eigenray:
    diff = d - s
    dist = np.linalg.norm(diff, axis=-1)
    horiz = np.hypot(diff[..., 0], diff[..., 1])
    ang = np.arctan2(diff[..., 2], horiz)
    bad = _outside(ssp, s, d)
    nan = np.nan
    return Eigenray(
        time=np.where(bad, nan, dist / ssp.speed_mps),
        length=np.where(bad, nan, dist),
        launch_angle=np.where(bad, nan, ang),
        arrival_angle=np.where(bad, nan, ang),
        turning_depth=np.full(dist.shape, nan),
        path=np.where(bad, np.int8(PathKind.NONE), np.int8(PathKind.DIRECT)).astype(np.int8),
    )


def reflected_eigenray(
    ssp: SoundSpeedProfile, src: ArrayLike, dst: ArrayLike, boundary: Literal["surface", "bottom"]
) -> Eigenray:
    """First arrival with one reflection off ``boundary`` ("surface" or "bottom"): the direct
    eigenray of the profile mirrored about that boundary, to the receiver's image."""
    s, d = _pairs(src, dst)
    return layered.reflected_eigenray(ssp.to_layered(), s, d, boundary)


def eigenray(
    ssp: SoundSpeedProfile, src: ArrayLike, dst: ArrayLike, *, reflections: Reflections = "fallback"
) -> Eigenray:
    """First-arrival eigenray from ``src`` to ``dst`` (..., 3; x, y, depth in m, broadcast).

    Returns an :class:`Eigenray` of arrays of the links' broadcast shape: time (s), arc length
    (m; Ramezani et al. 2013, eq 19), launch and arrival grazing angles (rad, positive down),
    turning depth (m, NaN if the ray does not turn; eqs 21-22) and ``path``
    (:class:`PathKind`: direct, or the surface- or bottom-reflected arrival that
    ``reflections`` allows). NaN and ``PathKind.NONE`` where there is no path.

    Examples:
        In an isogradient profile (c = 1500 m/s + 0.017 s^-1 z) a ray from 10 m down to 190 m
        leaves steeper than it arrives: it bends towards the slower, shallower water.

        >>> import numpy as np
        >>> from aquasim_py.channel import Isogradient, PathKind, eigenray
        >>> ray = eigenray(Isogradient(1500.0, 0.017), [0.0, 0.0, 10.0], [3000.0, 0.0, 190.0])
        >>> round(float(ray.time), 6), round(float(ray.length), 3)  # s, m
        (2.001233, 3005.54)
        >>> np.degrees([ray.launch_angle, ray.arrival_angle]).round(3)  # down from horizontal
        array([4.406, 2.461])
        >>> PathKind(int(ray.path)).name
        'DIRECT'
    """
    _check_mode(reflections)
    s, d = _pairs(src, dst)
    if isinstance(ssp, Constant):
        direct = _constant_direct(ssp, s, d)
    elif isinstance(ssp, Isogradient):
        direct = isogradient.eigenray(ssp.surface_speed, ssp.gradient, s, d, bottom=ssp.bottom)
    else:
        return layered.eigenray(ssp.to_layered(), s, d, reflections=reflections)
    if reflections == "none":
        return direct
    need = np.ones(direct.time.shape, bool) if reflections == "all" else np.isnan(direct.time)
    # Constant: the straight line is never later than a reflected path, and always exists
    if isinstance(ssp, Constant) or not need.any():
        return direct
    parts: list[tuple[int, Eigenray]] = [(PathKind.DIRECT, direct)]
    lay = ssp.to_layered()
    boundaries: tuple[tuple[PathKind, Literal["surface", "bottom"]], ...] = (
        (PathKind.SURFACE, "surface"),
        (PathKind.BOTTOM, "bottom"),
    )
    for kind, name in boundaries:
        if name == "bottom" and ssp.bottom is None:
            continue
        r = layered.reflected_eigenray(lay, s[need], d[need], name)
        full = {
            f: np.full(need.shape, np.nan) for f in ("time", "length", "launch_angle", "arrival_angle", "turning_depth")
        }
        for f in full:
            full[f][need] = getattr(r, f)
        path = np.full(need.shape, np.int8(PathKind.NONE), dtype=np.int8)
        path[need] = r.path
        parts.append((kind, Eigenray(path=path, **full)))
    return layered.combine_arrivals(parts, reflections)


def travel_time(
    ssp: SoundSpeedProfile, src: ArrayLike, dst: ArrayLike, *, reflections: Reflections = "fallback"
) -> NDArray[np.float64]:
    """First-arrival travel time (s) from ``src`` to ``dst`` (..., 3; x, y, depth in m,
    broadcast); NaN where there is no path. ``reflections``: as for :func:`eigenray`.

    Examples:
        A straight line at 1500 m/s, then the same link through an isogradient profile: the
        bent ray reaches faster water and arrives 2.4 ms earlier.

        >>> from aquasim_py.channel import Constant, Isogradient, travel_time
        >>> src, dst = [0.0, 0.0, 10.0], [3000.0, 0.0, 190.0]
        >>> round(float(travel_time(Constant(1500.0), src, dst)), 9)  # |dst - src| / c
        2.003596766
        >>> round(float(travel_time(Isogradient(1500.0, 0.017), src, dst)), 9)
        2.001233119

        Arrays of links broadcast: one source to two receivers.

        >>> travel_time(Isogradient(1500.0, 0.017), src, [[1000.0, 0.0, 50.0], [2000.0, 0.0, 100.0]]).round(6)
        array([0.666969, 1.333823])
    """
    _check_mode(reflections)
    s, d = _pairs(src, dst)
    if isinstance(ssp, Constant):
        return _constant_direct(ssp, s, d).time
    if isinstance(ssp, Isogradient) and reflections == "none":
        return isogradient.travel_time(ssp.surface_speed, ssp.gradient, s, d, bottom=ssp.bottom)
    return eigenray(ssp, s, d, reflections=reflections).time


def travel_time_gradient(
    ssp: SoundSpeedProfile, src: ArrayLike, dst: ArrayLike, *, reflections: Reflections = "fallback"
) -> NDArray[np.float64]:
    """d travel_time / d dst (s/m), shape (..., 3); NaN where no path.

    Isogradient direct paths: the exact derivative of eq 13 (eqs 15-18). Every other arrival:
    the slowness vector at the receiver, (cos th_R e_h + sin th_R e_z) / c(z_R), which is the
    exact gradient of the travel time of any eigenray (Fermat: the path is stationary, so
    only the end point moves)."""
    _check_mode(reflections)
    s, d = _pairs(src, dst)
    if isinstance(ssp, Constant):
        diff = d - s
        dist = np.linalg.norm(diff, axis=-1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            g = np.where(dist > 0.0, diff / (dist * ssp.speed_mps), 0.0)
        return np.where(_outside(ssp, s, d)[..., None], np.nan, g)
    if isinstance(ssp, Isogradient):
        g = isogradient.travel_time_gradient(ssp.surface_speed, ssp.gradient, s, d, bottom=ssp.bottom)
        if reflections == "none":
            return g
        ray = eigenray(ssp, s, d, reflections=reflections)
        refl = (ray.path != PathKind.DIRECT)[..., None]
        return np.where(refl, layered.slowness_gradient(ssp, s, d, ray), g)
    ray = eigenray(ssp, s, d, reflections=reflections)
    return layered.slowness_gradient(ssp.to_layered(), s, d, ray)


def straight_line_time(ssp: SoundSpeedProfile, src: ArrayLike, dst: ArrayLike) -> NDArray[np.float64]:
    """Straight-ray approximation of the travel time (s): the line integral of 1/c along the
    chord, distance times the mean slowness over the depth interval (Ramezani et al.,
    eqs 23-24; closed form for Isogradient, layer by layer otherwise)."""
    s, d = _pairs(src, dst)
    if isinstance(ssp, Constant):
        return np.linalg.norm(d - s, axis=-1) / ssp.speed_mps
    if isinstance(ssp, Isogradient):
        return isogradient.straight_line_time(ssp.surface_speed, ssp.gradient, s, d)
    return layered.straight_line_time(ssp.to_layered(), s, d)


def why_no_path(ssp: SoundSpeedProfile, src: ArrayLike, dst: ArrayLike) -> NDArray[np.object_]:
    """Reason per pair there is no direct eigenray ("" where there is one): a point outside
    the water column, a ray that would leave the water at the surface / bottom (a reflected
    path exists), or a shadow zone."""
    s, d = _pairs(src, dst)
    out = np.full(s.shape[:-1], "", dtype=object)
    if isinstance(ssp, Constant):
        out[_outside(ssp, s, d)] = layered.REASON_OUTSIDE
        return out
    if isinstance(ssp, Isogradient):
        none = np.isnan(isogradient.travel_time(ssp.surface_speed, ssp.gradient, s, d, bottom=ssp.bottom))
        if none.any():
            out[none] = layered.why_no_path(ssp.to_layered(), s[none], d[none], assume_no_direct=True)
        return out
    return layered.why_no_path(ssp.to_layered(), s, d)
