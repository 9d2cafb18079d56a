"""Sign-respecting intervals over runs (issue 35 item 1)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from aquasim_py.reporting import intervals


def _one(values, metric="m", **kw):
    df = pd.DataFrame({"p": ["a"] * len(values), metric: values})
    return intervals.summarize(df, ["p"], [metric], **kw).iloc[0]


def test_a_positive_metric_gets_the_log_scale_interval():
    # the case: two runs of 0.025 m and 0.255 m; Student t gives [-1.3, 1.6]
    v = np.array([0.025, 0.255])
    r = _one(v)
    lv = np.log(v)
    half = stats.t.ppf(0.975, 1) * lv.std(ddof=1) / math.sqrt(2)
    assert r["stat"] == intervals.GEOMETRIC and r["n"] == 2
    assert r["center"] == pytest.approx(math.sqrt(0.025 * 0.255))
    assert (r["low"], r["high"]) == pytest.approx((math.exp(lv.mean() - half), math.exp(lv.mean() + half)))
    assert 0 < r["low"] < r["center"] < r["high"]


def test_a_metric_with_zeros_gets_the_mean_cut_at_zero():
    r = _one([0.0, 0.0, 5.0])
    half = stats.t.ppf(0.975, 2) * np.std([0, 0, 5.0], ddof=1) / math.sqrt(3)
    assert r["stat"] == intervals.MEAN and r["center"] == pytest.approx(5 / 3)
    assert r["low"] == 0.0 and r["high"] == pytest.approx(5 / 3 + half)


def test_a_signed_metric_keeps_the_student_t_interval():
    v = [-1.0, 0.5, 2.0]
    r = _one(v)
    half = stats.t.ppf(0.975, 2) * np.std(v, ddof=1) / math.sqrt(3)
    assert (r["low"], r["high"]) == pytest.approx((0.5 - half, 0.5 + half))


def test_one_run_has_no_interval_and_nan_runs_are_left_out():
    r = _one([3.0, math.nan])
    assert r["n"] == 1 and r["center"] == pytest.approx(3.0) and math.isnan(r["low"]) and math.isnan(r["high"])


def test_the_choice_is_per_metric_over_the_whole_sweep():
    # one point with a zero makes the metric a "mean" metric at every point (one kind per line)
    df = pd.DataFrame({"p": ["a", "a", "b", "b"], "m": [1.0, 2.0, 0.0, 3.0]})
    s = intervals.summarize(df, ["p"], ["m"])
    assert list(s["p"]) == ["a", "b"] and set(s["stat"]) == {intervals.MEAN}


def test_the_log_interval_covers_the_geometric_mean_95_percent_of_the_time():
    # independent check by simulation: lognormal runs, true geometric mean exp(mu)
    rng = np.random.default_rng(7)
    reps, n, mu = 2000, 5, -1.0
    x = np.exp(rng.normal(mu, 0.8, size=(reps, n)))
    df = pd.DataFrame({"rep": np.repeat(np.arange(reps), n), "m": x.ravel()})
    s = intervals.summarize(df, ["rep"], ["m"])
    covered = ((s["low"] <= math.exp(mu)) & (math.exp(mu) <= s["high"])).mean()
    assert abs(covered - 0.95) < 4 * math.sqrt(0.95 * 0.05 / reps)
