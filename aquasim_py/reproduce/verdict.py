"""Our number for a claim, its 95 % confidence interval over seeds, and the verdict.

Means and paired mean differences get Student-t intervals (scipy); every other statistic (an
RMS over runs, MSWPF's time average of per-interval RMSEs, a ratio, a gap in %) a percentile
bootstrap over the seeds, resampling the runs of both quantities together (they are paired:
the same seeds), from a fixed generator so that the same rows always give the same interval.
Where the paper's number is one example run, the comparison is with a 95 % prediction interval
of one run (normal theory: mean +- t s sqrt(1 + 1/n)). Below :data:`~.claims.MIN_RUNS` runs
there is no verdict on any path ("too few runs").
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .claims import MIN_RUNS, REL_TOL, Claim, Statistic

__all__ = ["BELOW_BOUND", "VERDICTS", "Outcome", "evaluate"]

BOOTSTRAP = 4000
CONFIDENCE = 0.95
#: every verdict a row can have ("-": a reference, or no data)
VERDICTS = ("holds", "does not hold", "inconclusive", "too few runs", "-")
#: the flag of a ratio to a lower bound that lies below 1 beyond its CI
BELOW_BOUND = "below the bound: check the bound's assumptions"

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Outcome:
    ours: float
    low: float  #: 95 % CI of ``ours``
    high: float
    n: int  #: runs (seeds) used
    verdict: str  #: one of :data:`VERDICTS`
    pi_low: float = math.nan  #: 95 % prediction interval of one run (claims on one example run)
    pi_high: float = math.nan
    paper_in_ci: bool | None = None  #: the paper's number inside the CI (None: no number, or too few runs)
    paper_in_pi: bool | None = None  #: ... inside the prediction interval (claims on one example run)
    flag: str = ""  #: :data:`BELOW_BOUND` or ""


def stat(x: Array, how: Statistic) -> Array:
    """The statistic over runs: ``x`` is (..., runs) per-run values, or (..., runs, intervals)
    per-interval series for ``time_mean_rms`` and ``interval_mean`` (NaN intervals left out;
    ``interval_mean`` keeps the intervals axis)."""
    if how == "interval_mean":
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return np.asarray(np.nanmean(x, axis=-2))
    if how == "time_mean_rms":
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # an interval no resampled run reached
            return np.asarray(np.nanmean(np.sqrt(np.nanmean(x**2, axis=-2)), axis=-1))
    if how == "rms":
        return np.asarray(np.sqrt(np.mean(x**2, axis=-1)))
    return np.asarray(np.mean(x, axis=-1))


def _reduce(v: Array, how: str) -> Array:
    """Per-interval numbers (last axis) to one: their largest or their median (NaN left out)."""
    if not how:
        return v
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # an all-NaN resample
        return np.asarray(np.nanmax(v, axis=-1) if how == "max" else np.nanmedian(v, axis=-1))


def _t_interval(x: Array, predict: bool = False) -> tuple[float, float, float]:
    """Mean and its 95 % t-interval; ``predict``: the prediction interval of one more value."""
    from scipy import stats

    m = float(np.mean(x))
    if x.size < 2:
        return m, math.nan, math.nan
    spread = math.sqrt(1.0 + 1.0 / x.size) if predict else 1.0 / math.sqrt(x.size)
    half = float(stats.t.ppf(0.5 + CONFIDENCE / 2, x.size - 1) * np.std(x, ddof=1) * spread)
    return m, m - half, m + half


def _bootstrap(a: Array, b: Array | None, f: Callable[[Array, Array | None], Array]) -> tuple[float, float]:
    """Percentile interval of ``f(a, b)`` over resamples of the runs (first axis of a and b),
    vectorized: ``f`` gets (resamples, runs[, intervals]) arrays."""
    rng = np.random.default_rng(20180808)
    idx = rng.integers(0, a.shape[0], size=(BOOTSTRAP, a.shape[0]))
    vals = np.asarray(f(a[idx], None if b is None else b[idx]))
    vals = vals[np.isfinite(vals)]
    if vals.size == 0:
        return math.nan, math.nan
    q = np.quantile(vals, [0.5 - CONFIDENCE / 2, 0.5 + CONFIDENCE / 2])
    return float(q[0]), float(q[1])


def _band(paper: float, low: float, high: float) -> str:
    """``value``-like verdict: the CI inside the paper's +-REL_TOL band, outside it, or across."""
    lo, hi = sorted((paper * (1 - REL_TOL), paper * (1 + REL_TOL)))
    if not (math.isfinite(low) and math.isfinite(high)):
        return "inconclusive"
    if lo <= low and high <= hi:
        return "holds"
    if high < lo or low > hi:
        return "does not hold"
    return "inconclusive"


def _inside(v: float, low: float, high: float) -> bool | None:
    return bool(low <= v <= high) if math.isfinite(low) and math.isfinite(high) else None


def _valid(x: Array) -> NDArray[np.bool_]:
    """Runs with a value: finite, or (a series) with any finite interval."""
    return np.asarray(np.isfinite(x) if x.ndim == 1 else np.isfinite(x).any(axis=1), dtype=bool)


def evaluate(
    claim: Claim,
    a: Array,
    b: Array | None,
    sa: Statistic | None = None,
    sb: Statistic | None = None,
) -> Outcome:
    """The outcome of ``claim`` from its quantities' per-seed values (paired by index; a run
    missing in either is dropped, as is a non-finite value). ``a`` / ``b``: (runs,) values or
    (runs, intervals) series; ``sa`` / ``sb``: their statistics (default: the claim's)."""
    a = np.asarray(a, float)
    ok = _valid(a)
    if b is not None:
        b = np.asarray(b, float)
        ok &= _valid(b)
        b = b[ok]
    a = a[ok]
    n = int(a.shape[0])
    if n == 0:
        return Outcome(math.nan, math.nan, math.nan, 0, "-")
    sa = sa or claim.a.statistic
    enough = n >= MIN_RUNS
    if claim.kind in ("value", "reference"):
        if sa == "mean":
            ours, low, high = _t_interval(a)
        else:
            ours = float(_reduce(stat(a, sa), claim.reduce))
            low, high = _bootstrap(a, None, lambda x, _: _reduce(stat(x, sa), claim.reduce))
        if claim.kind == "reference" or claim.paper is None:
            return Outcome(ours, low, high, n, "-")
        if not enough:
            return Outcome(ours, low, high, n, "too few runs")
        in_ci = _inside(claim.paper, low, high)
        if claim.paper_runs == "one":
            if sa != "mean":
                raise ValueError(f"claim {claim.id!r}: a prediction interval needs the mean statistic")
            _, plo, phi = _t_interval(a, predict=True)
            in_pi = _inside(claim.paper, plo, phi)
            verdict = "inconclusive" if in_pi is None else "holds" if in_pi else "does not hold"
            return Outcome(ours, low, high, n, verdict, plo, phi, in_ci, in_pi)
        return Outcome(ours, low, high, n, _band(claim.paper, low, high), paper_in_ci=in_ci)
    assert b is not None and claim.b is not None
    sb = sb or claim.b.statistic
    if claim.kind == "less":
        if sa == sb == "mean":
            ours, low, high = _t_interval(a - b)
        else:
            ours = float(_reduce(stat(a, sa) - stat(b, sb), claim.reduce))

            def diff(x: Array, y: Array | None) -> Array:
                assert y is not None
                return _reduce(stat(x, sa) - stat(y, sb), claim.reduce)

            low, high = _bootstrap(a, b, diff)
        if not enough:
            return Outcome(ours, low, high, n, "too few runs")
        verdict = "holds" if high < 0 else "does not hold" if low > 0 else "inconclusive"
        return Outcome(ours, low, high, n, verdict)

    def f(x: Array, y: Array | None) -> Array:
        assert y is not None
        xa, yb = stat(x, sa), stat(y, sb)
        with np.errstate(divide="ignore", invalid="ignore"):
            if claim.kind == "ratio":
                return _reduce(np.asarray(xa / yb), claim.reduce)
            return _reduce(np.asarray(100.0 * (yb - xa) / (xa if claim.of == "a" else yb)), claim.reduce)

    ours = float(f(a, b))
    low, high = _bootstrap(a, b, f)
    flag = BELOW_BOUND if claim.kind == "ratio" and claim.bound and enough and high < 1.0 else ""
    if claim.paper is None:
        return Outcome(ours, low, high, n, "-", flag=flag)
    if not enough:
        return Outcome(ours, low, high, n, "too few runs")
    return Outcome(
        ours, low, high, n, _band(claim.paper, low, high), paper_in_ci=_inside(claim.paper, low, high), flag=flag
    )
