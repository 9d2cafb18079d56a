"""Closed-form isogradient eigenrays against independent references.

References: numerical integration of the ray equations with shooting (ray_ode.py, no closed
form inside), the paper's own formulas evaluated literally from the angles (eqs 12-14, 19),
scipy quadrature for the straight-line time, central finite differences for the gradient, and
Fermat / speed bounds as Hypothesis properties.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.integrate import quad

from aquasim_py.channel import isogradient as iso
from aquasim_py.channel.rays import PathKind

sys.path.insert(0, str(Path(__file__).parent))
import ray_ode


def _random_pairs(rng: np.random.Generator, n: int, z_max: float = 1000.0) -> tuple[np.ndarray, np.ndarray]:
    """n pairs with depths in [0, z_max] m and 10 m <= distance <= 5 km (rejection sampling)."""
    src, dst = [], []
    while len(src) < n:
        s = np.array([0.0, 0.0, rng.uniform(0.0, z_max)])
        z2 = rng.uniform(0.0, z_max)
        dist = math.exp(rng.uniform(math.log(10.0), math.log(5000.0)))
        if dist <= abs(z2 - s[2]):
            continue
        r = math.sqrt(dist**2 - (z2 - s[2]) ** 2)
        phi = rng.uniform(0.0, 2.0 * math.pi)
        shift = rng.uniform(-500.0, 500.0, 2)
        s[:2] = shift
        src.append(s)
        dst.append(np.array([shift[0] + r * math.cos(phi), shift[1] + r * math.sin(phi), z2]))
    return np.array(src), np.array(dst)


def _profiles(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    b = rng.uniform(1480.0, 1520.0, n)
    mag = rng.uniform(0.01, 0.1, n)
    sign = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
    return b, sign * mag


# the closed forms' own rounding: a few elementary functions of O(1) arguments per quantity,
# each correctly rounded to ~1 ulp; 1e-13 relative is ~450 eps, 4.4e-16 rad is 2 ulp of pi/2
SOLVER_REL = 1e-13
SOLVER_ANGLE = 4.4e-16


def _turn_tol(b: float, a: float, z: float) -> float:
    """Rounding of the closed-form vertex depth (c / cos(theta) - b) / a: c ~ b cancels, so
    its relative rounding is amplified by b / |a|."""
    return SOLVER_REL * (abs(z) + b / abs(a))


def _oracle_sweep(n: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    src, dst = _random_pairs(rng, n)
    b, a = _profiles(rng, n)
    # a tenth of the pairs near the surface with a < 0, where arcs can rise out of the water
    k = n // 10
    src[:k], dst[:k] = _random_pairs(rng, k, z_max=60.0)
    a[:k] = -np.abs(a[:k])
    ray = iso.eigenray(b, a, src, dst)
    grad = iso.travel_time_gradient(b, a, src, dst)
    n_direct = n_turning = n_none = 0
    # worst error as a fraction of its tolerance: the oracle's own bound (ray_ode.tolerances,
    # from its rtol/atol and steps) plus the closed forms' rounding (SOLVER_REL relative)
    worst = {"time": 0.0, "length": 0.0, "angle": 0.0, "turn": 0.0, "grad": 0.0}
    for i in range(n):
        ai, bi = float(a[i]), float(b[i])
        ode = ray_ode.shoot(lambda z: bi + ai * z, lambda z: ai, src[i], dst[i], extrema=True)
        tol = ray_ode.tolerances(ode)
        if ray.path[i] == PathKind.NONE:
            # only possible here through the surface (a < 0, no bottom): the free arc must rise above z = 0
            n_none += 1
            assert ai < 0.0 and ode.z_min < 0.0, (i, ode)
            assert np.isnan(ray.time[i]) and ray.turning_depth[i] < 0.0
            assert abs(ray.turning_depth[i] - ode.z_min) <= tol["position"] + _turn_tol(bi, ai, ode.z_min), (i, ode)
            continue
        n_direct += 1
        assert ode.z_min >= -tol["position"], (i, ode)
        worst["time"] = max(worst["time"], abs(ray.time[i] - ode.time) / (tol["time"] + SOLVER_REL * ode.time))
        worst["length"] = max(
            worst["length"], abs(ray.length[i] - ode.length) / (tol["length"] + SOLVER_REL * ode.length)
        )
        worst["angle"] = max(
            worst["angle"],
            abs(ray.launch_angle[i] - ode.launch_angle) / (tol["launch"] + SOLVER_ANGLE),
            abs(ray.arrival_angle[i] - ode.arrival_angle) / (tol["arrival"] + SOLVER_ANGLE),
        )
        # the gradient is the slowness vector at the receiver of the ODE's ray: its relative
        # error is the arrival angle's error (its length 1/c is exact)
        e_h = (dst[i, :2] - src[i, :2]) / np.hypot(*(dst[i, :2] - src[i, :2]))
        c2 = bi + ai * dst[i, 2]
        slow = np.r_[math.cos(ode.arrival_angle) * e_h, math.sin(ode.arrival_angle)] / c2
        worst["grad"] = max(
            worst["grad"],
            float(np.linalg.norm(grad[i] - slow) / np.linalg.norm(slow)) / (tol["arrival"] + SOLVER_ANGLE + SOLVER_REL),
        )
        # vertex strictly inside <=> the brute-force extreme depth lies outside [z1, z2]
        z_lo, z_hi = sorted((src[i, 2], dst[i, 2]))
        overshoot = ode.z_max - z_hi if ai > 0.0 else z_lo - ode.z_min
        if np.isnan(ray.turning_depth[i]):
            assert overshoot <= tol["position"], (i, overshoot)
        else:
            n_turning += 1
            brute = ode.z_max if ai > 0.0 else ode.z_min
            worst["turn"] = max(
                worst["turn"], abs(ray.turning_depth[i] - brute) / (tol["position"] + _turn_tol(bi, ai, brute))
            )
    assert n_direct >= 200 and n_turning >= 20 and n_none >= 3, (n_direct, n_turning, n_none)
    print(
        f"\n{n} pairs ({n_direct} direct, {n_turning} turning, {n_none} none), worst errors "
        f"as fractions of their tolerances: {worst}"
    )
    assert max(worst.values()) <= 1.0, worst


def test_against_ode_oracle() -> None:
    """>= 200 random direct pairs within the integrated ray's error bounds (measured: <= 4% of them)."""
    _oracle_sweep(260, seed=20260101)


@pytest.mark.slow
def test_against_ode_oracle_large() -> None:
    _oracle_sweep(2000, seed=7)


def test_gradient_matches_central_differences() -> None:
    rng = np.random.default_rng(3)
    src, dst = _random_pairs(rng, 400)
    b, a = _profiles(rng, 400)
    a[::7] = 0.0
    a[1::7] = 1e-9
    g = iso.travel_time_gradient(b, a, src, dst)
    ok = ~np.isnan(g[:, 0])
    assert ok.sum() > 300
    h = 1e-3  # m: truncation ~ h^2/D^2 relative, rounding ~ 1e-15 t / h
    fd = np.empty_like(g)
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        fd[:, k] = (iso.travel_time(b, a, src, dst + e) - iso.travel_time(b, a, src, dst - e)) / (2 * h)
    # near-surface / near-vertex points can lose a neighbour: compare where both sides exist
    ok &= ~np.isnan(fd).any(axis=1)
    err = np.linalg.norm(g[ok] - fd[ok], axis=1) / np.linalg.norm(g[ok], axis=1)
    print(f"\ngradient vs central differences: max rel err {err.max():.2e} over {ok.sum()} pairs")
    assert err.max() <= 1e-6


def test_equal_depths_eq12() -> None:
    """Eq 12 (tan alpha_0 = a R / (2 c)), then eqs 13 and 19 evaluated literally from the angles."""
    for a in (0.1, 0.017, -0.05):
        b, z, R = 1490.0, 300.0, np.array([10.0, 777.0, 3000.0, 5000.0])
        src = np.stack([np.zeros_like(R), np.zeros_like(R), np.full_like(R, z)], axis=-1)
        dst = np.stack([R, np.zeros_like(R), np.full_like(R, z)], axis=-1)
        c = b + a * z
        alpha0 = np.arctan(0.5 * a * R / c)
        th_a, th_t = alpha0, -alpha0  # beta_0 = 0
        t13 = -(1 / a) * (np.log((1 + np.sin(th_t)) / np.cos(th_t)) - np.log((1 + np.sin(th_a)) / np.cos(th_a)))
        l19 = -c * (th_t - th_a) / (a * np.cos(th_t))
        ray = iso.eigenray(b, a, src, dst, bottom=None if a < 0 else 2000.0)
        ok = ray.path == PathKind.DIRECT
        np.testing.assert_allclose(ray.time[ok], t13[ok], rtol=1e-11)
        np.testing.assert_allclose(ray.length[ok], l19[ok], rtol=1e-11)
        np.testing.assert_allclose(ray.launch_angle[ok], th_a[ok], rtol=1e-12)
        np.testing.assert_allclose(ray.arrival_angle[ok], th_t[ok], rtol=1e-12)
        # the vertex sits mid-way (eq 22: z = (1/k0 - b)/a with k0 = cos(theta_A)/c)
        np.testing.assert_allclose(ray.turning_depth[ok], ((c / np.cos(th_a) - b) / a)[ok], rtol=1e-9)


def test_general_pairs_match_eq13_and_eq19() -> None:
    """For random pairs, the paper's time (eq 13) and length (eq 19) from our angles, and Snell (eq 3)."""
    rng = np.random.default_rng(11)
    src, dst = _random_pairs(rng, 500)
    b, a = _profiles(rng, 500)
    ray = iso.eigenray(b, a, src, dst)
    ok = ray.path == PathKind.DIRECT
    th_a, th_t = ray.launch_angle[ok], ray.arrival_angle[ok]
    aa, bb = a[ok], b[ok]
    c1, c2 = bb + aa * src[ok, 2], bb + aa * dst[ok, 2]
    t13 = -(1 / aa) * (np.log((1 + np.sin(th_t)) / np.cos(th_t)) - np.log((1 + np.sin(th_a)) / np.cos(th_a)))
    l19 = -c2 * (th_t - th_a) / (aa * np.cos(th_t))
    # eq 13 and 19 difference nearly equal numbers: allow for their own rounding
    np.testing.assert_allclose(ray.time[ok], t13, rtol=1e-9)
    np.testing.assert_allclose(ray.length[ok], l19, rtol=1e-9)
    np.testing.assert_allclose(np.cos(th_a) / c1, np.cos(th_t) / c2, rtol=1e-13)


@pytest.mark.parametrize("a", [0.1, 0.02, -0.03])
def test_vertical_eq14(a: float) -> None:
    b = 1500.0
    z1 = np.array([10.0, 700.0, 0.0, 999.0])
    z2 = np.array([700.0, 10.0, 1000.0, 998.0])
    src = np.stack([np.full(4, 5.0), np.full(4, -2.0), z1], axis=-1)
    dst = np.stack([np.full(4, 5.0), np.full(4, -2.0), z2], axis=-1)
    c1, c2 = b + a * z1, b + a * z2
    # eq 14, with ln(c2/c1) written as log1p(a dz / c1) so the 1 m case keeps full precision
    ln21 = np.log1p(a * (z2 - z1) / c1)
    t14 = np.where(z2 < z1, -ln21 / a, ln21 / a)
    ray = iso.eigenray(b, a, src, dst)
    np.testing.assert_allclose(ray.time, t14, rtol=1e-13)
    np.testing.assert_allclose(ray.length, np.abs(z2 - z1), rtol=1e-14)
    np.testing.assert_allclose(ray.launch_angle, np.sign(z2 - z1) * np.pi / 2)
    assert np.all(np.isnan(ray.turning_depth))
    g = iso.travel_time_gradient(b, a, src, dst)
    np.testing.assert_allclose(g[:, 2], np.sign(z2 - z1) / c2, rtol=1e-13)
    np.testing.assert_allclose(g[:, :2], 0.0, atol=1e-18)


@pytest.mark.parametrize("a", [1e-9, -1e-9, 1e-12, -1e-12, 0.0])
def test_small_gradient_limit(a: float) -> None:
    """|a| <= 1e-9: distance / speed to 1e-12 relative (no cancellation)."""
    rng = np.random.default_rng(5)
    src, dst = _random_pairs(rng, 300)
    b = 1500.0
    D = np.linalg.norm(dst - src, axis=-1)
    # over these depths the speed varies by < 1e-6 m/s, so the speed at mid-depth is exact to ~1e-19
    c_mid = b + a * 0.5 * (src[:, 2] + dst[:, 2])
    ray = iso.eigenray(b, a, src, dst)
    np.testing.assert_allclose(ray.time, D / c_mid, rtol=1e-12)
    np.testing.assert_allclose(ray.length, D, rtol=1e-12)
    np.testing.assert_allclose(iso.straight_line_time(b, a, src, dst), D / c_mid, rtol=1e-12)
    g = iso.travel_time_gradient(b, a, src, dst)
    # the ray's curvature tilts the slowness by ~ |a| D / c (<= 4e-9 rad here), no more
    straight = (dst - src) / (D * c_mid)[:, None]
    rel = np.linalg.norm(g - straight, axis=-1) / np.linalg.norm(straight, axis=-1)
    assert rel.max() <= 1e-15 + 1.0 * abs(a) * D.max() / b
    chord = np.arctan2(dst[:, 2] - src[:, 2], np.hypot(*(dst - src)[:, :2].T))
    np.testing.assert_allclose(ray.launch_angle, chord, rtol=0, atol=1e-15 + abs(a) * D.max() / b)
    if a == 0.0:
        np.testing.assert_allclose(ray.time, D / b, rtol=1e-15)


def test_coincident_points() -> None:
    p = np.array([[1.0, 2.0, 30.0], [0.0, 0.0, 0.0]])
    for a in (0.1, -0.1, 0.0):
        ray = iso.eigenray(1500.0, a, p, p)
        np.testing.assert_array_equal(ray.time, 0.0)
        np.testing.assert_array_equal(ray.length, 0.0)
        np.testing.assert_array_equal(iso.travel_time_gradient(1500.0, a, p, p), 0.0)
        np.testing.assert_array_equal(iso.straight_line_time(1500.0, a, p, p), 0.0)


def test_straight_line_time_eq23_and_quadrature() -> None:
    rng = np.random.default_rng(8)
    src, dst = _random_pairs(rng, 40)
    b, a = _profiles(rng, 40)
    tsl = iso.straight_line_time(b, a, src, dst)
    for i in range(40):
        D = float(np.linalg.norm(dst[i] - src[i]))
        # line integral of 1/c along the chord, parametrized by the fraction u of the way
        q, _ = quad(
            lambda u: D / (b[i] + a[i] * (src[i, 2] + u * (dst[i, 2] - src[i, 2]))), 0.0, 1.0, epsabs=0.0, epsrel=1e-13
        )
        assert tsl[i] == pytest.approx(q, rel=1e-12)  # quad asked for 1e-13 relative; 10x margin
    # eq 23 literally (beta_0 the chord angle), away from equal depths
    dz = dst[:, 2] - src[:, 2]
    ok = np.abs(dz) > 1.0
    c1, c2 = b + a * src[:, 2], b + a * dst[:, 2]
    beta0 = np.arcsin(dz / np.linalg.norm(dst - src, axis=-1))
    eq23 = -np.log(c2 / c1) / (a * np.sin(beta0))
    # eq 23 literally cancels: log(c2/c1) with |c2 - c1| >= 0.01 m/s (|a| >= 0.01, |dz| > 1 m)
    # loses c / |c2 - c1| <= 1.5e5 ulps, ~3e-11 relative; 1e-9 leaves a 30x margin
    np.testing.assert_allclose(tsl[ok], np.abs(eq23[ok]), rtol=1e-9)
    # equal depths: distance / c(z)
    flat = src + np.array([1234.0, -55.0, 0.0])
    np.testing.assert_allclose(
        iso.straight_line_time(b, a, src, flat), np.hypot(1234.0, 55.0) / (b + a * src[:, 2]), rtol=1e-15
    )


def test_no_direct_path_surface_and_bottom() -> None:
    """Arcs that leave [0, bottom] are NONE; the ODE ray confirms they do leave the water."""
    b = 1500.0
    # a < 0: rays bend towards the surface; two shallow distant nodes
    src, dst = np.array([0.0, 0.0, 20.0]), np.array([4000.0, 0.0, 30.0])
    ray = iso.eigenray(b, -0.1, src, dst)
    assert ray.path == PathKind.NONE and np.isnan(ray.time) and np.isnan(iso.travel_time(b, -0.1, src, dst))
    ode = ray_ode.shoot(lambda z: b - 0.1 * z, lambda z: -0.1, src, dst, extrema=True)
    assert ode.z_min < 0.0
    assert abs(ray.turning_depth - ode.z_min) <= ray_ode.tolerances(ode)["position"] + _turn_tol(b, 0.1, ode.z_min)
    assert np.all(np.isnan(iso.travel_time_gradient(b, -0.1, src, dst)))
    # a > 0: rays dip; with a bottom at 1000 m two deep distant nodes have no direct arc
    src, dst = np.array([0.0, 0.0, 980.0]), np.array([4000.0, 0.0, 990.0])
    assert iso.eigenray(b, 0.1, src, dst).path == PathKind.DIRECT
    ray = iso.eigenray(b, 0.1, src, dst, bottom=1000.0)
    assert ray.path == PathKind.NONE and ray.turning_depth > 1000.0
    ode = ray_ode.shoot(lambda z: b + 0.1 * z, lambda z: 0.1, src, dst, extrema=True)
    assert abs(ode.z_max - ray.turning_depth) <= ray_ode.tolerances(ode)["position"] + _turn_tol(b, 0.1, ode.z_max)
    # same geometry, deeper bottom: direct
    assert iso.eigenray(b, 0.1, src, dst, bottom=float(ray.turning_depth) + 1.0).path == PathKind.DIRECT
    # end points outside the water column
    assert np.isnan(iso.travel_time(b, 0.1, [0, 0, -1.0], [10, 0, 5.0]))
    assert np.isnan(iso.travel_time(b, 0.1, [0, 0, 5.0], [10, 0, 1001.0], bottom=1000.0))
    # a node on the surface is in the water
    assert np.isfinite(iso.travel_time(b, 0.1, [0, 0, 0.0], [1000, 0, 0.0]))


@pytest.mark.exact
def test_broadcasting_and_array_parameters() -> None:
    rng = np.random.default_rng(2)
    src = np.array([0.0, 0.0, 100.0])
    dst = np.stack(
        [rng.uniform(-2000, 2000, (4, 5)), rng.uniform(-2000, 2000, (4, 5)), rng.uniform(0, 900, (4, 5))], axis=-1
    )
    a = rng.uniform(0.01, 0.1, (4, 5))
    ray = iso.eigenray(1500.0, a, src, dst)
    assert ray.time.shape == (4, 5) and ray.path.shape == (4, 5) and ray.turning_depth.shape == (4, 5)
    assert iso.travel_time_gradient(1500.0, a, src, dst).shape == (4, 5, 3)
    flat = iso.travel_time(1500.0, a.ravel(), np.broadcast_to(src, (20, 3)), dst.reshape(20, 3))
    np.testing.assert_array_equal(flat.reshape(4, 5), iso.travel_time(1500.0, a, src, dst))
    with pytest.raises(ValueError):
        iso.travel_time(1500.0, 0.1, np.zeros(2), np.zeros(3))


# ---------------------------------------------------------------- Hypothesis properties


def _no_underflow(v: float) -> float:
    # offsets below ~1e-150 m square to 0 in D^2 = dx^2 + dy^2 + dz^2: not a physical case
    return v if abs(v) > 1e-100 else 0.0


_xy = st.floats(-3000.0, 3000.0).map(_no_underflow)
_z = st.floats(0.0, 1000.0).map(_no_underflow)
_point = st.tuples(_xy, _xy, _z)
_b = st.floats(1480.0, 1520.0)
_a = st.one_of(st.floats(-0.1, 0.1), st.sampled_from([0.0, 1e-12, -1e-9]))


@given(_point, _point, _b, _a)
def test_symmetry(p: tuple, q: tuple, b: float, a: float) -> None:
    t_pq = iso.travel_time(b, a, p, q)
    t_qp = iso.travel_time(b, a, q, p)
    if np.isnan(t_pq):
        assert np.isnan(t_qp)
    else:
        assert t_pq == pytest.approx(t_qp, rel=1e-13, abs=1e-15)
        r_pq, r_qp = iso.eigenray(b, a, p, q), iso.eigenray(b, a, q, p)
        assert r_pq.length == pytest.approx(r_qp.length, rel=1e-11, abs=1e-12)
        # reversing the ray reverses (and negates) its angles
        assert r_pq.launch_angle == pytest.approx(-r_qp.arrival_angle, abs=1e-12)


@given(_point, _point, _b, _a)
def test_speed_bounds(p: tuple, q: tuple, b: float, a: float) -> None:
    """distance / (max speed the ray meets) <= t <= straight-line time <= distance / (min speed on the chord).

    The lower bound needs the speed at the turning depth too: with a != 0 an arc between two
    equal depths dips into faster water, and for D >> c/|a| t grows only like log(D), so
    t >= D / max(c1, c2) is false in general (e.g. a = 0.1, 5 km at equal depth: t = 0.9954 D/c).
    """
    ray = iso.eigenray(b, a, p, q)
    if ray.path == PathKind.NONE:
        return
    D = math.dist(p, q)
    zs = [p[2], q[2]] + ([] if np.isnan(ray.turning_depth) else [float(ray.turning_depth)])
    c_max = max(b + a * z for z in zs)
    c_min = min(b + a * p[2], b + a * q[2])  # linear c: the chord's extremes are at its ends
    t = float(ray.time)
    assert t >= D / c_max * (1 - 1e-13)
    assert t <= float(iso.straight_line_time(b, a, p, q)) * (1 + 1e-13) + 1e-15
    assert t <= D / c_min * (1 + 1e-13)
    # water-column bound: a ray inside [0, 1000] m never meets a speed above the column's maximum
    assert t >= D / max(b, b + a * 1000.0) * (1 - 1e-13) or ray.turning_depth > 1000.0


def test_strongly_bent_arcs() -> None:
    """Ranges beyond 2 c/|a| (arc turning by more than 90 degrees): the x <= 0 branch of the length."""
    b, a = 1500.0, 0.1
    src = np.array([[0.0, 0.0, 100.0], [0.0, 0.0, 200.0]])
    dst = np.array([[40000.0, 0.0, 100.0], [0.0, 35000.0, 900.0]])
    ray = iso.eigenray(b, a, src, dst)
    assert np.all(np.abs(ray.launch_angle - ray.arrival_angle) > np.pi / 2)
    for i in range(2):
        ode = ray_ode.shoot(lambda z: b + a * z, lambda z: a, src[i], dst[i], extrema=True)
        tol = ray_ode.tolerances(ode)  # plus the closed forms' rounding
        assert abs(ray.time[i] - ode.time) <= tol["time"] + SOLVER_REL * ode.time
        assert abs(ray.length[i] - ode.length) <= tol["length"] + SOLVER_REL * ode.length
        assert abs(ray.turning_depth[i] - ode.z_max) <= tol["position"] + _turn_tol(b, a, ode.z_max)


def test_gradient_matches_paper_eqs_15_to_18() -> None:
    """The paper's route: solve the linear systems (16), (17) for the angle derivatives, then (15), (18)."""
    rng = np.random.default_rng(21)
    src, dst = _random_pairs(rng, 400)
    b, a = _profiles(rng, 400)
    ray = iso.eigenray(b, a, src, dst)
    thA, thT = ray.launch_angle, ray.arrival_angle
    # keep pairs where the paper's forms are well conditioned (sin(theta_T) and 1 - cos(dtheta) not tiny)
    ok = (ray.path == PathKind.DIRECT) & (np.abs(np.sin(thT)) > 0.02) & (np.abs(thT - thA) > 1e-3)
    assert ok.sum() > 100
    src, dst, a, b, thA, thT = src[ok], dst[ok], a[ok], b[ok], thA[ok], thT[ok]
    r = np.hypot(*(dst - src)[:, :2].T)
    zA, zT = src[:, 2], dst[:, 2]
    cA, cT = b + a * zA, b + a * zT
    q = (np.sin(thT) - np.sin(thA)) ** 2 / (1.0 - np.cos(thT - thA))
    P = cT / cA * np.sin(thA) / np.sin(thT)
    rhs16 = -(zT - zA) / r**2 * q  # (16a); (16b): x - P y = 0
    y = rhs16 / (1.0 + P)
    x = P * y
    rhs17a = q / r
    rhs17b = -a / cA * np.cos(thA) / np.sin(thT)
    v = (rhs17a - rhs17b) / (1.0 + P)
    u = rhs17a - v
    dt_dr = -(1.0 / a) * (x / np.cos(thT) - y / np.cos(thA))  # (15a)
    dt_dz = -(1.0 / a) * (u / np.cos(thT) - v / np.cos(thA))  # (15b)
    e_h = (dst - src)[:, :2] / r[:, None]
    paper = np.column_stack([dt_dr * e_h[:, 0], dt_dr * e_h[:, 1], dt_dz])  # (18)
    g = iso.travel_time_gradient(b, a, src, dst)
    err = np.linalg.norm(g - paper, axis=1) / np.linalg.norm(g, axis=1)
    print(f"\npaper eqs 15-18 vs gradient: max rel err {err.max():.2e} over {ok.sum()} pairs")
    assert err.max() <= 1e-7


# ---------------------------------------------------------------- the oracle itself


def test_oracle_interfaces() -> None:
    """Stops at interfaces must not change a smooth profile; across real kinks Snell's invariant holds."""
    b, a = 1500.0, 0.05
    src, dst = np.array([0.0, 0.0, 120.0]), np.array([3500.0, 0.0, 640.0])
    c, dc, ifs = ray_ode.piecewise_linear([0.0, 200.0, 450.0, 2000.0], [b, b + a * 200, b + a * 450, b + a * 2000])
    assert ifs == [200.0, 450.0]
    ode = ray_ode.shoot(c, dc, src, dst, interfaces=ifs)
    assert abs(ode.time - float(iso.travel_time(b, a, src, dst))) <= ode.time_bound + SOLVER_REL * ode.time
    # a sound-speed minimum at 300 m; a ray that turns inside a layer and recrosses an interface
    c, dc, _ = ray_ode.piecewise_linear([0.0, 300.0, 1000.0], [1510.0, 1490.0, 1505.0])
    for dst in (np.array([4000.0, 0.0, 350.0]), np.array([2500.0, 1000.0, 50.0])):
        ode = ray_ode.shoot(c, dc, [0.0, 0.0, 280.0], dst, interfaces=[300.0], extrema=True)
        assert ode.z_end == dst[2]  # shoot reports the receiver's depth, its time corrected to it
        xi0 = math.cos(ode.launch_angle) / c(280.0)
        # Snell's invariant: the arrival angle is off by at most angle_bound, which moves
        # cos(theta) by |sin(theta)| angle_bound; the speeds are exact to rounding
        assert abs(math.cos(ode.arrival_angle) / c(dst[2]) - xi0) <= (
            abs(math.sin(ode.arrival_angle)) * ode.angle_bound / c(dst[2]) + 1e-15 * xi0
        )
    # the brute-force fan finds this eigenray among its arrivals, and none earlier: two oracle
    # rays, so their two time bounds
    rays = ray_ode.fan(c, dc, [0.0, 0.0, 280.0], dst, n=21, interfaces=[300.0])
    assert rays and min(abs(r.time - ode.time) - r.time_bound for r in rays) <= ode.time_bound
    assert rays[0].time <= ode.time + ode.time_bound + rays[0].time_bound
