"""Gauss-Newton ToF localization (Ramezani et al., Algorithm 1) on the straight-ray model."""

from __future__ import annotations

import numpy as np
import pytest

from aquasim_py.channel import Constant, travel_time, travel_time_gradient
from aquasim_py.estimation import (
    DegenerateGeometryError,
    InsufficientMeasurementsError,
    constant_speed_tof,
    crb,
    gauss_newton,
    gauss_newton_batch,
    tof_model,
)

C = Constant(1500.0)
# four vertices of a 100 m cube forming a regular tetrahedron: centroid at the cube centre
ANCHORS = np.array([[0.0, 0.0, 0.0], [100.0, 100.0, 0.0], [100.0, 0.0, 100.0], [0.0, 100.0, 100.0]])
CENTROID = ANCHORS.mean(axis=0)


def tt(src, dst):
    return travel_time(C, src, dst)


def tg(src, dst):
    return travel_time_gradient(C, src, dst)


@pytest.mark.parametrize("target", [[50.0, 50.0, 50.0], [61.0, 37.0, 55.0], [20.0, 80.0, 5.0], [150.0, -20.0, 60.0]])
def test_recovers_position_from_exact_times(target) -> None:
    x = np.array(target)
    t = tt(ANCHORS, x)
    res = gauss_newton(tof_model(ANCHORS, t, tt, tg, sigma=1e-3), CENTROID + [3.0, -2.0, 1.0], max_iter=30, tol=1e-12)
    assert res.method == "gauss-newton" and res.converged
    np.testing.assert_allclose(res.x, x, atol=1e-9)
    # paper's settings (K = 7, eps = 1e-3) already get within ~1e-6 m near the centroid
    res7 = gauss_newton(tof_model(ANCHORS, t, tt, tg), CENTROID)
    assert np.linalg.norm(res7.x - x) < 1e-4


def test_noisy_estimates_sit_on_the_crb() -> None:
    """Monte Carlo (vectorized over draws): GN's error covariance equals the CRB (eq 33)."""
    rng = np.random.default_rng(11)
    B, sig = 3000, 5e-5
    x = np.array([55.0, 42.0, 47.0])
    t = tt(ANCHORS, x) + sig * rng.standard_normal((B, 4))
    X, iters, ok = gauss_newton_batch(tof_model(ANCHORS, t, tt, tg, sigma=sig), np.tile(CENTROID, (B, 1)))
    assert ok.all() and iters.max() <= 7
    err = X - x
    bound = crb(tg(ANCHORS, x), np.full(4, sig**2))
    mse = np.mean(np.sum(err**2, axis=1))
    assert mse == pytest.approx(np.trace(bound), rel=0.08)
    # the whole error covariance, not only its trace
    np.testing.assert_allclose(np.cov(err.T), bound, atol=0.1 * np.trace(bound))
    # the batch iterates are exactly those of the single-problem solver
    single = gauss_newton(tof_model(ANCHORS, t[0], tt, tg, sigma=sig), CENTROID, fallback=False)
    np.testing.assert_allclose(X[0], single.x, rtol=0, atol=1e-12)


def test_depth_measurement_with_surface_anchors() -> None:
    """Anchors all at the surface: the ToFs alone leave a mirror image above the surface; the
    depth residual (eq 37) pins the depth."""
    A = np.array([[0.0, 0.0, 0.0], [200.0, 0.0, 0.0], [0.0, 200.0, 0.0], [200.0, 200.0, 0.0]])
    x = np.array([70.0, 120.0, 80.0])
    fun = tof_model(A, tt(A, x), tt, tg, sigma=1e-4, depth=80.0, sigma_depth=0.1)
    res = gauss_newton(fun, [100.0, 100.0, 10.0], max_iter=20, tol=1e-10)
    np.testing.assert_allclose(res.x, x, atol=1e-8)
    r, J = fun(res.x)
    assert r.shape == (5,) and J.shape == (5, 3)


def test_collinear_anchors_raise() -> None:
    A = np.array([[0.0, 0.0, 0.0], [50.0, 0.0, 0.0], [100.0, 0.0, 0.0], [150.0, 0.0, 0.0]])
    x = np.array([60.0, 40.0, 30.0])
    with pytest.raises(DegenerateGeometryError):
        gauss_newton(tof_model(A, tt(A, x), tt, tg), [70.0, 30.0, 20.0])


def test_target_on_the_anchor_plane_raises() -> None:
    A = np.array([[0.0, 0.0, 10.0], [100.0, 0.0, 10.0], [0.0, 100.0, 10.0], [100.0, 100.0, 10.0]])
    x = np.array([30.0, 60.0, 10.0])
    with pytest.raises(DegenerateGeometryError):
        gauss_newton(tof_model(A, tt(A, x), tt, tg), [50.0, 50.0, 10.0])


def test_constant_speed_model_equals_channel_straight_rays() -> None:
    t_fn, g_fn = constant_speed_tof(C.speed_mps)
    X = np.random.default_rng(0).uniform(0, 150, (20, 1, 3))  # in the water (z >= 0)
    np.testing.assert_allclose(t_fn(ANCHORS, X), tt(ANCHORS, X), rtol=1e-15)
    np.testing.assert_allclose(g_fn(ANCHORS, X), tg(ANCHORS, X), rtol=1e-15)


def test_per_draw_sigma_broadcasts() -> None:
    x = np.array([[40.0, 60.0, 50.0], [55.0, 45.0, 52.0]])
    t = tt(ANCHORS, x[:, None, :])
    sig = np.array([[1e-4, 2e-4, 3e-4, 4e-4], [1e-3, 1e-3, 2e-3, 2e-3]])
    r, J = tof_model(ANCHORS, t, tt, tg, sigma=sig)(x + 1.0)
    np.testing.assert_allclose(J, tg(ANCHORS, (x + 1.0)[:, None, :]) / sig[..., None])
    np.testing.assert_allclose(r, (tt(ANCHORS, (x + 1.0)[:, None, :]) - t) / sig)


def test_too_few_measurements_raise() -> None:
    A = ANCHORS[:2]
    with pytest.raises(InsufficientMeasurementsError):
        gauss_newton(tof_model(A, tt(A, CENTROID), tt, tg), CENTROID + 1.0)


def test_lm_fallback_when_gauss_newton_diverges() -> None:
    # r(x) = atan(x): the GN step x - atan(x)(1 + x^2) overshoots without bound for |x0| > 1.39
    def fun(x):
        return (np.arctan(x), (1.0 / (1.0 + x**2)).reshape(1, 1))

    res = gauss_newton(fun, [3.0], max_iter=7, tol=1e-10)
    assert res.method == "levenberg-marquardt"
    assert abs(res.x[0]) < 1e-8
    assert np.all(np.isfinite(res.cov))


def test_step_leaving_the_domain_is_shortened() -> None:
    # r = log(x): the first full GN step from x = 5 lands at x < 0, where the model is undefined
    def fun(x):
        return (np.log(x), (1.0 / x).reshape(1, 1))

    with np.errstate(invalid="ignore"):
        res = gauss_newton(fun, [5.0], max_iter=20, tol=1e-12)
    assert res.method == "gauss-newton" and res.converged
    assert res.x[0] == pytest.approx(1.0, abs=1e-12)


def test_lm_fallback_on_singular_start() -> None:
    # r = [x^2 + y - 3, x + y^2 - 5] has a root at (1, 2); J = [[2x, 1], [1, 2y]] is singular at (0.5, 0.5)
    def fun(v):
        x, y = v
        return np.array([x * x + y - 3.0, x + y * y - 5.0]), np.array([[2 * x, 1.0], [1.0, 2 * y]])

    res = gauss_newton(fun, [0.5, 0.5], tol=1e-12)
    assert res.method == "levenberg-marquardt"
    np.testing.assert_allclose(fun(res.x)[0], 0.0, atol=1e-10)


def test_batch_flags_singular_rows_without_nan() -> None:
    A = np.array([[0.0, 0.0, 10.0], [100.0, 0.0, 10.0], [0.0, 100.0, 10.0], [100.0, 100.0, 10.0]])
    x = np.array([[30.0, 60.0, 40.0], [30.0, 60.0, 10.0]])
    X, _, ok = gauss_newton_batch(
        tof_model(A, tt(A, x[:, None, :]), tt, tg), [[50.0, 50.0, 30.0], [50.0, 50.0, 10.0]], tol=1e-9, max_iter=20
    )
    assert ok.tolist() == [True, False]
    assert np.all(np.isfinite(X))
    np.testing.assert_allclose(X[0], x[0], atol=1e-8)
