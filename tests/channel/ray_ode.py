"""Independent ray-tracing oracle: numerical integration of the ray equations plus shooting.

Not used by the package; tests compare the closed forms (isogradient) and the layered solver
against it. It knows nothing of circles or Snell invariants: for any depth-dependent speed
c(z) (positive down) it integrates, in arc length s (so rays that turn in depth are fine),

    dr/ds = cos(theta),  dz/ds = sin(theta),  dtheta/ds = -cos(theta) c'(z) / c(z),  dt/ds = 1/c(z)

with ``scipy.integrate.solve_ivp`` (DOP853, rtol 1e-12), and finds the launch angle that hits
the receiver with ``scipy.optimize.brentq``. theta is the grazing angle from the horizontal,
positive down. ``c`` and ``dcdz`` are called with Python floats some 1e4 times per shot: make
them plain-Python fast (see :func:`piecewise_linear`).

For a piecewise-linear c (kinks in c'(z) at layer interfaces) pass ``interfaces``: the
integration stops exactly at every interface crossing (a terminal event) and restarts there, so
the high-order integrator never steps across a discontinuity of the right-hand side.

Error bounds. Every ray carries bounds on its own integration error, derived from RTOL/ATOL
and the steps the integrator actually took (so they hold for any scipy/numpy version or CPU,
whatever step sequence those produce). solve_ivp accepts a step when the RMS over the 4
components of err_j / (ATOL + RTOL max(|y_j|, |y_j new|)) is <= 1, so each component's local
error is <= 2 sc_j, sc_j = ATOL + RTOL max|y_j| (the terminal partial step and the dense-output
event points are counted as steps too). Propagated to the end of the ray, as first-order
perturbations of a weakly refracting ray (an angle error dtheta at arc length s_k tilts the rest
of the ray by dtheta over L - s_k; a position error moves it rigidly):

* ``normal_bound`` = sum_k 2 [hypot(sc_r, sc_z) + sc_theta (L - s_k)]: the distance between
  the computed end point and the exact ray's, across the ray (m). A depth miss at a fixed range
  is that distance over cos(arrival angle): near vertical incidence the depth miss is ill
  conditioned (amplified by 1 / cos theta) and must be compared in the normal direction;
* ``along_bound`` = sum_k 2 hypot(sc_r, sc_z): the same along the ray (m), i.e. the arc
  length error at the end;
* ``angle_bound`` = sum_k 2 sc_theta: the arrival angle error (rad);
* ``time_bound`` = sum_k 2 sc_t + along_bound / c_min: the travel-time error (s); a normal
  displacement changes the time (corrected for the depth miss) only to second order.

Measured (tests/channel): the actual errors are 3-100x below these bounds.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.integrate import quad, solve_ivp
from scipy.optimize import brentq, minimize_scalar

SpeedFn = Callable[[float], float]

RTOL = 1e-12
ATOL = 1e-12


def piecewise_linear(depths: Sequence[float], speeds: Sequence[float]) -> tuple[SpeedFn, SpeedFn, list[float]]:
    """(c, dc/dz, interior interfaces) of a piecewise-linear profile through (depths[i], speeds[i]).

    The end layers extend linearly beyond the first/last depth. Pure-Python scalar functions:
    a shot calls them ~2e4 times, so numpy scalar calls (~10x slower) would dominate the cost.
    """
    zs = [float(z) for z in depths]
    cs = [float(v) for v in speeds]
    gs = [(cs[i + 1] - cs[i]) / (zs[i + 1] - zs[i]) for i in range(len(zs) - 1)]
    last = len(gs) - 1

    def layer(z: float) -> int:
        return min(max(bisect.bisect_right(zs, z) - 1, 0), last)

    def c(z: float) -> float:
        i = layer(z)
        return cs[i] + gs[i] * (z - zs[i])

    def dcdz(z: float) -> float:
        return gs[layer(z)]

    return c, dcdz, zs[1:-1]


@dataclass(frozen=True)
class OdeRay:
    """One integrated ray from (0, z_src) to the vertical plane r = r_end."""

    time: float  #: s
    length: float  #: arc length, m
    launch_angle: float  #: rad, positive down
    arrival_angle: float  #: rad, positive down
    r_end: float  #: m
    z_end: float  #: m
    z_min: float  #: shallowest depth along the ray, m (brute force on the dense output)
    z_max: float  #: deepest depth along the ray, m
    reached: bool  #: False if the ray left ``z_limits`` (or hit c -> 0) before r_end
    normal_bound: float = 0.0  #: m, integration error across the ray at its end (see above)
    along_bound: float = 0.0  #: m, integration error along the ray (= arc length error)
    angle_bound: float = 0.0  #: rad, arrival angle error
    time_bound: float = 0.0  #: s, travel time error


class _ErrorSums:
    """Running sums of the per-step local error bounds of one ray (see the module docstring)."""

    def __init__(self) -> None:
        self.pos = self.th = self.th_s = self.t = 0.0
        self.c_min = math.inf

    def add(self, s: np.ndarray, y: np.ndarray, c: SpeedFn) -> None:
        """Steps between consecutive columns of ``y`` (4 x n) at arc lengths ``s``."""
        if s.size < 2:
            return
        sc = ATOL + RTOL * np.maximum(np.abs(y[:, :-1]), np.abs(y[:, 1:]))
        th = 2.0 * sc[2]
        self.pos += float(2.0 * np.hypot(sc[0], sc[1]).sum())
        self.th += float(th.sum())
        self.th_s += float((th * s[1:]).sum())
        self.t += float(2.0 * sc[3].sum())
        self.c_min = min(self.c_min, *(c(float(z)) for z in y[1]))

    def bounds(self, length: float) -> dict[str, float]:
        return {
            "normal_bound": self.pos + length * self.th - self.th_s,
            "along_bound": self.pos,
            "angle_bound": self.th,
            "time_bound": self.t + self.pos / self.c_min,
        }


def _rhs(c: SpeedFn, dcdz: SpeedFn) -> Callable[[float, np.ndarray], list[float]]:
    def f(s: float, y: np.ndarray) -> list[float]:
        _r, z, th, _t = y
        cz = c(z)
        ct = math.cos(th)
        return [ct, math.sin(th), -ct * dcdz(z) / cz, 1.0 / cz]

    return f


def _extrema(sol, s0: float, s1: float) -> tuple[float, float]:
    """Brute-force min/max depth of one integrated segment: dense sampling, then a bounded
    scalar refinement around the best sample (the dense output is a degree-7 interpolant)."""
    if s1 <= s0:
        z = float(sol(s0)[1])
        return z, z
    ss = np.linspace(s0, s1, 4001)
    zz = sol(ss)[1]
    out = []
    for sign in (1.0, -1.0):
        i = int(np.argmin(sign * zz))
        lo, hi = ss[max(i - 1, 0)], ss[min(i + 1, ss.size - 1)]
        best = sign * zz[i]
        if hi > lo:
            res = minimize_scalar(
                lambda s: sign * float(sol(s)[1]),
                bounds=(lo, hi),
                method="bounded",
                options={"xatol": 1e-9 * max(1.0, hi)},
            )
            best = min(best, float(res.fun))
        out.append(sign * best)
    return out[0], out[1]


def trace(
    c: SpeedFn,
    dcdz: SpeedFn,
    z_src: float,
    theta0: float,
    r_target: float,
    *,
    interfaces: Sequence[float] = (),
    z_limits: tuple[float, float] | None = None,
    c_floor: float = 1.0,
    extrema: bool = False,
    max_step: float = np.inf,
) -> OdeRay:
    """Integrate one ray launched at depth ``z_src`` (m) with angle ``theta0`` (rad) until r = r_target.

    The ray stops early (``reached=False``) when it leaves ``z_limits`` or c drops below
    ``c_floor`` (m/s). ``extrema=True`` also computes the brute-force min/max depth.
    ``max_step`` (m of arc) should be finite for layered profiles: a ray that dips across an
    interface and back within one step fires no crossing event and is bent with the wrong
    gradient (seen: a 4 cm dip below an interface over 4.5 km missed the target by 8.6 m).
    Such a dip has a turning point inside the step, so every turning point (sin theta = 0) is
    located too (a non-terminal event): where one lies past an interface not crossed, the
    segment is integrated again with shorter steps until the crossing is seen (seen: a 0.1 mm
    dip below 800 m inside a 25 m step, a 4.7 cm miss; even a 1e-9 m dip would move the
    range by mm, as the turning-layer range grows as the square root of the dip).
    """
    f = _rhs(c, dcdz)
    ifs = np.asarray(sorted(interfaces), dtype=float)
    y = np.array([0.0, float(z_src), float(theta0), 0.0])
    s = 0.0
    zmin = zmax = float(z_src)
    # arc length budget: a ray never needs more than a few times the range plus the depth span
    s_max = 20.0 * (r_target + 1.0) + 1e4
    just_crossed: tuple[int, float] | None = None
    err = _ErrorSums()
    step = max_step
    while True:
        events = []

        def hit_r(s_, y_):
            return y_[0] - r_target

        hit_r.terminal = True
        hit_r.direction = 1.0
        events.append(hit_r)

        def floor(s_, y_):
            return c(y_[1]) - c_floor

        floor.terminal = True
        floor.direction = -1.0
        events.append(floor)
        if z_limits is not None:

            def lo(s_, y_):
                return y_[1] - z_limits[0]

            def hi(s_, y_):
                return y_[1] - z_limits[1]

            lo.terminal = hi.terminal = True
            lo.direction, hi.direction = -1.0, 1.0
            events += [lo, hi]
        n_fixed = len(events)
        for k, zi in enumerate(ifs):

            def cross(s_, y_, zi=zi):
                return y_[1] - zi

            cross.terminal = True
            # right after crossing interface k, only a crossing back the other way can follow
            cross.direction = -just_crossed[1] if just_crossed and just_crossed[0] == k else 0.0
            events.append(cross)

        n_stop = len(events)
        if ifs.size:

            def turn(s_, y_):
                return math.sin(y_[2])

            turn.terminal = False  # only located: checked below, no restart
            events.append(turn)
        sol = solve_ivp(
            f, (s, s_max), y, method="DOP853", rtol=RTOL, atol=ATOL, events=events, dense_output=extrema, max_step=step
        )  # 3 extra stages per step: only when needed
        fired = [i for i, te in enumerate(sol.t_events[:n_stop]) if te.size]
        i = min(fired, key=lambda j: sol.t_events[j][0]) if sol.status == 1 and fired else -1
        if ifs.size and sol.t_events[-1].size:
            # every turning point of the segment must lie on the start's side of every interface
            side = np.sign(y[1] - ifs)
            slack = np.zeros(ifs.size)
            if just_crossed is not None:
                # the segment starts on this interface: a turn right after crossing it may
                # round to a few ulps on the other side
                side[just_crossed[0]] = just_crossed[1]
                slack[just_crossed[0]] = 1e-12 * max(1.0, abs(ifs[just_crossed[0]]))
            d = sol.y_events[-1][:, 1][:, None] - ifs[None, :]
            if np.any((np.sign(d) * side < 0.0) & (np.abs(d) > slack)):
                step = min(step, float(sol.t[-1]) - s) / 4.0
                if step < 1e-6:
                    raise RuntimeError("trace: cannot resolve an interface crossing at a turning point")
                continue
        step = max_step
        if extrema:
            lo_z, hi_z = _extrema(sol.sol, s, float(sol.t[-1]))
            zmin, zmax = min(zmin, lo_z), max(zmax, hi_z)
        if i < 0:
            y = sol.y[:, -1]
            return OdeRay(y[3], sol.t[-1], theta0, y[2], y[0], y[1], zmin, zmax, False)
        s = float(sol.t_events[i][0])
        y = sol.y_events[i][0].copy()
        # the steps up to the event; the event point (dense output) counts as one more step
        err.add(np.append(sol.t, s), np.column_stack([sol.y, y]), c)
        if i == 0:
            return OdeRay(y[3], s, theta0, y[2], y[0], y[1], zmin, zmax, True, **err.bounds(s))
        if i < n_fixed:
            return OdeRay(y[3], s, theta0, y[2], y[0], y[1], zmin, zmax, False, **err.bounds(s))
        k = i - n_fixed
        y[1] = ifs[k]  # snap onto the interface (the event root is within a few ulps)
        just_crossed = (k, 1.0 if math.sin(y[2]) > 0.0 else -1.0)


def _miss(ray: OdeRay, z_dst: float) -> float:
    """Signed depth miss at the target range; a continuous surrogate for rays that stopped early."""
    if ray.reached:
        return ray.z_end - z_dst
    # stopped early: it was heading away in depth, so count the missing range as extra depth
    sign = 1.0 if math.sin(ray.arrival_angle) > 0.0 else -1.0
    return ray.z_end - z_dst + sign * 1e3


def shoot(
    c: SpeedFn,
    dcdz: SpeedFn,
    src: Sequence[float],
    dst: Sequence[float],
    *,
    interfaces: Sequence[float] = (),
    z_limits: tuple[float, float] | None = None,
    bracket: tuple[float, float] | None = None,
    extrema: bool = False,
    max_step: float = np.inf,
) -> OdeRay:
    """Eigenray from ``src`` to ``dst`` (x, y, z in m) by shooting on the launch angle.

    Without ``bracket`` the launch angle is bracketed by stepping out from the chord's angle
    (fine for profiles with a single eigenray, e.g. isogradient); with several eigenrays pass a
    bracket (see :func:`fan`). The returned time is corrected to first order for the residual
    depth miss (dt/dz = sin(theta)/c at the receiver), which is below 1e-10 m anyway.
    """
    src = np.asarray(src, dtype=float)
    dst = np.asarray(dst, dtype=float)
    R = float(math.hypot(dst[0] - src[0], dst[1] - src[1]))
    z1, z2 = float(src[2]), float(dst[2])
    if R == 0.0:
        pts = [zi for zi in interfaces if min(z1, z2) < zi < max(z1, z2)]
        t, err = quad(
            lambda z: 1.0 / c(z), min(z1, z2), max(z1, z2), points=pts or None, epsabs=1e-14, epsrel=1e-13, limit=200
        )
        ang = math.copysign(math.pi / 2, z2 - z1)
        # exact straight ray: only the quadrature's error (its estimate, or what it was asked for)
        return OdeRay(
            t, abs(z2 - z1), ang, ang, 0.0, z2, min(z1, z2), max(z1, z2), True, time_bound=max(err, 1e-14 + 1e-13 * t)
        )

    def miss(th: float) -> float:
        return _miss(trace(c, dcdz, z1, th, R, interfaces=interfaces, z_limits=z_limits, max_step=max_step), z2)

    lim = math.pi / 2 - 1e-9
    if bracket is None:
        beta = math.atan2(z2 - z1, R)
        f0 = miss(beta)
        if f0 == 0.0:
            bracket = (beta, beta)
        else:
            step = 1e-2
            direction = -1.0 if f0 > 0.0 else 1.0
            lo = beta
            while True:
                hi = min(max(beta + direction * step, -lim), lim)
                fh = miss(hi)
                if fh == 0.0 or (fh > 0.0) != (f0 > 0.0):
                    break
                if abs(hi) >= lim:
                    raise RuntimeError("shoot: could not bracket the launch angle")
                lo, f0 = hi, fh
                step *= 2.0
            bracket = (min(lo, hi), max(lo, hi))
    if bracket[0] == bracket[1]:
        th = bracket[0]
    else:
        th = brentq(miss, bracket[0], bracket[1], xtol=1e-16, rtol=8.9e-16, maxiter=200)
    ray = trace(c, dcdz, z1, th, R, interfaces=interfaces, z_limits=z_limits, extrema=extrema, max_step=max_step)
    if not ray.reached:
        raise RuntimeError("shoot: converged launch angle does not reach the receiver")
    dt = math.sin(ray.arrival_angle) / c(ray.z_end) * (z2 - ray.z_end)
    return OdeRay(
        ray.time + dt,
        ray.length,
        th,
        ray.arrival_angle,
        ray.r_end,
        z2,
        ray.z_min,
        ray.z_max,
        True,
        ray.normal_bound,
        ray.along_bound,
        ray.angle_bound,
        ray.time_bound,
    )


def tolerances(ray: OdeRay) -> dict[str, float]:
    """How far an exact eigenray's quantities may be from this shot ray's (see the module
    docstring): shooting re-aims the launch to cancel the end point's error across the ray, at
    most ``normal_bound``, which turns the ray by ~normal_bound / L (launch and arrival) and
    changes its length and any depth along it by < normal_bound; the time is stationary under
    re-aiming (Fermat), so only ``time_bound`` enters it."""
    tilt = ray.normal_bound / ray.length if ray.length > 0.0 else 0.0
    return {
        "time": ray.time_bound,
        "launch": tilt,
        "arrival": ray.angle_bound + tilt,
        "length": ray.along_bound + ray.normal_bound,
        "position": ray.along_bound + ray.normal_bound,
    }


def fan(
    c: SpeedFn,
    dcdz: SpeedFn,
    src: Sequence[float],
    dst: Sequence[float],
    *,
    n: int = 181,
    interfaces: Sequence[float] = (),
    z_limits: tuple[float, float] | None = None,
    angle_range: tuple[float, float] = (-math.pi / 2 + 1e-6, math.pi / 2 - 1e-6),
    max_step: float = np.inf,
) -> list[OdeRay]:
    """All eigenrays found by scanning ``n`` launch angles and refining every sign change of the
    depth miss; sorted by travel time (the first is the first arrival). Brute force: slow."""
    src = np.asarray(src, dtype=float)
    dst = np.asarray(dst, dtype=float)
    R = float(math.hypot(dst[0] - src[0], dst[1] - src[1]))
    z1, z2 = float(src[2]), float(dst[2])
    ths = np.linspace(angle_range[0], angle_range[1], n)
    rays = [trace(c, dcdz, z1, th, R, interfaces=interfaces, z_limits=z_limits, max_step=max_step) for th in ths]
    out = []
    for k in range(n - 1):
        if not (rays[k].reached and rays[k + 1].reached):
            continue
        fa, fb = rays[k].z_end - z2, rays[k + 1].z_end - z2
        if fa == 0.0 or (fa > 0.0) != (fb > 0.0):
            out.append(
                shoot(
                    c,
                    dcdz,
                    src,
                    dst,
                    interfaces=interfaces,
                    z_limits=z_limits,
                    bracket=(float(ths[k]), float(ths[k + 1])),
                    max_step=max_step,
                )
            )
    return sorted(out, key=lambda r: r.time)
