"""The per-link arrival cache (aquasim_py.channel.arrival_cache) against the exact search."""

from __future__ import annotations

import numpy as np
import pytest
from test_rangedep import _front_env

from aquasim_py.channel.arrival_cache import ArrivalCache
from aquasim_py.channel.arrivals import arrivals


def _links(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    s = np.c_[rng.uniform(0, 6000, n), rng.uniform(-2000, 2000, n), rng.uniform(5, 140, n)]
    d = np.c_[rng.uniform(0, 6000, n), rng.uniform(-2000, 2000, n), rng.uniform(5, 140, n)]
    return s, d


def test_served_delays_within_bound_and_1e7() -> None:
    """Random moves of both ends inside the region the cache serves (a front over a slope,
    every arrival up to 2 bounces): each served delay is within the cache's bound of the exact
    search's, the bound is <= 1e-7 s, and the served arrival sets equal the exact ones."""
    env = _front_env()
    rng = np.random.default_rng(3)
    n = 40
    s, d = _links(rng, n)
    ids = np.arange(n)
    cache = ArrivalCache(env, n, max_bounces=2, tol_s=1e-7)
    cache.get(ids, s, d)
    served = 0
    for _ in range(4):
        radius = cache.radius(ids)
        u = rng.normal(size=(n, 6))
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        f = (rng.uniform(0, 1, n) * radius)[:, None]
        s2, d2 = s + u[:, :3] * f, d + u[:, 3:] * f
        bound = cache.bound(ids, s2, d2)
        before = cache.stats.hits
        got = cache.get(ids, s2, d2)
        served += cache.stats.hits - before
        exact = arrivals(env, s2, d2, max_bounces=2)
        np.testing.assert_array_equal(got.offsets, exact.offsets)
        np.testing.assert_array_equal(got.bounce_code, exact.bounce_code)
        b = bound[got.link]
        ok = np.isfinite(b)
        assert np.all(np.abs(got.delay - exact.delay)[ok] <= b[ok])
        assert np.all(b[ok] <= 1e-7)
    assert served >= n  # most links are served


def test_moves_beyond_the_bound_are_solved_again() -> None:
    env = _front_env()
    rng = np.random.default_rng(4)
    s, d = _links(rng, 10)
    ids = np.arange(10)
    cache = ArrivalCache(env, 10, max_bounces=1)
    cache.get(ids, s, d)
    moved = d + np.array([5.0, 0.0, 0.0])
    got = cache.get(ids, s, moved)
    assert cache.stats.hits == 0 and cache.stats.misses == 20
    exact = arrivals(env, s, moved, max_bounces=1)
    np.testing.assert_allclose(got.delay, exact.delay, rtol=0, atol=1e-12)


def test_bad_ids() -> None:
    cache = ArrivalCache(_front_env(), 3)
    with pytest.raises(ValueError, match="link ids"):
        cache.get([5], [[0, 0, 10]], [[100, 0, 10]])
    with pytest.raises(ValueError, match="twice"):
        cache.get([1, 1], [[0, 0, 10]] * 2, [[100, 0, 10]] * 2)
