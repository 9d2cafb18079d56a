"""Tests of aquasim_py.mobility against closed forms, event-driven bounces and an ODE solver."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from aquasim_py.mobility import (
    Box,
    ConstantVelocity,
    CoordinatedTurn,
    Kinematic,
    MeanderingCurrent,
    MeanderingJet,
    Mobility,
    RandomWalk,
    Static,
    Waypoints,
)

BOX = Box((0.0, 0.0, 0.0), (500.0, 400.0, 200.0))
HUGE = Box((-1e7, -1e7, 0.0), (1e7, 1e7, 1e7))


def gen(seed: int = 0) -> np.random.Generator:
    return np.random.default_rng(seed)


def inside(box: Box, n: int, seed: int = 0) -> np.ndarray:
    return gen(seed).uniform(box.lo, box.hi, (n, 3))


def bounce_1d(x: float, lo: float, hi: float) -> float:
    """Reference mirror: reflect off the walls one bounce at a time."""
    for _ in range(10_000):
        if x > hi:
            x = 2 * hi - x
        elif x < lo:
            x = 2 * lo - x
        else:
            return x
    raise AssertionError("too many bounces")


def bounced_path(p0: np.ndarray, v: np.ndarray, t: float, box: Box) -> tuple[np.ndarray, np.ndarray]:
    """Event-driven reference for straight motion: advance wall to wall, flipping velocity."""
    p, vel = p0.astype(float).copy(), v.astype(float).copy()
    for axis in range(3):
        x, u, left = p[axis], vel[axis], t
        lo, hi = box.lo[axis], box.hi[axis]
        while left > 0 and u != 0:
            wall = hi if u > 0 else lo
            hit = (wall - x) / u
            if hit >= left:
                x += u * left
                break
            x, u, left = wall, -u, left - hit
        p[axis], vel[axis] = x, u
    return p, vel


# -- Box ------------------------------------------------------------------------------------------


@given(
    st.lists(st.floats(-5000.0, 5000.0), min_size=3, max_size=3),
)
def test_reflect_matches_bounce_by_bounce_mirror(p) -> None:
    p = np.array(p)
    expected = [bounce_1d(p[i], BOX.lo[i], BOX.hi[i]) for i in range(3)]
    got = BOX.reflect(p)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9)
    assert BOX.contains(got)


def test_reflect_keeps_points_inside_and_fold_sign_is_the_derivative() -> None:
    p = gen(1).uniform(-3000, 3000, (1000, 3))
    folded, sign = BOX.fold(p)
    assert BOX.contains(folded).all()
    d = 1e-4
    for axis in range(3):
        step = np.zeros(3)
        step[axis] = d
        slope = (BOX.reflect(p + step) - BOX.reflect(p - step))[:, axis] / (2 * d)
        away = np.abs(folded[:, axis] - BOX.lo[axis]) > 1e-2
        away &= np.abs(folded[:, axis] - BOX.hi[axis]) > 1e-2
        np.testing.assert_allclose(slope[away], sign[away, axis], atol=1e-6)
    assert set(np.unique(sign)) == {-1.0, 1.0}
    # Points already inside are unchanged.
    q = inside(BOX, 100)
    np.testing.assert_allclose(BOX.reflect(q), q, rtol=0, atol=1e-12)


def test_box_validation() -> None:
    with pytest.raises(ValueError, match="hi > lo"):
        Box((0, 0, 0), (10, 0, 10))
    with pytest.raises(ValueError, match="depth"):
        Box((0, 0, -1), (10, 10, 10))
    with pytest.raises(ValueError, match="3-vectors"):
        Box((0, 0), (1, 1))
    with pytest.raises(ValueError, match="finite"):
        Box((0, 0, 0), (1, np.inf, 1))


# -- construction ---------------------------------------------------------------------------------


def test_mobility_validation() -> None:
    with pytest.raises(ValueError, match=r"shape \(n, 3\)"):
        Static(np.zeros((3, 2)), BOX)
    with pytest.raises(ValueError, match="outside"):
        Static([[600.0, 1.0, 1.0]], BOX)
    with pytest.raises(ValueError, match="Box"):
        Static(np.zeros((1, 3)), (0, 0, 0))
    m = Static(np.ones((2, 3)), BOX)
    with pytest.raises(ValueError, match="time"):
        m.position(-1.0)
    with pytest.raises(ValueError, match="time"):
        m.position(float("nan"))
    with pytest.raises(ValueError, match="rng"):
        RandomWalk(np.ones((2, 3)), BOX, None)
    with pytest.raises(ValueError, match="rng"):
        CoordinatedTurn(np.ones((2, 3)), BOX, None, speed=1.0)
    with pytest.raises(ValueError, match="speed_min"):
        RandomWalk(np.ones((2, 3)), BOX, gen(), speed_min=2.0, speed_max=1.0)
    with pytest.raises(ValueError, match="velocity"):
        ConstantVelocity(np.ones((2, 3)), BOX, velocity=np.ones((3, 3)))
    with pytest.raises(ValueError, match="inside"):
        Waypoints(np.ones((1, 3)), BOX, waypoints=[[[1e4, 0, 0]]])


# -- closed forms ---------------------------------------------------------------------------------


def test_static() -> None:
    p0 = inside(BOX, 5)
    m = Static(p0, BOX)
    assert m.n == 5
    np.testing.assert_array_equal(m.position(123.0), p0)
    np.testing.assert_array_equal(m.velocity(123.0), np.zeros((5, 3)))


def test_constant_velocity_closed_form_and_bounces() -> None:
    p0 = inside(BOX, 20, seed=3)
    v = gen(4).uniform(-30, 30, (20, 3))
    m = ConstantVelocity(p0, BOX, velocity=v)
    free = p0 + 0.5 * v
    clear = BOX.contains(free)  # nodes that meet no wall in the first 0.5 s
    assert clear.sum() > 10
    np.testing.assert_allclose(m.position(0.5)[clear], free[clear], atol=1e-9)
    for t in [0.0, 3.7, 41.0, 333.3, 1e4 + 0.1]:
        ref = [bounced_path(p0[i], v[i], t, BOX) for i in range(20)]
        np.testing.assert_allclose(m.position(t), [r[0] for r in ref], atol=1e-6)
        np.testing.assert_allclose(m.velocity(t), [r[1] for r in ref], atol=1e-12)


def test_coordinated_turn_is_an_exact_circle() -> None:
    n = 6
    p0 = np.column_stack([np.full(n, 1000.0), np.full(n, -500.0), np.full(n, 50.0)])
    speed = np.array([1.0, 2.0, 3.0, 0.5, 2.5, 1.5])
    rate = np.array([0.05, -0.02, 0.1, 0.3, -0.07, 1e-3])
    heading = np.linspace(0.0, 5.0, n)
    m = CoordinatedTurn(p0, HUGE, speed=speed, turn_rate=rate, heading=heading, vz=0.2)
    radius = speed / np.abs(rate)
    # Centre: a quarter turn to the inside of the initial heading.
    centre = p0[:, :2] + (speed / rate)[:, None] * np.column_stack([-np.sin(heading), np.cos(heading)])
    for t in [0.0, 1.0, 17.3, 250.0, 3000.0]:
        p = m.position(t)
        h = heading + rate * t
        expected = centre + (speed / rate)[:, None] * np.column_stack([np.sin(h), -np.cos(h)])
        # HUGE's 1e7 m corners cost ~2e-9 m of rounding in the fold.
        np.testing.assert_allclose(p[:, :2], expected, rtol=0, atol=1e-8)
        np.testing.assert_allclose(np.linalg.norm(p[:, :2] - centre, axis=1), radius, rtol=0, atol=1e-8)
        np.testing.assert_allclose(p[:, 2], 50.0 + 0.2 * t, atol=1e-9)
        np.testing.assert_allclose(
            m.velocity(t)[:, :2], speed[:, None] * np.column_stack([np.cos(h), np.sin(h)]), atol=1e-12
        )


def test_coordinated_turn_straight_limit() -> None:
    p0 = np.array([[0.0, 0.0, 10.0], [0.0, 0.0, 10.0]])
    m = CoordinatedTurn(p0, HUGE, speed=2.0, turn_rate=[0.0, 1e-13], heading=0.3)
    for t in [0.0, 10.0, 1e3]:
        straight = p0[0] + 2.0 * t * np.array([math.cos(0.3), math.sin(0.3), 0.0])
        np.testing.assert_allclose(m.position(t), [straight, straight], rtol=0, atol=1e-6)


def test_coordinated_turn_random_heading_is_seeded() -> None:
    p0 = inside(BOX, 50)
    a = CoordinatedTurn(p0, BOX, gen(7), speed=1.0, turn_rate=0.01)
    b = CoordinatedTurn(p0, BOX, gen(7), speed=1.0, turn_rate=0.01)
    c = CoordinatedTurn(p0, BOX, gen(8), speed=1.0, turn_rate=0.01)
    assert np.array_equal(a.heading, b.heading) and not np.array_equal(a.heading, c.heading)
    assert a.heading.min() >= 0.0 and a.heading.max() < 2 * np.pi


# -- random walk ----------------------------------------------------------------------------------


def test_random_walk_legs_are_straight_constant_speed() -> None:
    n, dur = 40, 7.5
    p0 = np.zeros((n, 3)) + [0.0, 0.0, 5e6]
    m = RandomWalk(p0, HUGE, gen(2), speed_min=0.5, speed_max=2.0, leg_duration=dur)
    legs = m.leg_velocities(200)  # spans several draw blocks
    speeds = np.linalg.norm(legs, axis=-1)
    assert speeds.min() >= 0.5 and speeds.max() <= 2.0
    assert speeds.mean() == pytest.approx(1.25, abs=0.02)
    assert np.all(legs[..., 2] == 0.0)
    # Knot positions are the running sum of legs; mid-leg points are the linear interpolation.
    knots = p0 + np.concatenate([np.zeros((1, n, 3)), np.cumsum(legs * dur, axis=0)])
    for k in [0, 1, 63, 64, 65, 150, 199]:
        np.testing.assert_allclose(m.position(k * dur), knots[k], rtol=0, atol=1e-7)
        np.testing.assert_allclose(m.position((k + 0.3) * dur), knots[k] + 0.3 * dur * legs[k], atol=1e-7)
        np.testing.assert_allclose(m.velocity((k + 0.9) * dur), legs[k], atol=0)


def test_random_walk_vertical_directions_uniform_on_sphere() -> None:
    m = RandomWalk(np.full((50, 3), 100.0), BOX, gen(3), speed_min=1.0, speed_max=1.0, leg_duration=1.0, vertical=True)
    u = m.leg_velocities(128).reshape(-1, 3)
    np.testing.assert_allclose(np.linalg.norm(u, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(u.mean(axis=0), 0.0, atol=0.03)
    np.testing.assert_allclose((u**2).mean(axis=0), 1.0 / 3.0, atol=0.015)


# -- waypoints ------------------------------------------------------------------------------------


def test_waypoints_timing_is_exact() -> None:
    p0 = np.array([[0.0, 0.0, 10.0], [100.0, 100.0, 10.0]])
    wps = [
        [[30.0, 40.0, 10.0], [30.0, 40.0, 10.0], [30.0, 40.0, 70.0]],  # 50 m, repeat, 60 m
        [[100.0, 100.0, 110.0]],  # 100 m straight down
    ]
    m = Waypoints(p0, BOX, waypoints=wps, speed=[2.0, 4.0])
    np.testing.assert_allclose(m.path_length, [110.0, 100.0])
    np.testing.assert_allclose(m.position(12.5), [[15.0, 20.0, 10.0], [100.0, 100.0, 60.0]], atol=1e-12)
    np.testing.assert_allclose(m.velocity(12.5), [[1.2, 1.6, 0.0], [0.0, 0.0, 4.0]], atol=1e-12)
    np.testing.assert_allclose(m.position(25.0)[0], [30.0, 40.0, 10.0], atol=1e-12)  # arrives at 50 m / 2 m/s
    np.testing.assert_allclose(m.velocity(25.0)[0], [0.0, 0.0, 2.0], atol=1e-12)  # next segment
    np.testing.assert_allclose(m.position(26.0)[0], [30.0, 40.0, 12.0], atol=1e-12)
    # Arrival at the end (55 s and 25 s) then stop.
    np.testing.assert_allclose(m.position(55.0), [[30.0, 40.0, 70.0], [100.0, 100.0, 110.0]], atol=1e-12)
    np.testing.assert_allclose(m.position(1e4), [[30.0, 40.0, 70.0], [100.0, 100.0, 110.0]], atol=1e-12)
    np.testing.assert_array_equal(m.velocity(55.0), np.zeros((2, 3)))


def test_waypoints_loop() -> None:
    p0 = np.array([[10.0, 10.0, 10.0]])
    m = Waypoints(p0, BOX, waypoints=[[[40.0, 10.0, 10.0], [40.0, 50.0, 10.0]]], speed=5.0, loop=True)
    period = (30.0 + 40.0 + 50.0) / 5.0  # back to the start on the hypotenuse
    np.testing.assert_allclose(m.path_length, [120.0])
    for cycle in [0, 1, 7]:
        base = cycle * period
        np.testing.assert_allclose(m.position(base), p0, atol=1e-9)
        np.testing.assert_allclose(m.position(base + 6.0), [[40.0, 10.0, 10.0]], atol=1e-9)
        np.testing.assert_allclose(m.position(base + 14.0), [[40.0, 50.0, 10.0]], atol=1e-9)
        np.testing.assert_allclose(m.position(base + 19.0), [[25.0, 30.0, 10.0]], atol=1e-9)
        np.testing.assert_allclose(m.velocity(base + 19.0), [[-3.0, -4.0, 0.0]], atol=1e-12)


# -- kinematic model (STVF / SLMP) ----------------------------------------------------------------


def stvf_velocity(m: Kinematic, p: np.ndarray, t: float) -> np.ndarray:
    """STVF Sec. 5.1 field written out independently, in the documented physical scales."""
    L, T = m.length_scale, m.time_scale
    x, y, tau = p[:, 0] / L, p[:, 1] / L, t / T + m.phase
    vx = m.k1 * m.iota * m.omega * np.sin(m.k2 * x) * np.cos(m.k3 * y) + m.k1 * m.iota * np.cos(2 * m.k1 * tau) + m.k4
    vy = -m.iota * m.omega * np.cos(m.k2 * x) * np.sin(m.k3 * y) + m.k5
    return np.column_stack([vx, vy, np.zeros_like(vx)]) * (L / T)


@pytest.mark.parametrize("scales", [{}, dict(length_scale=300.0, time_scale=1500.0, phase=0.3)])
def test_kinematic_matches_an_independent_ode_solution(scales) -> None:
    n = 12
    p0 = np.column_stack([gen(5).uniform(0, 5000, (n, 2)), np.full(n, 40.0)])
    m = Kinematic(p0, HUGE, gen(6), **scales)
    # Up to one time scale: the tidal flow is chaotic, so over many time scales any two
    # accurate integrators drift apart and stop being a reference for each other.
    times = m.time_scale * np.array([0.0, 3e-4, 2e-3, 0.0171, 0.1, 0.35, 1.0])

    def rhs(t, s):
        v = stvf_velocity(m, np.column_stack([s[:n], s[n:], np.zeros(n)]), t)
        return np.concatenate([v[:, 0], v[:, 1]])

    y0 = np.concatenate([p0[:, 0], p0[:, 1]])
    ref = solve_ivp(rhs, (0, times[-1]), y0, method="LSODA", t_eval=times, rtol=1e-11, atol=1e-8)
    assert ref.success
    for j in range(len(times))[::-1]:  # out of order on purpose
        p = m.position(times[j])
        np.testing.assert_allclose(p[:, 0], ref.y[:n, j], rtol=0, atol=2e-4)
        np.testing.assert_allclose(p[:, 1], ref.y[n:, j], rtol=0, atol=2e-4)
        np.testing.assert_array_equal(p[:, 2], p0[:, 2])
        np.testing.assert_allclose(m.velocity(times[j]), stvf_velocity(m, p, times[j]), rtol=0, atol=1e-5)
    assert np.abs(ref.y[:, -1] - y0).max() > m.length_scale  # the nodes really crossed the pattern


def test_kinematic_parameter_draws() -> None:
    m = Kinematic(inside(BOX, 4000), BOX, gen(9))
    for name, mean in [
        ("k1", math.pi),
        ("k2", math.pi),
        ("k3", 2 * math.pi),
        ("iota", 3.0),
        ("omega", 1.0),
        ("k4", 1.0),
        ("k5", 1.0),
    ]:
        vals = getattr(m, name)
        assert vals.shape == (4000,)
        assert vals.mean() == pytest.approx(mean, rel=0.01)
        assert vals.std() / mean == pytest.approx(0.1, rel=0.05)
    fixed = Kinematic(inside(BOX, 3), BOX, None, rel_std=0.0)
    assert np.all(fixed.k3 == 2 * math.pi)


def test_kinematic_drift_speed_is_about_one_metre_per_second() -> None:
    """STVF layout (200 nodes, 500 m x 500 m): ~1 m/s, ~110 m per 100 s in the paper's sample."""
    box = Box((0.0, 0.0, 0.0), (500.0, 500.0, 100.0))
    m = Kinematic(inside(box, 200, seed=10), box, gen(11))
    speeds = np.array([np.linalg.norm(m.velocity(t), axis=1).mean() for t in np.arange(0.0, 500.0, 5.0)])
    assert 0.8 < speeds.mean() < 1.6
    unfolded = HUGE
    free = Kinematic(inside(box, 200, seed=10), unfolded, gen(11))
    net = np.linalg.norm(free.position(100.0) - free.position(0.0), axis=1).mean()
    assert 80.0 < net < 160.0


# -- Bower / Caruso meandering jet ----------------------------------------------------------------

CARUSO = dict(amplitude=1.2, phase_speed=0.12, wavelength=7.5, omega=0.4, epsilon=0.3)


def caruso_psi(x, y, t, amplitude, phase_speed, wavelength, omega, epsilon):
    """Caruso et al. (INFOCOM 2008) eq. 1, dimensionless, written out independently."""
    k = 2 * np.pi / wavelength
    B = amplitude + epsilon * np.cos(omega * t)
    th = k * (x - phase_speed * t)
    return 1 - np.tanh((y - B * np.cos(th)) / np.sqrt(1 + k**2 * B**2 * np.sin(th) ** 2))


def jet_nodes(n: int, seed: int) -> np.ndarray:
    """Nodes spread over the meander region, |x'|, |y'| <= 3 km (origin at 0)."""
    return np.column_stack([gen(seed).uniform(-3000, 3000, (n, 2)), np.full(n, 50.0)])


def test_meandering_jet_steady_case_conserves_the_comoving_stream_function() -> None:
    # epsilon = 0: in the frame moving east at c the flow is steady, so psi + c y' is a
    # constant of motion. DOP853 at rtol 1e-12 plus the Hermite table (error ~ (h/T)^4 / 384
    # ~ 1e-11 length units at 128 steps per unit) keep it to ~1e-11 (measured 7e-12); 1e-9
    # leaves margin while a wrong derivative (a sign, a missing chain-rule term) breaks it at O(0.1).
    p = dict(CARUSO, epsilon=0.0)
    m = MeanderingJet(jet_nodes(40, 1), HUGE, None, origin=(0.0, 0.0), **p)
    L, T, c = m.length_scale, m.time_scale, p["phase_speed"]

    def invariant(t):
        q = m.position(t)
        return caruso_psi(q[:, 0] / L, q[:, 1] / L, t / T, **p) + c * q[:, 1] / L

    phi0 = invariant(0.0)
    moved = 0.0
    for t in T * np.array([20.0, 0.37, 7.5, 3.0]):  # out of order on purpose
        np.testing.assert_allclose(invariant(t), phi0, rtol=0, atol=1e-9)
        moved = max(moved, float(np.abs(m.position(t)[:, 0] - m.initial_positions[:, 0]).max()))
    assert moved > 5 * L  # some nodes rode the jet for kilometres


def test_meandering_jet_matches_a_hand_integrated_trajectory() -> None:
    # Independent reference: classical RK4 with a fixed step of 2e-3 time units on the
    # velocity obtained by central differences of the published psi (step 1e-6). RK4 error
    # ~ h^4 = 1.6e-11 per unit time, difference error ~ 1e-16 / 1e-6 = 1e-10; even with the
    # flow's stretching (e-folding in about a time unit) the reference is good to ~1e-8
    # length units over 2 units, i.e. 0.01 mm: 1 mm tolerance.
    n, p = 10, CARUSO
    m = MeanderingJet(jet_nodes(n, 2), HUGE, None, origin=(0.0, 0.0), phase=1.7, **p)
    L, T = m.length_scale, m.time_scale
    d = 1e-6

    def vel(x, y, t):
        u = -(caruso_psi(x, y + d, t, **p) - caruso_psi(x, y - d, t, **p)) / (2 * d)
        v = (caruso_psi(x + d, y, t, **p) - caruso_psi(x - d, y, t, **p)) / (2 * d)
        return u, v

    x, y = m.initial_positions[:, 0] / L, m.initial_positions[:, 1] / L
    t, h, steps = 1.7, 2e-3, 1000
    for _ in range(steps):
        k1 = vel(x, y, t)
        k2 = vel(x + h / 2 * k1[0], y + h / 2 * k1[1], t + h / 2)
        k3 = vel(x + h / 2 * k2[0], y + h / 2 * k2[1], t + h / 2)
        k4 = vel(x + h * k3[0], y + h * k3[1], t + h)
        x = x + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        y = y + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        t += h
    q = m.position(steps * h * T)
    np.testing.assert_allclose(q[:, 0], x * L, rtol=0, atol=1e-3)
    np.testing.assert_allclose(q[:, 1], y * L, rtol=0, atol=1e-3)
    u, v = vel(x, y, t)
    np.testing.assert_allclose(m.velocity(steps * h * T)[:, :2], np.column_stack([u, v]) * L / T, rtol=0, atol=1e-8)


def test_meandering_jet_is_divergence_free_and_preserves_area() -> None:
    m = MeanderingJet(jet_nodes(3, 3), HUGE, None, origin=(0.0, 0.0), **CARUSO)
    # Pointwise: central differences (step 1 cm) of the field, error ~ (1e-5)^2 of a unit
    # gradient (1 / L in s^-1 units after scaling): |div| << |grad|.
    r = gen(4)
    pts = np.column_stack([r.uniform(-4000, 4000, (200, 2)), np.zeros(200)])[:, None, :]
    ts = r.uniform(0, 50 * m.time_scale, (200, 1))
    h = 0.01
    ex, ey = np.array([h, 0, 0]), np.array([0, h, 0])
    dudx = (m.field(pts + ex, ts)[..., 0] - m.field(pts - ex, ts)[..., 0]) / (2 * h)
    dvdy = (m.field(pts + ey, ts)[..., 1] - m.field(pts - ey, ts)[..., 1]) / (2 * h)
    scale = np.abs(dudx).max()
    assert scale > 1e-5  # the field really has gradients (s^-1)
    assert np.abs(dudx + dvdy).max() < 1e-6 * scale
    # Along trajectories: small triangles (1 m sides) keep their area while being sheared.
    # The straight-edged image of a triangle of size s differs from the exact image by
    # O(s * curvature / gradient) ~ 1e-3 relatively: 1 % tolerance, far below the
    # e^{div t} change a compressible field of comparable gradients would give.
    centres = jet_nodes(6, 5)[:, :2]
    tri = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    p0 = (centres[:, None, :] + tri[None]).reshape(-1, 2)
    mt = MeanderingJet(np.column_stack([p0, np.full(len(p0), 50.0)]), HUGE, None, origin=(0.0, 0.0), **CARUSO)
    q = mt.position(2.0 * mt.time_scale)[:, :2].reshape(-1, 3, 2)
    a, b = q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]
    area = 0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    np.testing.assert_allclose(area, 0.5, rtol=1e-2)
    side = np.linalg.norm(a, axis=1)
    assert np.abs(side - 1.0).max() > 0.05  # the triangles were deformed, not just carried


def test_meandering_jet_scaling_origin_and_phase() -> None:
    box = Box((0.0, 0.0, 0.0), (1000.0, 600.0, 100.0))
    m = MeanderingJet(inside(box, 5), box, None)
    np.testing.assert_array_equal(m.origin, [500.0, 300.0])  # default: the box centre
    # On the jet axis at a meander crest (theta = 0, y' = B = A + epsilon at t' = 0) the
    # flow is due east at the peak speed, 1 km per 0.03 days.
    crest = np.array([[[500.0, 300.0 + 1500.0, 50.0]]])
    np.testing.assert_allclose(m.field(crest, 0.0)[0, 0], [1000.0 / 2592.0, 0.0, 0.0], atol=1e-15)
    period = 2 * np.pi / (0.12 * 2 * np.pi / 7.5)
    draws = [MeanderingJet(inside(box, 2), box, gen(s), phase=None).phase for s in range(30)]
    assert all(0.0 <= d < period for d in draws) and len(set(draws)) == 30
    assert MeanderingJet(inside(box, 2), box, gen(4), random_phase=True).phase == draws[4]
    with pytest.raises(ValueError, match="rng"):
        MeanderingJet(inside(box, 2), box, None, phase=None)
    with pytest.raises(ValueError, match="wavelength"):
        MeanderingJet(inside(box, 2), box, None, wavelength=0.0)
    with pytest.raises(ValueError, match="origin"):
        MeanderingJet(inside(box, 2), box, None, origin=(1.0, 2.0, 3.0))


def test_meandering_current_is_a_deprecated_alias_of_kinematic() -> None:
    p0 = inside(BOX, 4)
    with pytest.warns(DeprecationWarning, match="Kinematic"):
        old = MeanderingCurrent(p0, BOX, gen(3))
    new = Kinematic(p0, BOX, gen(3))
    np.testing.assert_array_equal(old.position(123.4), new.position(123.4))


def test_scenario_model_names(tmp_path) -> None:
    import warnings

    from aquasim_py import scenario

    assert scenario.mobility_class("kinematic") is Kinematic
    assert scenario.mobility_class("meandering_jet") is MeanderingJet
    assert scenario.mobility_class("random_walk") is RandomWalk
    text = """
[simulation]
duration_s = 2.0
seed = 3
[environment]
volume = {{ lo = [0.0, 0.0, 0.0], hi = [400.0, 400.0, 100.0] }}
[[nodes]]
role = "ordinary"
count = 3
protocol = "beacon"
placement = {{ kind = "uniform" }}
mobility = {{ model = "{model}" }}
[[nodes]]
role = "ordinary"
count = 2
protocol = "beacon"
placement = {{ kind = "uniform" }}
mobility = {{ model = "{model}" }}
"""
    for model in ("kinematic", "meandering_jet", "random_walk"):
        f = tmp_path / f"{model}.toml"
        f.write_text(text.format(model=model))
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            scenario.load(f)
    old = tmp_path / "old.toml"
    old.write_text(text.format(model="meandering_current"))
    with pytest.warns(scenario.ScenarioDeprecationWarning, match="'kinematic'.*'meandering_jet'"):
        scenario.load(old)


def test_cli_prints_one_warning_line_for_the_old_name(tmp_path, capsys) -> None:
    from aquasim_py import cli

    f = tmp_path / "old.toml"
    f.write_text(
        """
[simulation]
duration_s = 1.0
seed = 3
[environment]
volume = { lo = [0.0, 0.0, 0.0], hi = [400.0, 400.0, 100.0] }
[[nodes]]
role = "ordinary"
count = 2
protocol = "beacon"
placement = { kind = "uniform" }
mobility = { model = "meandering_current" }
[[nodes]]
role = "anchor"
count = 2
protocol = "beacon"
placement = { kind = "uniform" }
mobility = { model = "meandering_current" }
"""
    )
    assert cli.main([str(f), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("warning: ") and "kinematic" in lines[0]


# -- properties shared by all models --------------------------------------------------------------


def build(kind: str, p0: np.ndarray, box: Box, seed: int, speed: float) -> Mobility:
    r = gen(seed)
    if kind == "static":
        return Static(p0, box, r)
    if kind == "cv":
        return ConstantVelocity(p0, box, r, velocity=r.normal(0, speed, (len(p0), 3)))
    if kind == "turn":
        return CoordinatedTurn(
            p0, box, r, speed=speed, turn_rate=r.normal(0, 0.05, len(p0)), vz=r.normal(0, speed / 3, len(p0))
        )
    if kind == "walk":
        return RandomWalk(p0, box, r, speed_min=0.0, speed_max=speed, leg_duration=5.0, vertical=True)
    if kind == "meander":
        return Kinematic(p0, box, r, length_scale=2000.0 * speed, time_scale=20000.0)
    if kind == "jet":
        # a jet much wider than the box, so nodes bounce, at speeds around ``speed``
        # (time scale floored at 150 s: the table integration cost grows with t / time_scale)
        T = max(300.0 / speed, 150.0)
        return MeanderingJet(p0, box, r, length_scale=300.0, time_scale=T, phase=None, steps_per_unit=16)
    if kind == "waypoints":
        return Waypoints(p0, box, r, waypoints=[r.uniform(box.lo, box.hi, (3, 3)) for _ in p0], speed=speed, loop=True)
    raise AssertionError(kind)


KINDS = ["static", "cv", "turn", "walk", "meander", "jet", "waypoints"]


@settings(max_examples=40)
@given(
    kind=st.sampled_from(KINDS),
    seed=st.integers(0, 2**31),
    speed=st.floats(0.1, 50.0),
    times=st.lists(st.floats(0.0, 5000.0), min_size=1, max_size=8),
)
def test_always_inside_and_query_order_independent(kind, seed, speed, times) -> None:
    box = Box((0.0, -50.0, 5.0), (300.0, 100.0, 80.0))
    p0 = inside(box, 7, seed=seed % 1000)
    a = build(kind, p0, box, seed, speed)
    b = build(kind, p0, box, seed, speed)
    forward = [a.position(t) for t in sorted(times)]
    backward = [b.position(t) for t in sorted(times, reverse=True)][::-1]
    for pa, pb in zip(forward, backward):
        assert np.array_equal(pa, pb)
        assert box.contains(pa).all()
        assert pa.shape == (7, 3)


@pytest.mark.parametrize("kind", KINDS)
def test_velocity_is_the_derivative_of_position(kind) -> None:
    box = Box((0.0, 0.0, 0.0), (400.0, 300.0, 150.0))
    m = build(kind, inside(box, 30, seed=1), box, 2, 3.0)
    dt = 1e-4
    checked = 0
    for t in np.linspace(0.3, 900.0, 25):
        if kind == "walk" and abs(t / 5.0 - round(t / 5.0)) < 1e-3:
            continue  # leg switch inside the difference window
        fd = (m.position(t + dt) - m.position(t - dt)) / (2 * dt)
        p = m.position(t)
        # Away from walls (and waypoint corners) the central difference is the velocity.
        ok = np.all((p - box.lo > 0.1) & (box.hi - p > 0.1), axis=1)
        good = np.all(np.abs(fd - m.velocity(t)) < 1e-4, axis=1)
        if kind == "waypoints":  # corners are kinks
            ok &= np.linalg.norm(m.points - p[:, None, :], axis=-1).min(axis=1) > 0.1
        assert np.all(good[ok]), (kind, t)
        checked += ok.sum()
    assert checked > 300


def test_same_seed_same_trajectories_other_seed_differs() -> None:
    p0 = inside(BOX, 10)
    for kind in ["walk", "meander", "turn"]:
        a, b, c = (build(kind, p0, BOX, s, 2.0) for s in (1, 1, 2))
        assert np.array_equal(a.position(321.0), b.position(321.0))
        assert not np.array_equal(a.position(321.0), c.position(321.0))


def test_track_and_state() -> None:
    m = ConstantVelocity(inside(BOX, 4), BOX, velocity=(3.0, -2.0, 1.0))
    tr = m.track([0.0, 10.0, 20.0])
    assert tr.shape == (3, 4, 3)
    np.testing.assert_array_equal(tr[1], m.position(10.0))
    pos, vel = m.state(10.0)
    np.testing.assert_array_equal(pos, m.position(10.0))
    np.testing.assert_array_equal(vel, m.velocity(10.0))


def test_position_cost_200_nodes(benchmark) -> None:
    """Per-reception cost: one position(t) for a group of 200 drifting nodes."""
    box = Box((0.0, 0.0, 0.0), (500.0, 500.0, 100.0))
    m = Kinematic(inside(box, 200), box, gen(1))
    ts = iter(np.linspace(0.0, 500.0, 10**7))
    out = benchmark(lambda: m.position(next(ts)))
    assert out.shape == (200, 3)


@pytest.mark.parametrize("kind", KINDS)
def test_batched_pairs_match_per_time_queries(kind) -> None:
    box = Box((0.0, 0.0, 0.0), (400.0, 300.0, 150.0))
    m = build(kind, inside(box, 25, seed=4), box, 5, 4.0)
    r = gen(6)
    idx = r.integers(0, 25, 60)
    t = r.uniform(0.0, 3000.0, 60)
    pos = m.position_at(idx, t)
    vel = m.velocity_at(idx, t)
    fresh = build(kind, inside(box, 25, seed=4), box, 5, 4.0)  # also: batch first, singles later
    for j in range(60):
        np.testing.assert_allclose(pos[j], fresh.position(t[j])[idx[j]], rtol=0, atol=1e-9)
        np.testing.assert_allclose(vel[j], fresh.velocity(t[j])[idx[j]], rtol=0, atol=1e-9)
    np.testing.assert_allclose(m.position_at(idx[:5], 12.0), m.position(12.0)[idx[:5]], rtol=0, atol=1e-9)
    assert m.position_at(np.array([], dtype=int), []).shape == (0, 3)


def test_batched_pairs_validation() -> None:
    m = Static(np.ones((3, 3)), BOX)
    with pytest.raises(ValueError, match="indices"):
        m.position_at([0, 3], 1.0)
    with pytest.raises(ValueError, match="indices"):
        m.position_at([-1], 1.0)
    with pytest.raises(ValueError, match="1-D"):
        m.position_at([0.5], 1.0)
    with pytest.raises(ValueError, match="times"):
        m.position_at([0, 1], [1.0, -2.0])


def test_noisy_constant_velocity_steps_follow_the_cv_model() -> None:
    """Before start_s the node rests; with q = 0 it moves in a straight line; with q > 0 one
    step's (position, velocity) increments have the exact CWNA covariance q [[T^3/3, T^2/2],
    [T^2/2, T]] (sample covariance of 4000 nodes; 4 sigma of its sampling error allowed)."""
    from aquasim_py.mobility import Box, NoisyConstantVelocity

    box = Box([-1e6, -1e6, 0.0], [1e6, 1e6, 1e6])
    p0 = np.tile([0.0, 0.0, 50.0], (4000, 1))
    m0 = NoisyConstantVelocity(p0[:1], box, np.random.default_rng(0), velocity=[10.0, 10.0, 0.0], q=0.0, start_s=5.0)
    np.testing.assert_allclose(m0.position(3.0)[0], [0.0, 0.0, 50.0])
    np.testing.assert_allclose(m0.position(12.5)[0], [75.0, 75.0, 50.0], atol=1e-9)
    q, T = 2.0, 1.0
    m = NoisyConstantVelocity(p0, box, np.random.default_rng(1), velocity=[10.0, 0.0, 0.0], q=q, dt=T)
    p1 = m.position(1.0)[:, 0]
    # the velocity at step 1 is not reported directly (segments are straight): use p2 - 2 p1 + p0 = T (v1 - v0) + w2_p - w1_p
    C = np.cov(np.vstack([p1 - 10.0]))
    ref = q * T**3 / 3
    assert abs(float(C) - ref) < 4 * ref * math.sqrt(2 / 4000)
    assert np.all(m.position(7.0)[:, 2] == 50.0)  # not vertical: depth fixed


class TestConfinedNoisyCV:
    """confine_steps: the CV model conditioned on staying in the box, by rejection."""

    def _make(self, box, seed, **kw):
        from aquasim_py.mobility import NoisyConstantVelocity

        return NoisyConstantVelocity(
            np.array([[0.0, 0.0, 50.0]]), box, np.random.default_rng(seed), velocity=[10.0, 10.0, 0.0], q=1.0, **kw
        )

    def test_a_box_nothing_leaves_changes_nothing(self):
        from aquasim_py.mobility import Box

        big = Box([-1e6, -1e6, 0.0], [1e6, 1e6, 100.0])
        free, held = self._make(big, 4), self._make(big, 4, confine_steps=80)
        t = np.linspace(0.0, 79.0, 200)
        assert held.redraws == 0
        np.testing.assert_array_equal(held.position_at(np.zeros(200, int), t), free.position_at(np.zeros(200, int), t))

    @pytest.mark.parametrize("seed", range(5))
    def test_tracks_stay_in_the_box(self, seed):
        from aquasim_py.mobility import Box

        box = Box([-200.0, -200.0, 0.0], [400.0, 400.0, 100.0])
        m = self._make(box, seed, confine_steps=40)
        k = np.arange(41.0)
        pos = m._raw_position_at(np.zeros(41, int), k)
        assert box.contains(pos).all()
        with pytest.raises(ValueError, match="stayed in"):
            self._make(Box([-1.0, -1.0, 0.0], [1.0, 1.0, 100.0]), seed, confine_steps=40, max_redraws=3)
