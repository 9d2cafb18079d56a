"""Our number for a claim, its 95 % confidence interval over seeds, and the verdict.

Means and paired mean differences get Student-t intervals (scipy); every other statistic (an
RMS over runs, a ratio, a gap in %) a percentile bootstrap over the seeds, resampling the runs
of both quantities together (they are paired: the same seeds), from a fixed generator so that
the same rows always give the same interval.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .claims import REL_TOL, Claim

__all__ = ["Outcome", "evaluate"]

BOOTSTRAP = 4000
CONFIDENCE = 0.95


@dataclass(frozen=True)
class Outcome:
    ours: float
    low: float
    high: float
    n: int
    verdict: str  #: "holds", "does not hold", "tie" or "-" (a reference, or no data)


def _stat(x: NDArray[np.float64], how: str, axis: int = -1) -> NDArray[np.float64]:
    if how == "rms":
        return np.sqrt(np.mean(x**2, axis=axis))
    return np.mean(x, axis=axis)


def _t_interval(x: NDArray[np.float64]) -> tuple[float, float, float]:
    from scipy import stats

    m = float(np.mean(x))
    if x.size < 2:
        return m, math.nan, math.nan
    half = float(stats.t.ppf(0.5 + CONFIDENCE / 2, x.size - 1) * np.std(x, ddof=1) / math.sqrt(x.size))
    return m, m - half, m + half


def _bootstrap(a: NDArray[np.float64], b: NDArray[np.float64] | None, f: object) -> tuple[float, float]:
    """Percentile interval of ``f(a, b)`` (vectorized over resamples on the last axis)."""
    rng = np.random.default_rng(20180808)
    idx = rng.integers(0, a.size, size=(BOOTSTRAP, a.size))
    vals = f(a[idx], None if b is None else b[idx])  # type: ignore[operator]
    vals = vals[np.isfinite(vals)]
    if vals.size == 0:
        return math.nan, math.nan
    q = np.quantile(vals, [0.5 - CONFIDENCE / 2, 0.5 + CONFIDENCE / 2])
    return float(q[0]), float(q[1])


def _band(paper: float, low: float, high: float) -> str:
    """``value``-like verdict: the CI inside the paper's +-REL_TOL band, outside it, or across."""
    lo, hi = sorted((paper * (1 - REL_TOL), paper * (1 + REL_TOL)))
    if not (math.isfinite(low) and math.isfinite(high)):
        return "tie"
    if lo <= low and high <= hi:
        return "holds"
    if high < lo or low > hi:
        return "does not hold"
    return "tie"


def evaluate(claim: Claim, a: NDArray[np.float64], b: NDArray[np.float64] | None) -> Outcome:
    """The outcome of ``claim`` from its quantities' per-seed values (paired by index; a run
    missing in either is dropped, as is a non-finite value)."""
    a = np.asarray(a, float)
    ok = np.isfinite(a)
    if b is not None:
        b = np.asarray(b, float)
        ok &= np.isfinite(b)
        b = b[ok]
    a = a[ok]
    n = int(a.size)
    if n == 0:
        return Outcome(math.nan, math.nan, math.nan, 0, "-")
    sa = claim.a.statistic
    if claim.kind in ("value", "reference"):
        if sa == "mean":
            ours, low, high = _t_interval(a)
        else:
            ours = float(_stat(a, sa))
            low, high = _bootstrap(a, None, lambda x, _: _stat(x, sa))
        if claim.kind == "reference" or claim.paper is None:
            return Outcome(ours, low, high, n, "-")
        return Outcome(ours, low, high, n, _band(claim.paper, low, high))
    assert b is not None and claim.b is not None
    sb = claim.b.statistic
    if claim.kind == "less":
        if sa == sb == "mean":
            ours, low, high = _t_interval(a - b)
        else:
            ours = float(_stat(a, sa) - _stat(b, sb))
            low, high = _bootstrap(a, b, lambda x, y: _stat(x, sa) - _stat(y, sb))
        verdict = "holds" if high < 0 else "does not hold" if low > 0 else "tie"
        return Outcome(ours, low, high, n, verdict)

    def f(x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
        xa, yb = _stat(x, sa), _stat(y, sb)
        with np.errstate(divide="ignore", invalid="ignore"):
            if claim.kind == "ratio":
                return np.asarray(xa / yb)
            return np.asarray(100.0 * (yb - xa) / (xa if claim.of == "a" else yb))

    ours = float(f(a, b))
    low, high = _bootstrap(a, b, f)
    verdict = _band(claim.paper, low, high) if claim.paper is not None else "-"
    return Outcome(ours, low, high, n, verdict)
