"""Layered eigenray solver against independent references.

Oracle: the ray equations integrated with solve_ivp (it knows no circles and no Snell
invariants): ``trace`` below for the per-pair checks, tests/channel/ray_ode.py (shooting with
brentq, launch fans) for the rest. The default run traces, for every pair, the ray launched at
the solver's launch angle, checks that it lands on the receiver (depth miss < 1e-6 m) and
compares its travel time (corrected to first order for the tiny depth miss) with the
solver's; ``-m slow`` adds more pairs and a launch fan over all angles (is the returned
arrival really the first one, and is there really no direct ray where the solver says so?).
"""

from __future__ import annotations

import bisect
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from aquasim_py.channel import Constant, Isogradient, Layered, PathKind, isogradient, layered

sys.path.insert(0, str(Path(__file__).parent))
import ray_ode

BOTTOM = 1200.0
# monotone: speed grows with depth, the gradient changing from layer to layer
MONO = Layered(
    [0, 40, 100, 180, 260, 380, 500, 650, 800, 1000, 1200],
    [1480, 1483, 1486, 1487.5, 1490, 1493, 1494, 1497, 1501, 1504, 1508],
    bottom=BOTTOM,
)
# sound channel: minimum (axis) at 300 m
CHANNEL = Layered(
    [0, 50, 120, 200, 300, 420, 550, 700, 850, 1000, 1200],
    1500.0 + np.array([0, -5, -12, -20, -24, -20, -14, -8, -2, 4, 8.0]),
    bottom=BOTTOM,
)


class Oracle:
    """Pure-python c(z), c'(z) of a piecewise-linear profile for ray_ode (fast scalar calls)."""

    def __init__(self, prof: Layered, mirror: bool = False) -> None:
        self.z = prof.depths.tolist()
        self.c = prof.speeds.tolist()
        self.mirror = mirror  # c(|y|): the profile unfolded about the surface
        self.interfaces = [z for z in self.z[1:] if z < BOTTOM]
        if mirror:
            self.interfaces = sorted([-z for z in self.interfaces] + [0.0] + self.interfaces)

    def _k(self, z: float) -> int:
        return min(max(bisect.bisect_right(self.z, z) - 1, 0), len(self.z) - 2)

    def speed(self, y: float) -> float:
        z = abs(y) if self.mirror else y
        k = self._k(z)
        return self.c[k] + (self.c[k + 1] - self.c[k]) / (self.z[k + 1] - self.z[k]) * (z - self.z[k])

    def dspeed(self, y: float) -> float:
        z = abs(y) if self.mirror else y
        k = self._k(z)
        g = (self.c[k + 1] - self.c[k]) / (self.z[k + 1] - self.z[k])
        return -g if (self.mirror and y < 0.0) else g


def random_pairs(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Pairs 10 m to 5 km apart horizontally, depths 0-1000 m, random bearings."""
    rng = np.random.default_rng(seed)
    r = rng.uniform(10.0, 5000.0, n)
    b = rng.uniform(0.0, 2 * np.pi, n)
    src = np.column_stack([rng.uniform(-100, 100, n), rng.uniform(-100, 100, n), rng.uniform(0, 1000, n)])
    dst = src + np.column_stack([r * np.cos(b), r * np.sin(b), np.zeros(n)])
    dst[:, 2] = rng.uniform(0, 1000, n)
    return src, dst


def trace(orc: Oracle, z0: float, theta0: float, R: float, z_lim, max_step: float = 25.0) -> tuple[float, float, float]:
    """(depth, time, arrival angle) at range R of the ray launched at ``theta0`` from depth
    ``z0``: solve_ivp (DOP853, rtol 1e-12) on dx/ds = cos th, dz/ds = sin th,
    dth/ds = -cos th c'(z) / c(z), dt/ds = 1 / c(z), restarted at every interface crossing.

    Like ray_ode.trace, but with ``max_step``: a ray that dips across an interface and back
    inside one step (a turning point a few cm past it) leaves no sign change of the event
    function at the step ends, and ray_ode.trace then bends it with the wrong gradient
    (seen: MONO, 368.93 m -> 295.43 m over 4485.20 m, turning 4 cm below 380 m, misses by 8.6 m).
    """

    def rhs(s_, y):
        c = orc.speed(y[1])
        ct = math.cos(y[2])
        return [ct, math.sin(y[2]), -ct * orc.dspeed(y[1]) / c, 1.0 / c]

    def hit_r(s_, y):
        return y[0] - R

    def leave_top(s_, y):
        return y[1] - z_lim[0]

    def leave_bottom(s_, y):
        return y[1] - z_lim[1]

    hit_r.terminal = leave_top.terminal = leave_bottom.terminal = True
    hit_r.direction, leave_top.direction, leave_bottom.direction = 1.0, -1.0, 1.0
    y = np.array([0.0, z0, theta0, 0.0])
    s, last = 0.0, None
    while True:
        cross = []
        for k, zk in enumerate(orc.interfaces):

            def ev(s_, y_, zk=zk):
                return y_[1] - zk

            ev.terminal = True
            # just restarted on interface k: only the crossing back can come next
            ev.direction = 0.0 if last is None or last[0] != k else -last[1]
            cross.append(ev)
        sol = solve_ivp(
            rhs,
            (s, s + 10.0 * R + 1e4),
            y,
            method="DOP853",
            rtol=1e-12,
            atol=1e-12,
            max_step=max_step,
            events=[hit_r, leave_top, leave_bottom] + cross,
        )
        fired = [i for i, te in enumerate(sol.t_events) if te.size]
        assert sol.status == 1 and fired, "ray did not reach the receiver range"
        i = min(fired, key=lambda j: sol.t_events[j][0])
        s, y = float(sol.t_events[i][0]), sol.y_events[i][0].copy()
        if i == 0:
            return y[1], y[3], y[2]
        assert i >= 3, "the ray at the solver's launch angle leaves the water"
        k = i - 3
        y[1] = orc.interfaces[k]
        last = (k, 1.0 if math.sin(y[2]) > 0.0 else -1.0)


def shot_check(orc: Oracle, z_src: float, z_dst: float, R: float, launch: float, z_lim) -> tuple[float, float]:
    """Trace the ray launched at ``launch``; return (depth miss at range R, corrected time)."""
    z_end, t, ang = trace(orc, z_src, launch, R, z_lim)
    miss = z_end - z_dst
    # t(R, z) = t_ray + (dt/dz) dz with dt/dz = sin(theta)/c at the arrival (first order)
    return miss, t - math.sin(ang) / orc.speed(z_end) * miss


def check_against_oracle(prof: Layered, n: int, seed: int) -> None:
    src, dst = random_pairs(n, seed=seed)
    ray = layered.eigenray(prof, src, dst, reflections="none")
    ok = ray.path == PathKind.DIRECT
    assert ok.sum() >= 0.9 * len(src)  # most random pairs have a direct path (the rest: see test below)
    orc = Oracle(prof)
    R = np.hypot(*(dst - src)[:, :2].T)
    worst_t, worst_z = 0.0, 0.0
    for i in np.flatnonzero(ok):
        miss, t = shot_check(orc, src[i, 2], dst[i, 2], R[i], float(ray.launch_angle[i]), (0.0, BOTTOM))
        worst_z = max(worst_z, abs(miss))
        worst_t = max(worst_t, abs(t - ray.time[i]))
    assert worst_z < 1e-6
    assert worst_t < 1e-7


@pytest.mark.parametrize("prof", [MONO, CHANNEL], ids=["monotone", "channel"])
def test_matches_ode_oracle(prof: Layered) -> None:
    check_against_oracle(prof, 100, seed=11)  # 2 profiles: 200 pairs


@pytest.mark.slow
@pytest.mark.parametrize("prof", [MONO, CHANNEL], ids=["monotone", "channel"])
def test_matches_ode_oracle_large(prof: Layered) -> None:
    check_against_oracle(prof, 500, seed=12)


@pytest.mark.slow
@pytest.mark.parametrize("prof", [MONO, CHANNEL], ids=["monotone", "channel"])
def test_first_arrival_against_launch_fan(prof: Layered) -> None:
    """Brute force: every eigenray from a fan of launch angles, refined by brentq shooting.

    The fan can miss an eigenray whose launch window is narrower than its spacing (so a
    solver arrival the fan did not see is checked by shooting it), but it must find no
    arrival earlier than the solver's, and none at all where the solver says there is none."""
    src, dst = random_pairs(40, seed=5)
    ray = layered.eigenray(prof, src, dst, reflections="none")
    orc = Oracle(prof)
    R = np.hypot(*(dst - src)[:, :2].T)
    for i in range(len(src)):
        rays = ray_ode.fan(
            orc.speed,
            orc.dspeed,
            src[i],
            dst[i],
            n=121,
            interfaces=orc.interfaces,
            z_limits=(0.0, BOTTOM),
            max_step=25.0,
        )
        if ray.path[i] == PathKind.NONE:
            assert not rays
            continue
        miss, t = shot_check(orc, src[i, 2], dst[i, 2], R[i], float(ray.launch_angle[i]), (0.0, BOTTOM))
        assert abs(miss) < 1e-6 and abs(t - ray.time[i]) < 1e-7
        if rays:
            assert ray.time[i] <= rays[0].time + 1e-7


def test_one_layer_equals_isogradient() -> None:
    src, dst = random_pairs(2000, seed=3)
    for b, a, bottom in ((1480.0, 0.1, None), (1520.0, -0.05, 1000.0), (1500.0, 1e-10, None), (1500.0, 0.0, 2000.0)):
        lay = Isogradient(b, a, bottom=bottom).to_layered()
        t_lay = layered.travel_time(lay, src, dst, reflections="none")
        t_iso = isogradient.travel_time(b, a, src, dst, bottom=bottom)
        assert np.array_equal(np.isnan(t_lay), np.isnan(t_iso))
        np.testing.assert_allclose(t_lay, t_iso, rtol=1e-12, atol=0)


def test_special_cases() -> None:
    # vertical pair: integral of dz / c, exact for a layered profile (log of the speed ratio)
    t = layered.travel_time(MONO, [0, 0, 10.0], [0, 0, 900.0])
    z = MONO.depths
    from scipy.integrate import quad

    ref = quad(lambda zz: 1.0 / MONO.speed(zz), 10.0, 900.0, points=z[1:-1], epsabs=1e-15, epsrel=1e-13, limit=200)[0]
    assert abs(t - ref) < 1e-13
    # coincident points
    assert layered.travel_time(CHANNEL, [5, 5, 300.0], [5, 5, 300.0]) == 0.0
    # equal depths in a constant-speed layer: a horizontal line
    flat = Layered([0, 100, 200], [1500, 1500, 1510])
    assert layered.travel_time(flat, [0, 0, 50.0], [3000, 0, 50.0]) == pytest.approx(2.0, rel=1e-15)
    # broadcasting: (4, 1, 3) x (5, 3) -> (4, 5)
    src, dst = random_pairs(5, seed=1)
    out = layered.travel_time(CHANNEL, src[:4, None, :], dst)
    assert out.shape == (4, 5)


def test_turning_rays_and_angles_against_oracle() -> None:
    """Pairs chosen to need a turning point (both near the channel axis, far apart)."""
    orc = Oracle(CHANNEL)
    src = np.array([[0, 0, 290.0], [0, 0, 330.0], [0, 0, 150.0], [0, 0, 600.0]])
    dst = np.array([[4000, 0, 310.0], [4500, 0, 303.0], [3000, 0, 160.0], [3000, 0, 520.0]])
    ray = layered.eigenray(CHANNEL, src, dst, reflections="none")
    assert np.all(ray.path == PathKind.DIRECT)
    assert np.isfinite(ray.turning_depth).sum() >= 3
    for i in range(len(src)):
        r = ray_ode.shoot(
            orc.speed,
            orc.dspeed,
            src[i],
            dst[i],
            interfaces=orc.interfaces,
            z_limits=(0.0, BOTTOM),
            bracket=(ray.launch_angle[i] - 1e-6, ray.launch_angle[i] + 1e-6),
            extrema=bool(np.isfinite(ray.turning_depth[i])),
            max_step=25.0,
        )
        assert abs(r.time - ray.time[i]) < 1e-9
        assert abs(r.arrival_angle - ray.arrival_angle[i]) < 1e-7
        assert abs(r.length - ray.length[i]) < 1e-5
        if np.isfinite(ray.turning_depth[i]):
            turn = r.z_min if ray.turning_depth[i] < min(src[i, 2], dst[i, 2]) else r.z_max
            assert abs(turn - ray.turning_depth[i]) < 1e-4


# ---------------------------------------------------------------- properties

depth = st.floats(0.0, 1000.0)
horiz = st.floats(10.0, 5000.0)


@settings(max_examples=60)
@given(z1=depth, z2=depth, r=horiz, bearing=st.floats(0, 2 * np.pi))
def test_properties(z1: float, z2: float, r: float, bearing: float) -> None:
    a = np.array([0.0, 0.0, z1])
    b = np.array([r * np.cos(bearing), r * np.sin(bearing), z2])
    for prof in (MONO, CHANNEL):
        t_ab = layered.travel_time(prof, a, b, reflections="none")
        t_ba = layered.travel_time(prof, b, a, reflections="none")
        assert np.isnan(t_ab) == np.isnan(t_ba)
        if np.isnan(t_ab):
            continue
        assert abs(t_ab - t_ba) <= 1e-12 * t_ab
        dist = float(np.linalg.norm(b - a))
        cmax = float(prof.speeds.max())
        assert t_ab >= dist / cmax * (1 - 1e-14)
        # Fermat: no slower than the straight chord, itself no slower than the slowest speed on it
        zs = np.concatenate([[z1, z2], prof.depths[(prof.depths > min(z1, z2)) & (prof.depths < max(z1, z2))]])
        c_slow = float(prof.speed(zs).min())
        t_sl = layered.straight_line_time(prof, a, b)
        assert t_ab <= t_sl * (1 + 1e-12)
        assert t_sl <= dist / c_slow * (1 + 1e-12)


def test_gradient_matches_finite_differences() -> None:
    src, dst = random_pairs(60, seed=8)
    for prof in (MONO, CHANNEL):
        for mode in ("none", "all"):
            g = layered.travel_time_gradient(prof, src, dst, reflections=mode)
            h = 1e-2
            fd = np.empty_like(g)
            for k in range(3):
                e = np.zeros(3)
                e[k] = h
                fd[:, k] = (
                    layered.travel_time(prof, src, dst + e, reflections=mode)
                    - layered.travel_time(prof, src, dst - e, reflections=mode)
                ) / (2 * h)
            ok = np.isfinite(g).all(axis=1) & np.isfinite(fd).all(axis=1)
            assert ok.sum() >= 50
            err = np.linalg.norm(g[ok] - fd[ok], axis=1) / np.linalg.norm(g[ok], axis=1)
            assert err.max() < 1e-6


# ---------------------------------------------------------------- reflections and shadows


def test_constant_reflections_are_image_distances() -> None:
    src, dst = random_pairs(300, seed=4)
    prof = Constant(1500.0, bottom=1100.0).to_layered()
    R = np.hypot(*(dst - src)[:, :2].T)
    surf = layered.reflected_eigenray(prof, src, dst, "surface")
    np.testing.assert_allclose(surf.time, np.hypot(R, src[:, 2] + dst[:, 2]) / 1500.0, rtol=1e-13)
    assert np.all(surf.path == PathKind.SURFACE)
    assert np.all(surf.launch_angle <= 0) and np.all(surf.arrival_angle >= 0)
    bot = layered.reflected_eigenray(prof, src, dst, "bottom")
    np.testing.assert_allclose(bot.time, np.hypot(R, 2 * 1100.0 - src[:, 2] - dst[:, 2]) / 1500.0, rtol=1e-13)
    assert np.all(bot.path == PathKind.BOTTOM)
    np.testing.assert_allclose(surf.length, np.hypot(R, src[:, 2] + dst[:, 2]), rtol=1e-12)


def test_surface_reflection_against_mirrored_oracle() -> None:
    src, dst = random_pairs(30, seed=9)
    ray = layered.reflected_eigenray(CHANNEL, src, dst, "surface")
    orc = Oracle(CHANNEL, mirror=True)
    R = np.hypot(*(dst - src)[:, :2].T)
    n = 0
    for i in np.flatnonzero(ray.path == PathKind.SURFACE):
        # unfolded: the image source at -z_src sends the ray downwards through the surface
        miss, t = shot_check(orc, -src[i, 2], dst[i, 2], R[i], -float(ray.launch_angle[i]), (-BOTTOM, BOTTOM))
        assert abs(miss) < 1e-6
        assert abs(t - ray.time[i]) < 1e-7
        n += 1
    assert n >= 20


def test_shadow_zone_reason_and_fallback() -> None:
    # downward refracting (speed falls with depth): shallow points far apart are in the shadow
    # of the surface; the direct arc would have to leave the water there
    down = Layered([0, 100, 400, 1000], [1530, 1515, 1495, 1490], bottom=1000.0)
    a, b = np.array([0, 0, 20.0]), np.array([4000, 0, 30.0])
    assert np.isnan(layered.travel_time(down, a, b, reflections="none"))
    assert layered.why_no_path(down, a, b) == layered.REASON_SURFACE
    fb = layered.eigenray(down, a, b, reflections="fallback")
    assert fb.path in (PathKind.SURFACE, PathKind.BOTTOM) and np.isfinite(fb.time)
    # "all" never later than the direct path where one exists
    src, dst = random_pairs(100, seed=2)
    t_none = layered.travel_time(down, src, dst, reflections="none")
    t_all = layered.travel_time(down, src, dst, reflections="all")
    t_fb = layered.travel_time(down, src, dst, reflections="fallback")
    ok = np.isfinite(t_none)
    assert np.all(t_all[ok] <= t_none[ok])
    np.testing.assert_array_equal(t_fb[ok], t_none[ok])
    assert np.all(np.isfinite(t_fb))
    # a speed maximum between the points: no ray crosses it at long range, even with reflections
    peak = Layered([0, 100, 200], [1500, 1550, 1500])
    a, b = np.array([0, 0, 50.0]), np.array([5000, 0, 150.0])
    assert layered.why_no_path(peak, a, b) == layered.REASON_SHADOW
    e = layered.eigenray(peak, a, b, reflections="none")
    assert e.path == PathKind.NONE and np.isnan(e.time)
    # a point below the sea floor
    assert layered.why_no_path(down, a, [0, 0, 1500.0]) == layered.REASON_OUTSIDE
    assert layered.why_no_path(down, [0, 0, 20.0], [100, 0, 30.0]) == ""


def test_bad_reflections_option() -> None:
    with pytest.raises(ValueError):
        layered.eigenray(MONO, [0, 0, 1.0], [1, 0, 1.0], reflections="sometimes")
