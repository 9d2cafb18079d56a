"""Section-5 metrics of the STVF paper (Hu et al., Sensors 2018) from trace tables, shared by
the STVF and SLMP protocols. Reads the kernel's truth columns of ``estimates``: metrics
only, never protocol logic."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from aquasim_py import metrics as generic

__all__ = ["localization_metrics"]


def localization_metrics(
    tables: Mapping[str, Any],
    protocol: str,
    *,
    converge_within: int = 5,
    t_min: float | None = None,
    period_s: float | None = None,
) -> dict[str, float]:
    """STVF Section 5 metrics from the trace tables of one run.

    avg_rmse_m: mean over unknown nodes of each node's RMSE over its estimates (Sec. 5.2.3);
    share_below_avg: share of those nodes whose RMSE is below that mean; mean_error_m: mean
    distance error over all estimates ("localization accuracy", Sec. 5.1); rmse_m: RMSE over
    all estimates; coverage: mean over ``period_s`` periods (first to last estimate; default: the ``period_s`` column
    the protocols log, else 1 s) of (unknown nodes
    localized in the period) / (unknown nodes), the paper's time-averaged coverage;
    coverage_ever: share localized at least once; converge_within_5: share of localizations
    whose iteration count is <= ``converge_within`` (Fig. 6); mean_iterations; localizations.

    Rows and nodes are :mod:`aquasim_py.metrics`'s (docs/metrics.md): every row of the
    protocol's evaluated (unknown-role) nodes, promoted references included, and the RMSE,
    mean error, per-node RMSE and coverage_ever are its functions, so ``rmse_m`` =
    ``localization.rmse_m``, ``coverage_ever`` = ``localization.coverage`` and
    ``localizations`` = ``localization.estimates`` in a one-protocol run."""
    est = tables.get("estimates")
    nodes = tables.get("nodes")
    out: dict[str, float] = {}
    if nodes is None or len(nodes) == 0 or est is None or len(est) == 0:
        return {"coverage": 0.0, "localizations": 0.0}
    unknown = generic.evaluated_nodes(nodes, protocol=protocol)
    n_unknown = max(len(unknown), 1)
    sel: dict[str, Any] = dict(protocol=protocol, t_min=t_min)
    e = generic.select_rows(est, nodes, **sel)
    if len(e) == 0:
        return {"coverage": 0.0, "localizations": 0.0}
    per_node = generic.rmse_per_node(e, nodes, **sel)
    avg = float(per_node.mean())
    out["avg_rmse_m"] = avg
    out["share_below_avg"] = float((per_node < avg).mean())
    out["mean_error_m"] = generic.mean_error(e, nodes, **sel)
    out["rmse_m"] = generic.rmse(e, nodes, **sel)
    if period_s is None:
        period_s = float(e["period_s"].median()) if "period_s" in e.columns else 1.0
    periods = np.floor(e["time"].to_numpy() / period_s + 1e-9)
    per_period = pd.Series(e["node"].to_numpy()).groupby(periods).nunique()
    n_periods = int(np.ptp(periods)) + 1 if len(periods) else 1
    out["coverage"] = float(per_period.sum() / (n_periods * n_unknown))
    out["coverage_ever"] = generic.coverage(e, unknown)
    if "iterations" in e.columns:
        it = pd.to_numeric(e["iterations"], errors="coerce").dropna()
        if len(it):
            out["converge_within_5"] = float((it <= converge_within).mean())
            out["mean_iterations"] = float(it.mean())
            out["max_iterations"] = float(it.max())
    if "is_reference" in e.columns:
        out["share_promoted"] = float(e["is_reference"].isin([True, "True", "true"]).mean())
    out["localizations"] = float(len(e))
    return out
