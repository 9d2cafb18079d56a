"""Linearized least squares: multilateration on ranges and hyperbolic TDOA with a pivot."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from aquasim_py.estimation import (
    DegenerateGeometryError,
    InsufficientMeasurementsError,
    multilaterate,
    tdoa_ls,
)
from aquasim_py.estimation.lsq import multilateration_covariance

RNG = np.random.default_rng(5)


def _dist(A, x):
    return np.linalg.norm(A - x, axis=1)


@pytest.mark.parametrize("dim, n", [(2, 3), (2, 6), (3, 4), (3, 7)])
def test_multilateration_exact(dim: int, n: int) -> None:
    for _ in range(20):
        A = RNG.uniform(-500, 500, (n, dim)) + 1e4  # far from the origin: tests the pivot shift
        x = RNG.uniform(-500, 500, dim) + 1e4
        np.testing.assert_allclose(multilaterate(A, _dist(A, x)), x, atol=1e-6)


def test_multilateration_with_known_depth_and_surface_anchors() -> None:
    A = np.array([[0.0, 0.0, 0.0], [300.0, 0.0, 0.0], [0.0, 300.0, 0.0]])
    x = np.array([120.0, 80.0, 95.0])
    np.testing.assert_allclose(multilaterate(A, _dist(A, x), depth=95.0), x, atol=1e-9)
    with pytest.raises(DegenerateGeometryError):  # coplanar anchors without the depth
        multilaterate(np.vstack([A, [300.0, 300.0, 0.0]]), _dist(np.vstack([A, [300.0, 300.0, 0.0]]), x))


@pytest.mark.parametrize("dim, n", [(2, 4), (2, 8), (3, 5), (3, 9)])
def test_tdoa_exact(dim: int, n: int) -> None:
    c, t0 = 1500.0, 12.345  # unknown emission time: only differences matter
    for pivot in (0, n - 1):
        A = RNG.uniform(0, 1000, (n, dim))
        x = RNG.uniform(0, 1000, dim)
        res = tdoa_ls(A, t0 + _dist(A, x) / c, c, pivot=pivot)
        np.testing.assert_allclose(res.x, x, atol=1e-6)
        assert res.range_pivot == pytest.approx(_dist(A, x)[pivot], abs=1e-6)


def test_tdoa_one_equation_short_closes_with_chans_quadratic() -> None:
    A = np.array([[0.0, 0.0, 5.0], [400.0, 0.0, 20.0], [0.0, 400.0, 10.0], [400.0, 400.0, 0.0]])
    x = np.array([150.0, 260.0, 70.0])
    res = tdoa_ls(A, _dist(A, x) / 1500.0, 1500.0, depth=70.0)
    np.testing.assert_allclose(res.x, x, atol=1e-8)
    assert res.candidates == ()  # determined: no quadratic needed
    # 3-D, 4 anchors: 3 linear equations for (x, y, z, d_p); the true point is a root
    res = tdoa_ls(A, _dist(A, x) / 1500.0, 1500.0, hint=x + 5.0)
    assert any(np.allclose(c, x, atol=1e-6) for c, _ in res.candidates)
    np.testing.assert_allclose(res.x, x, atol=1e-6)
    assert res.range_pivot == pytest.approx(np.linalg.norm(A[0] - x), abs=1e-6)
    with pytest.raises(InsufficientMeasurementsError):
        tdoa_ls(A[:3], _dist(A[:3], x) / 1500.0, 1500.0)  # 2 equations for 4 unknowns


@pytest.mark.parametrize("n_refs", [3, 4, 5])
def test_tdoa_known_depth_recovers_position(n_refs: int) -> None:
    refs = np.array(
        [[0.0, 0.0, 5.0], [1000.0, 0.0, 15.0], [0.0, 900.0, 30.0], [950.0, 1000.0, 2.0], [500.0, -200.0, 60.0]]
    )
    p = np.array([420.0, 310.0, 140.0])
    ref = refs[:n_refs]
    t_rx = 12.345 + _dist(ref, p) / 1500.0
    res = tdoa_ls(ref, t_rx, 1500.0, depth=p[2], hint=[500.0, 500.0, 140.0])
    np.testing.assert_allclose(res.x, p, atol=1e-6)
    assert res.range_pivot == pytest.approx(np.linalg.norm(ref[0] - p), abs=1e-6)


def test_degenerate_geometries_raise() -> None:
    line = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [5.0, 5.0]])
    with pytest.raises(DegenerateGeometryError):
        multilaterate(line, _dist(line, np.array([3.0, 0.0])))
    plane = np.column_stack([RNG.uniform(0, 100, (6, 2)), np.zeros(6)])
    x = np.array([10.0, 20.0, 30.0])
    with pytest.raises(DegenerateGeometryError):
        tdoa_ls(plane, _dist(plane, x) / 1500, 1500.0)
    with pytest.raises(InsufficientMeasurementsError):
        multilaterate(line[:2], [1.0, 1.0])


def test_refined_multilateration_matches_scipy_least_squares() -> None:
    rng = np.random.default_rng(2)
    refs = np.array([[0.0, 0.0], [70.0, 10.0], [20.0, 60.0], [-30.0, 40.0]])
    truth = np.array([15.0, 20.0])
    r = _dist(refs, truth) + rng.normal(0, 1.0, 4)
    got = multilaterate(refs, r, refine=5)
    ref = least_squares(lambda x: np.linalg.norm(refs - x, axis=1) - r, x0=np.zeros(2)).x
    assert not np.allclose(multilaterate(refs, r), ref, atol=1e-3)  # the linear fix is not the ML fix
    assert np.allclose(got, ref, atol=1e-5)
    assert np.allclose(multilaterate(refs, _dist(refs, truth), refine=5), truth, atol=1e-9)


def test_multilateration_covariance_matches_monte_carlo() -> None:
    """First-order covariance of the linear fix against the sample covariance of 5 000 fixes
    from noisy ranges. The noise (0.1 m at 30-60 m) keeps the second-order bias below 1e-3 of
    the covariance; the sample covariance's own error is about sqrt(2 / 5000) = 2 %, so 8 %
    per entry (of the largest entry) is four of its standard errors."""
    rng = np.random.default_rng(5)
    A = np.array([[0.0, 0.0], [60.0, 5.0], [20.0, 50.0], [70.0, 70.0]])
    x = np.array([30.0, 20.0])
    sd = np.array([0.1, 0.05, 0.1, 0.15])
    r = np.linalg.norm(A - x, axis=1)
    cov = multilateration_covariance(A, r, sd)
    fixes = np.array([multilaterate(A, r + sd * rng.standard_normal(4)) for _ in range(5_000)])
    assert np.allclose(cov, np.cov(fixes.T), rtol=0, atol=0.08 * np.abs(cov).max())


def test_multilateration_covariance_grows_without_bound_as_anchors_become_collinear() -> None:
    """Across the line of nearly collinear anchors the fix is ill-determined (the mirror
    ambiguity); along it, it is not."""
    x = np.array([30.0, 40.0])
    worst = []
    for offset in (20.0, 2.0, 0.2):
        A = np.array([[0.0, 0.0], [50.0, offset], [100.0, 0.0]])
        ev = np.linalg.eigvalsh(multilateration_covariance(A, np.linalg.norm(A - x, axis=1), 0.5))
        worst.append(ev[-1])
        assert ev[0] < 1.0  # along the line: still about the range noise
    assert worst[0] < worst[1] < worst[2] and worst[2] > 100.0 * worst[0]
    with pytest.raises(DegenerateGeometryError):
        multilateration_covariance(np.array([[0.0, 0.0], [50.0, 0.0], [100.0, 0.0]]), [50.0, 40.0, 80.0], 0.5)
