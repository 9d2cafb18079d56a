"""Linearized least squares: multilateration on ranges and hyperbolic TDOA with a pivot."""

from __future__ import annotations

import numpy as np
import pytest

from aquasim_py.estimation import (
    DegenerateGeometryError,
    InsufficientMeasurementsError,
    multilaterate,
    tdoa_ls,
)

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


def test_tdoa_with_known_depth_needs_four_anchors() -> None:
    A = np.array([[0.0, 0.0, 5.0], [400.0, 0.0, 20.0], [0.0, 400.0, 10.0], [400.0, 400.0, 0.0]])
    x = np.array([150.0, 260.0, 70.0])
    res = tdoa_ls(A, _dist(A, x) / 1500.0, 1500.0, depth=70.0)
    np.testing.assert_allclose(res.x, x, atol=1e-8)
    with pytest.raises(InsufficientMeasurementsError):
        tdoa_ls(A, _dist(A, x) / 1500.0, 1500.0)  # 3 equations, 4 unknowns


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
