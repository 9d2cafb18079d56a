"""Tests of aquasim_py.clock against closed forms, brute-force sums and sampling statistics."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aquasim_py.clock import Clock


def rng(seed: int = 0) -> np.random.Generator:
    return np.random.default_rng(seed)


# -- affine clock ---------------------------------------------------------------------------------


def test_affine_clock_matches_closed_form() -> None:
    c = Clock(skew=40e-6, offset=-2.5)
    t = np.array([0.0, 1.0, 123.456, 1e5])
    expected = np.array([(1 + 40e-6) * x - 2.5 for x in t])
    np.testing.assert_allclose(c.to_local(t), expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(c.to_true(expected), t, rtol=0, atol=1e-10)
    assert isinstance(c.to_local(3.0), float)
    assert c.skew_at(7.0) == 40e-6 and c.offset_at(7.0) == -2.5


def test_perfect_clock_is_true_time() -> None:
    c = Clock.perfect()
    t = np.linspace(0.0, 1e4, 17)
    assert np.array_equal(c.to_local(t), t)
    assert np.array_equal(c.to_true(t), t)
    assert np.array_equal(c.stamp(t), t)


def test_vectorized_shapes() -> None:
    c = Clock(skew=1e-5, offset=1.0, drift_std=1e-6, rng=rng())
    t = np.arange(12.0).reshape(3, 4) * 7.0
    assert c.to_local(t).shape == (3, 4)
    assert c.to_true(c.to_local(t)).shape == (3, 4)
    assert c.skew_at(t).shape == (3, 4)


# -- drift ----------------------------------------------------------------------------------------


def brute_force_local(c: Clock, t: float) -> float:
    """Offset plus a sum over whole drift steps of (1 + skew) * interval, then the partial step."""
    d = c.drift_interval
    k = int(math.floor(t / d))
    total = c.offset
    for j in range(k):
        total += (1.0 + c.skew_at((j + 0.5) * d)) * d
    return total + (1.0 + c.skew_at(t)) * (t - k * d)


def test_drift_is_the_exact_piecewise_linear_integral() -> None:
    c = Clock(skew=30e-6, offset=0.7, drift_std=2e-6, drift_interval=5.0, rng=rng(1))
    for t in [0.0, 2.5, 5.0, 49.999, 400.0, 1234.5]:
        assert c.to_local(t) == pytest.approx(brute_force_local(c, t), abs=1e-9)
    # The skew really changes between steps (the walk is not a no-op).
    skews = c.skew_at(np.arange(0.0, 1000.0, 5.0))
    assert np.unique(skews).size > 100
    # local = (1 + skew_at) t + offset_at holds segment by segment.
    t = np.linspace(0.0, 3000.0, 101)
    np.testing.assert_allclose(c.to_local(t), (1 + c.skew_at(t)) * t + c.offset_at(t), rtol=0, atol=1e-9)


def test_drift_is_continuous_across_steps() -> None:
    c = Clock(skew=0.0, drift_std=1e-4, drift_interval=2.0, rng=rng(2))
    k = np.arange(1, 400) * 2.0
    eps = 1e-7
    jump = c.to_local(k + eps) - c.to_local(k - eps)
    expected = eps * (2.0 + c.skew_at(k - eps) + c.skew_at(k + eps))
    np.testing.assert_allclose(jump, expected, rtol=1e-5)


@settings(max_examples=60)
@given(
    skew=st.floats(-1e-3, 1e-3),
    offset=st.floats(-100.0, 100.0),
    drift_std=st.sampled_from([0.0, 1e-7, 1e-5, 1e-4]),
    interval=st.floats(0.5, 50.0),
    seed=st.integers(0, 2**32 - 1),
    times=st.lists(st.floats(0.0, 2e4), min_size=1, max_size=30),
)
def test_to_true_inverts_to_local(skew, offset, drift_std, interval, seed, times) -> None:
    c = Clock(skew=skew, offset=offset, drift_std=drift_std, drift_interval=interval, rng=rng(seed))
    t = np.array(times)
    local = c.to_local(t)
    np.testing.assert_allclose(c.to_true(local), t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(c.to_local(c.to_true(local)), local, rtol=0, atol=1e-9)


@settings(max_examples=30)
# The largest step still keeps the walk ~15 sigma away from skew = -1 over the test span.
@given(seed=st.integers(0, 2**32 - 1), drift_std=st.sampled_from([1e-6, 1e-4, 1e-3]))
def test_monotone_increasing(seed, drift_std) -> None:
    c = Clock(skew=-2e-4, offset=3.0, drift_std=drift_std, drift_interval=1.0, rng=rng(seed))
    gen = rng(seed + 1)
    t = np.cumsum(gen.uniform(1e-6, 3.0, 3000))
    local = c.to_local(t)
    assert np.all(np.diff(local) > 0)


def test_query_order_does_not_change_the_clock() -> None:
    gen = rng(5)
    t = gen.uniform(0.0, 5e4, 2000)
    a = Clock(skew=1e-5, drift_std=1e-6, drift_interval=3.0, jitter_std=1e-4, rng=rng(9))
    b = Clock(skew=1e-5, drift_std=1e-6, drift_interval=3.0, jitter_std=1e-4, rng=rng(9))
    order = gen.permutation(t.size)
    # b sees shuffled queries one at a time, with stamps (jitter draws) in between.
    shuffled = np.empty_like(t)
    for i in order:
        b.stamp(t[i])
        shuffled[i] = b.to_local(t[i])
    sorted_idx = np.argsort(t)
    in_order = np.empty_like(t)
    in_order[sorted_idx] = a.to_local(t[sorted_idx])
    assert np.array_equal(shuffled, in_order)
    locals_ = in_order[:50]
    assert np.array_equal(a.to_true(locals_), b.to_true(locals_))


def test_same_seed_same_clock_other_seed_other_clock() -> None:
    t = np.linspace(0.0, 1e4, 50)
    a = Clock(drift_std=1e-6, rng=rng(3)).to_local(t)
    b = Clock(drift_std=1e-6, rng=rng(3)).to_local(t)
    c = Clock(drift_std=1e-6, rng=rng(4)).to_local(t)
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)


def test_drift_statistics() -> None:
    sigma, interval = 2e-6, 10.0
    c = Clock(skew=1e-5, drift_std=sigma, drift_interval=interval, rng=rng(11))
    steps = np.diff(c.skew_at((np.arange(20001) + 0.5) * interval))
    assert abs(steps.mean()) < 4 * sigma / math.sqrt(steps.size)
    assert steps.std() == pytest.approx(sigma, rel=0.03)
    # Across independent clocks, the skew after K steps spreads as sigma * sqrt(K).
    k = 100
    final = np.array(
        [
            Clock(drift_std=sigma, drift_interval=interval, rng=rng(1000 + i)).skew_at(k * interval + 1.0)
            for i in range(1500)
        ]
    )
    assert final.std() == pytest.approx(sigma * math.sqrt(k), rel=0.06)


def test_stamp_jitter_statistics() -> None:
    c = Clock(skew=2e-5, offset=1.0, jitter_std=3e-4, rng=rng(12))
    t = np.linspace(0.0, 1000.0, 40000)
    noise = c.stamp(t) - c.to_local(t)
    assert abs(noise.mean()) < 4 * 3e-4 / math.sqrt(t.size)
    assert noise.std() == pytest.approx(3e-4, rel=0.02)
    assert isinstance(c.stamp(1.0), float)


# -- validation -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(skew=-1.0), "skew"),
        (dict(skew=float("nan")), "skew"),
        (dict(offset=float("inf")), "offset"),
        (dict(drift_std=-1e-6), "drift_std"),
        (dict(drift_interval=0.0), "drift_interval"),
        (dict(jitter_std=-1.0), "jitter_std"),
        (dict(drift_std=1e-6), "rng"),
        (dict(jitter_std=1e-6), "rng"),
        (dict(rng=np.random.RandomState(0)), "Generator"),
    ],
)
def test_invalid_parameters(kwargs, match) -> None:
    with pytest.raises(ValueError, match=match):
        Clock(**kwargs)


def test_invalid_times() -> None:
    c = Clock(skew=1e-5, drift_std=1e-6, rng=rng())
    with pytest.raises(ValueError, match="finite"):
        c.to_local(float("nan"))
    with pytest.raises(ValueError, match="finite"):
        c.to_true(np.array([1.0, np.inf]))


def test_runaway_drift_is_reported() -> None:
    c = Clock(drift_std=0.5, drift_interval=1.0, rng=rng(0))
    with pytest.raises(ValueError, match="-1"):
        c.to_local(1e5)


@pytest.mark.parametrize("drift_std", [0.0, 1e-6])
def test_scalar_and_array_queries_agree_exactly(drift_std) -> None:
    c = Clock(skew=3e-5, offset=-4.0, drift_std=drift_std, drift_interval=7.0, rng=rng(21))
    t = rng(22).uniform(0.0, 1e4, 200)
    vector = c.to_local(t)
    assert np.array_equal(vector, [c.to_local(float(x)) for x in t])
    assert np.array_equal(vector, [c.to_local(x) for x in t])  # numpy scalars
    assert np.array_equal(c.to_true(vector), [c.to_true(float(x)) for x in vector])
