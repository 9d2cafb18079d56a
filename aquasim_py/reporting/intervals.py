"""Confidence intervals over Monte Carlo runs that respect a metric's sign (sweep reports).

:func:`aquasim_py.metrics.summarize_runs` gives the mean and the Student-t interval, which for
a few runs of an error can reach below zero (two runs of 0.025 m and 0.255 m: [-1.3, 1.6]).
The reports use :func:`summarize` instead, chosen per metric over the whole sweep:

- **positive in every run** (errors, RMSEs, most counts): the interval is taken on the log
  scale, mean(log x) -/+ t_{(1 + c) / 2, n - 1} std(log x) / sqrt(n), and mapped back with
  exp: an interval for the *geometric* mean exp(mean(log x)), which is the centre shown. Both
  bounds are positive, and on a log axis the interval is symmetric about the centre;
- **otherwise**: the arithmetic mean with the Student-t interval; when the metric is never
  negative in the sweep (a count that is sometimes 0), the interval is cut at 0. Since the
  true mean of such a metric is >= 0, the cut interval covers it exactly as often.

One run (n = 1) has no interval (NaN bounds); a constant metric has a zero-width one.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

__all__ = ["GEOMETRIC", "MEAN", "summarize"]

GEOMETRIC = "geometric mean"
MEAN = "mean"


def summarize(
    runs: pd.DataFrame, by: Sequence[str], metrics: Sequence[str], *, confidence: float = 0.95
) -> pd.DataFrame:
    """One row per (group of ``by``, metric) with finite values: the ``by`` columns,
    ``metric``, ``n``, ``stat`` (:data:`GEOMETRIC` or :data:`MEAN`), ``center``, ``low`` and
    ``high`` (the ``confidence`` interval). Groups keep their order of first appearance."""
    from scipy import stats

    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence!r}")
    by = list(by)
    long = runs.melt(id_vars=by, value_vars=list(metrics), var_name="metric", value_name="value")
    long["value"] = pd.to_numeric(long["value"], errors="coerce")
    long = long[np.isfinite(long["value"].to_numpy(float))]
    cols = [*by, "metric", "n", "stat", "center", "low", "high"]
    if long.empty:
        return pd.DataFrame(columns=cols)
    per_metric = long.groupby("metric", sort=False)["value"]
    positive = per_metric.min() > 0.0  # per metric, over the whole sweep
    nonneg = per_metric.min() >= 0.0
    geo = long["metric"].map(positive).to_numpy(bool)
    with np.errstate(divide="ignore"):
        long["x"] = np.where(geo, np.log(np.where(geo, long["value"], 1.0)), long["value"])
    g = long.groupby([*by, "metric"], sort=False, dropna=False)["x"]
    out = g.agg(n="count", m="mean", s="std").reset_index()
    n = out["n"].to_numpy(float)
    half = np.full(len(out), np.nan)
    ok = n >= 2
    half[ok] = stats.t.ppf(0.5 + confidence / 2.0, n[ok] - 1.0) * out["s"].to_numpy(float)[ok] / np.sqrt(n[ok])
    m = out["m"].to_numpy(float)
    lo, hi = m - half, m + half
    is_geo = out["metric"].map(positive).to_numpy(bool)
    cut = out["metric"].map(nonneg).to_numpy(bool) & ~is_geo
    out["stat"] = np.where(is_geo, GEOMETRIC, MEAN)
    out["center"] = np.where(is_geo, np.exp(m), m)
    out["low"] = np.where(is_geo, np.exp(lo), np.where(cut, np.maximum(lo, 0.0), lo))
    out["high"] = np.where(is_geo, np.exp(hi), hi)
    out["n"] = out["n"].astype(int)
    return out[cols]
