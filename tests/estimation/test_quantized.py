"""Quantized Gaussian measurements: level probabilities against numerical integration, MI
limits on hand-made particle sets, Fisher information against closed forms."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad
from scipy.stats import norm

from aquasim_py.estimation import (
    level_probabilities,
    mutual_information,
    quantize,
    quantized_fisher_scale,
    quantized_log_likelihood,
    quantized_mutual_information,
)


def test_level_probabilities_match_numerical_integration() -> None:
    gam = np.array([-3.0, 0.5, 4.0])
    h, s = 1.2, 2.0
    P = level_probabilities(h, s, gam)
    edges = [-60.0, *gam, 60.0]  # +-60 is ~30 sigma: the cut tails are below 1e-190
    ref = [quad(lambda z: norm.pdf(z, h, s), a, b, epsabs=1e-14)[0] for a, b in itertools.pairwise(edges)]
    np.testing.assert_allclose(P, ref, rtol=1e-9, atol=1e-14)


def test_far_tail_keeps_relative_accuracy() -> None:
    # h 40 sigma below the top threshold: P(top) = Q(40) ~ 3.7e-350 underflows, but 20 sigma is exact
    P = level_probabilities(0.0, 1.0, [20.0])
    np.testing.assert_allclose(P[1], norm.sf(20.0), rtol=1e-10)
    assert np.isfinite(quantized_log_likelihood(1, 0.0, 1.0, [40.0]))


@settings(max_examples=25, deadline=None)
@given(
    h=st.floats(-50, 50),
    s=st.floats(0.1, 20),
    gam=st.lists(st.floats(-40, 40), min_size=1, max_size=7, unique=True),
)
def test_probabilities_are_a_distribution(h: float, s: float, gam: list[float]) -> None:
    g = np.sort(np.array(gam))
    if np.any(np.diff(g) <= 1e-9):
        return
    P = level_probabilities(h, s, g)
    assert np.all(P >= 0)
    assert P.sum() == pytest.approx(1.0, abs=1e-12)
    lv = quantize(h, g)
    assert 0 <= lv < len(g) + 1


def test_mi_is_zero_when_the_level_cannot_depend_on_the_state() -> None:
    # every particle predicts the same pressure (e.g. on a circle around the sensor)
    P = level_probabilities(np.full(500, 7.0), 2.0, [0.0, 5.0, 10.0])
    assert mutual_information(P) == pytest.approx(0.0, abs=1e-12)
    # or the thresholds are so far out that every particle gives level 0 for sure
    P = level_probabilities(np.linspace(-5, 5, 500), 1.0, [1e4])
    assert mutual_information(P) == pytest.approx(0.0, abs=1e-12)


def test_mi_is_largest_where_the_binary_quantizer_splits_the_prediction() -> None:
    """Particles spread evenly over h in c +- 20 (sigma 1), one threshold at 0: the MI peaks
    when the threshold is mid-spread (c = 0) and is then close to log 2 (an almost
    deterministic fair bit); it decreases as the threshold moves to the edge."""
    cs = np.linspace(-30, 30, 61)
    mi = np.array([mutual_information(level_probabilities(c + np.linspace(-20, 20, 2001), 1.0, [0.0])) for c in cs])
    assert cs[np.argmax(mi)] == 0.0
    # a fraction ~ (sigma * 2 / sqrt(2 pi)) / 40 of particles is uncertain: entropy loss <= 0.05
    assert np.log(2) - 0.05 < mi.max() <= np.log(2)
    assert np.all(np.diff(mi[cs >= 0]) <= 1e-12)
    assert mi[0] == pytest.approx(0.0, abs=1e-9)


def test_binary_fisher_closed_form_and_dense_limit() -> None:
    # one threshold at h: 4 phi(0)^2 / sigma^2 = 2 / (pi sigma^2)
    assert quantized_fisher_scale(3.0, 2.0, [3.0]) == pytest.approx(2.0 / (np.pi * 4.0), rel=1e-12)
    # dense thresholds (step 0.02 sigma): the unquantized 1/sigma^2, up to ~step^2/12 relative
    g = np.arange(-40.0, 40.0, 0.04)
    assert quantized_fisher_scale(0.3, 2.0, g) == pytest.approx(0.25, rel=1e-3)


def test_fused_mi_equals_mi_of_the_level_probabilities() -> None:
    """quantized_mutual_information skips edges beyond 12 sigma (bins of probability < 2e-33):
    it must equal eq 23 on the full level probabilities to ~1e-30 nats, also for particles
    spread over many bins and for a sensor whose particles all sit deep inside one bin."""
    rng = np.random.default_rng(4)
    g = np.linspace(300.0, 1000.0, 8)
    h = np.stack([rng.uniform(200, 1100, 500), rng.normal(650.0, 3.0, 500), rng.normal(300.0, 4.0, 500)])
    s = rng.uniform(2.0, 8.0, h.shape)
    ref = mutual_information(level_probabilities(h, s, g))
    np.testing.assert_allclose(quantized_mutual_information(h, s, g), ref, rtol=0, atol=1e-25)
    assert ref[0] > 1.0 and ref[1] < 1e-6  # many bins vs one: the cases differ
