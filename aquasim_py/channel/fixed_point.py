"""The moving receiver's arrival time: the fixed point t_a = t0 + T(p_src(t0), p_rx(t_a)).

Pure numpy, no SimPy. The channel (:mod:`.links`) iterates the fixed point on the receivers'
true trajectories; these functions give it a start that is usually already the answer: the
fixed point of the receivers' straight-line motion at t0, in closed form for a constant sound
speed (:func:`constant_moving_root`, with an acceleration correction,
:func:`accelerated_root`), else by secant steps seeded with the exact slope grad T . v
(:func:`linear_fixed_point`); and the straight rays of a constant profile without the ray
tracer's broadcasting (:func:`straight_rays`, :func:`straight_moving`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from . import isogradient
from .rays import Eigenray, PathKind
from .raytrace import Reflections, eigenray
from .ssp import Constant, Isogradient

if TYPE_CHECKING:  # pragma: no cover
    from .ssp import SoundSpeedProfile

__all__ = [
    "FIELDS",
    "FIXED_POINT_TOL_S",
    "MAX_ITER",
    "accelerated_root",
    "constant_moving_root",
    "constant_start",
    "direct_rays",
    "linear_fixed_point",
    "secant_fixed_point",
    "slope_along",
    "straight_moving",
    "straight_rays",
    "travel_time_fn",
]

#: fixed-point tolerance on the arrival time (s)
FIXED_POINT_TOL_S = 1e-10
#: iterations of a fixed point before it is declared not converging
MAX_ITER = 50
#: the fields of an Eigenray, and those that are floats
FIELDS = tuple(Eigenray.__dataclass_fields__)
_FLOAT_FIELDS = tuple(f for f in FIELDS if f != "path")


def linear_fixed_point(
    ssp: SoundSpeedProfile,
    refl: Reflections,
    p_src: NDArray[np.float64],
    p0: NDArray[np.float64],
    v: NDArray[np.float64],
    t_start: NDArray[np.float64],
    arrival_angle: NDArray[np.float64],
    path: NDArray[np.int8],
) -> NDArray[np.float64]:
    """Delay t (s) solving t = T(p_src, p0 + v t) for receivers at p0 (m, (k, 3)) moving in
    straight lines at v (m/s), given t_start = T(p_src, p0) and the arrival angle of that ray.

    Only the starting point of the exact iteration on the true trajectories (which decides
    the result), so it may be NaN / inexact where the straight line leaves the water.
    Constant profile: the closed-form root of |p0 + v t - p_src| = c t (no ray tracing).
    Other profiles: secant iteration on f(t) = t - T(p0 + v t), seeded with the exact slope
    dT/dt = grad T . v (the slowness vector at the receiver, Fermat), about 2 travel-time
    evaluations instead of the 4-5 of plain iteration (which contracts only by |v|/c per step).
    """
    if t_start.size == 0:
        return t_start
    if isinstance(ssp, Constant):
        t = constant_moving_root(ssp.speed_mps, p0 - p_src, v)
        if np.isfinite(t).all():
            return t
    slope = slope_along(ssp, p_src, p0, v, arrival_angle)
    return secant_fixed_point(travel_time_fn(ssp, refl, p_src, path), p0, v, t_start, slope)


def direct_rays(time: NDArray[np.float64], length: NDArray[np.float64], ang: NDArray[np.float64]) -> Eigenray:
    """Straight rays (constant profile) with delays ``time`` (s), lengths (m) and elevation
    ``ang`` (rad, launch = arrival); the arrival angle is its own array because the fixed point
    writes rows of each field."""
    return Eigenray(
        time=time,
        length=length,
        launch_angle=ang,
        arrival_angle=ang.copy(),
        turning_depth=np.full(length.shape, np.nan),
        path=np.full(length.shape, np.int8(PathKind.DIRECT)),
    )


def straight_rays(ssp: Constant, p_src: NDArray[np.float64]) -> Callable[[NDArray[np.float64]], Eigenray]:
    """``eigenray(ssp, p_src, dst)`` for a constant profile and one source, as a function of
    the receivers dst (k, 3): the same arithmetic as ``raytrace._constant_direct`` (so the same
    bits; a straight line is the first arrival in every ``reflections`` mode), without
    broadcasting the source to every receiver, and the source's own checks done once."""
    c = ssp.speed_mps
    bottom = ssp.bottom
    z_s = float(p_src[2])
    src_ok = z_s >= 0.0 and (bottom is None or z_s <= bottom) and bool(np.isfinite(p_src).all())
    none, direct = np.int8(PathKind.NONE), np.int8(PathKind.DIRECT)

    def rays(d: NDArray[np.float64]) -> Eigenray:
        diff = d - p_src
        dist = np.linalg.norm(diff, axis=-1)
        horiz = np.hypot(diff[..., 0], diff[..., 1])
        ang = np.arctan2(diff[..., 2], horiz)
        z = d[..., 2]
        ok = (z >= 0.0) & np.isfinite(d).all(axis=-1)
        if bottom is not None:
            ok &= z <= bottom
        if not src_ok:
            ok[...] = False
        bad = ~ok
        if not bad.any():  # the usual case: the np.where below would change nothing
            return direct_rays(dist / c, dist, ang)
        return Eigenray(
            time=np.where(bad, np.nan, dist / c),
            length=np.where(bad, np.nan, dist),
            launch_angle=np.where(bad, np.nan, ang),
            arrival_angle=np.where(bad, np.nan, ang),
            turning_depth=np.full(dist.shape, np.nan),
            path=np.where(bad, none, direct),
        )

    return rays


def straight_moving(
    ssp: Constant,
    p_src: NDArray[np.float64],
    p_rx: NDArray[np.float64],
    v: NDArray[np.float64],
    t0: float,
    positions_at: Callable[[NDArray[np.float64]], NDArray[np.float64]],
) -> Eigenray | None:
    """Constant profile, every receiver moving: the eigenrays to the receivers at their arrival
    instants, or None when anything is unusual (a point out of the water, a receiver faster
    than c/2, a step of the exact iteration larger than the tolerance: the general fixed point
    in ``links.LinkModel.arrivals`` then runs, with the same result).

    The same operations, in the same order, as the general path's usual course (the
    closed-form start of ``constant_start``, one exact step, the ray of ``straight_rays``),
    so the same bits, with the per-row checks done as a few reductions over the whole
    neighbourhood instead of masks and gathers: this runs once per transmission.
    positions_at(times): the receivers' true positions (k, 3) at true times (k,)."""
    c = ssp.speed_mps
    bottom = ssp.bottom
    z_s = float(p_src[2])
    if not (z_s >= 0.0 and (bottom is None or z_s <= bottom) and math.isfinite(float(p_src.sum()))):
        return None
    z = p_rx[:, 2]
    if not (z.min() >= 0.0 and (bottom is None or z.max() <= bottom)):  # NaN fails too
        return None
    t = constant_moving_root(c, p_rx - p_src, v)  # NaN / inf for a non-finite receiver or speed
    if not math.isfinite(float(t.sum())):
        return None
    p_new = positions_at(t0 + t)
    diff = p_new - p_src
    dist = np.sqrt(np.add.reduce(diff * diff, axis=-1))  # np.linalg.norm(diff, axis=-1), same bits
    z = p_new[:, 2]
    if not (math.isfinite(float(dist.sum())) and z.min() >= 0.0 and (bottom is None or z.max() <= bottom)):
        return None
    time = dist / c
    if not bool((np.abs(time - t) <= FIXED_POINT_TOL_S).all()):
        return None
    return direct_rays(time, dist, np.arctan2(diff[:, 2], np.hypot(diff[:, 0], diff[:, 1])))


def constant_start(
    ssp: Constant,
    refl: Reflections,
    p_src: NDArray[np.float64],
    p_rx: NDArray[np.float64],
    moving: NDArray[np.bool_],
    v: NDArray[np.float64],
    acc: NDArray[np.float64] | None = None,
) -> tuple[dict[str, NDArray[Any]], NDArray[np.intp]] | None:
    """Constant profile: the eigenray fields of the candidates before the exact iteration, and
    the moving receivers to iterate (``active``), without tracing rays to their send-time
    positions: a straight ray exists iff both ends are in the water (the ray tracer's own
    test), and the start delay is the closed-form straight-line root. Only the other
    candidates (static, or out of the water) are traced. None if the closed form fails."""
    z_s = float(p_src[2])
    z = p_rx[:, 2]
    inside = (z >= 0.0) & np.isfinite(p_rx).all(axis=1)
    ok_src = z_s >= 0.0 and bool(np.isfinite(p_src).all())
    if ssp.bottom is not None:
        inside &= z <= ssp.bottom
        ok_src = ok_src and z_s <= ssp.bottom
    act = moving & inside if ok_src else np.zeros_like(moving)
    active = np.flatnonzero(act)
    t = constant_moving_root(ssp.speed_mps, p_rx[active] - p_src, v[active])
    if not np.isfinite(t).all():
        return None
    if acc is not None:
        t = accelerated_root(ssp.speed_mps, p_rx[active] - p_src, v[active], acc[active], t)
    n = len(p_rx)
    if active.size == n:  # every row is overwritten by the first exact step, which reads only time
        return {"time": t}, active
    # every row is filled below: traced (rest) or overwritten by the first exact step (active)
    fields: dict[str, NDArray[Any]] = {f: np.empty(n) for f in _FLOAT_FIELDS}
    fields["path"] = np.empty(n, dtype=np.int8)
    rest = np.flatnonzero(~act)
    if rest.size:
        r = eigenray(ssp, p_src, p_rx[rest], reflections=refl)
        for f in fields:
            fields[f][rest] = getattr(r, f)
    fields["time"][active] = t  # the start delay: the only active field read before it is overwritten
    return fields, active


def constant_moving_root(c: float, d: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    """Positive root t (s) of |d + v t| = c t (receiver offset d (m) from the source, velocity v).

    (c^2 - |v|^2) t^2 - 2 (d.v) t - |d|^2 = 0, t = (d.v + sqrt((d.v)^2 + (c^2 - |v|^2) |d|^2))
    / (c^2 - |v|^2). With |v| <= c/2 the sum never cancels (|d.v| <= |v||d| is at most half the
    root), so this is accurate to a few ulps; NaN for faster receivers (the caller iterates).
    """
    dv = np.einsum("ij,ij->i", d, v)
    vv = np.einsum("ij,ij->i", v, v)
    if not bool((vv <= 0.25 * c * c).all()):
        return np.full(len(d), np.nan)
    a = c * c - vv
    return (dv + np.sqrt(dv * dv + a * np.einsum("ij,ij->i", d, d))) / a


def accelerated_root(
    c: float, d: NDArray[np.float64], v: NDArray[np.float64], a: NDArray[np.float64], t: NDArray[np.float64]
) -> NDArray[np.float64]:
    """One Newton step from the straight-line root t (s) towards the root of
    |d + v t + a t^2 / 2| = c t (offset d in m, velocity v in m/s, acceleration a in m/s^2),
    for the rows with a != 0; t where the step fails. The straight-line root misses by about
    |a| t^2 / (2 c) (1e-9 s for a current's 1e-3 m/s^2 over 80 m), more than the fixed point's
    tolerance, so the exact iteration would need a second step; from this start it needs one."""
    use = np.flatnonzero((a != 0.0).any(axis=1))
    if not use.size:
        return t
    tu, du, vu, au = t[use], d[use], v[use], a[use]
    q = du + vu * tu[:, None] + (0.5 * tu * tu)[:, None] * au
    dq = vu + au * tu[:, None]
    nq = np.sqrt(np.einsum("ij,ij->i", q, q))
    with np.errstate(invalid="ignore", divide="ignore"):
        t_new = tu - (nq - c * tu) / (np.einsum("ij,ij->i", q, dq) / nq - c)
    out = t.copy()
    # a correction is tiny (|a| t^2 / 2c); a large one comes from a poor estimate (e.g. a
    # wall bounce since the last one) and is not taken
    out[use] = np.where(np.abs(t_new - tu) <= 1e-3 * tu, t_new, tu)
    return out


def slope_along(
    ssp: SoundSpeedProfile,
    p_src: NDArray[np.float64],
    p0: NDArray[np.float64],
    v: NDArray[np.float64],
    arrival_angle: NDArray[np.float64],
) -> NDArray[np.float64]:
    """d/dt T(p_src, p0 + v t) at t = 0: grad T . v, with grad T the slowness vector at the
    receiver, (cos th e_h + sin th e_z) / c(z) (th the arrival grazing angle, positive down,
    e_h the horizontal direction of travel). 0 where unknown (plain iteration then)."""
    dx = p0[:, 0] - p_src[0]
    dy = p0[:, 1] - p_src[1]
    r = np.hypot(dx, dy)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.cos(arrival_angle)
        vh = np.where(r > 0.0, (dx * v[:, 0] + dy * v[:, 1]) / r, 0.0)
        k = (cos * vh + np.sin(arrival_angle) * v[:, 2]) / ssp.speed(p0[:, 2])
    return np.where(np.isfinite(k) & (np.abs(k) < 0.5), k, 0.0)


def travel_time_fn(
    ssp: SoundSpeedProfile, refl: Reflections, p_src: NDArray[np.float64], path: NDArray[np.int8]
) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """The cheapest exact first-arrival time (s) from ``p_src`` to receivers (k, 3) whose current
    arrival has kind ``path``: the isogradient closed form directly when every arrival is the
    direct arc and reflections cannot be earlier, else the full eigenray."""
    if isinstance(ssp, Isogradient) and refl in ("none", "fallback") and bool((path == PathKind.DIRECT).all()):
        b, a, bottom = ssp.surface_speed, ssp.gradient, ssp.bottom
        return lambda dst: isogradient.travel_time(b, a, p_src, dst, bottom=bottom)
    return lambda dst: eigenray(ssp, p_src, dst, reflections=refl).time


def secant_fixed_point(
    travel: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    p0: NDArray[np.float64],
    v: NDArray[np.float64],
    t_start: NDArray[np.float64],
    slope: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Fixed point of t = G(t) = travel(p0 + v t) by secant steps on t - G(t), vectorized.

    The first secant uses the known point (0, t_start) and ``slope`` = G'(0); later ones the
    last two evaluations. A receiver stops when a step moves t by <= FIXED_POINT_TOL_S / 10
    (secant convergence is superlinear, so the remaining error is far smaller), or when G is
    NaN (the straight line leaves the water: t is kept and the exact iteration decides).
    """
    out = t_start / (1.0 - slope)
    idx = np.arange(t_start.size)
    t = out.copy()
    x_prev = np.zeros_like(t)
    y_prev = t_start.copy()
    s = slope.copy()
    for _ in range(MAX_ITER):
        y = travel(p0[idx] + v[idx] * t[:, None])
        ok = np.isfinite(y)
        with np.errstate(invalid="ignore", divide="ignore"):
            s_new = (y - y_prev) / (t - x_prev)
            s = np.where(ok & np.isfinite(s_new), s_new, s)
            t_new = np.where(ok, (y - s * t) / (1.0 - s), t)
        out[idx] = t_new
        go = ok & (np.abs(t_new - t) > 0.1 * FIXED_POINT_TOL_S)
        if not go.any():
            break
        idx, x_prev, y_prev, s, t = idx[go], t[go], y[go], s[go], t_new[go]
    return out
