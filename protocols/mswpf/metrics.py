"""MSWPF metrics from the trace tables: the fused estimate of each interval (``mswpf_steps``)
against the target's true position at that interval's emission instant (``positions`` table,
interpolated), and the wall time per filter step (``mswpf_timing``, not deterministic)."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
import pandas as pd

from aquasim_py.metrics import positions_at

__all__ = ["interval_errors", "mswpf_metrics", "step_errors"]


def _target_id(nodes: pd.DataFrame | None) -> int | None:
    if nodes is None or not len(nodes):
        return None
    t = nodes.loc[(nodes["role"].astype(str) == "target") & (nodes["protocol"].astype(str) == "mswpf"), "node"]
    return int(t.iloc[0]) if len(t) else None


def step_errors(tables: Mapping[str, pd.DataFrame]) -> pd.DataFrame:
    """Per interval: step, t_step, estimate, truth and position error (m) of the fused estimate.

    The steps' local times are taken as true times (the network's clocks are assumed perfect,
    as in the scenario files)."""
    steps = tables.get("mswpf_steps")
    pos = tables.get("positions")
    tid = _target_id(tables.get("nodes"))
    if steps is None or not len(steps) or pos is None or tid is None:
        return pd.DataFrame(columns=["step", "t_step", "error"])
    s = steps.sort_values("step", kind="stable").reset_index(drop=True)
    t = s["t_step"].to_numpy(float)
    truth = positions_at(pos, np.full(len(s), tid), t)
    est = s[["x", "y", "z"]].to_numpy(float)
    out = s[["step", "t_step", "n_selected", "n_reports"]].copy()
    out[["true_x", "true_y", "true_z"]] = truth
    out["error"] = np.linalg.norm(est - truth, axis=1)
    return out


def mswpf_metrics(tables: Mapping[str, pd.DataFrame]) -> dict[str, float]:
    """rmse_m (sqrt of the time-mean squared error of the run), mean_error_m, steps,
    report_loss (share of selected sensors whose report missed its fusion), step_ms and
    select_ms (mean wall time of one filter update / one selection)."""
    e = step_errors(tables)
    out: dict[str, float] = {}
    if len(e):
        err = e["error"].to_numpy(float)
        out["rmse_m"] = float(np.sqrt(np.mean(err**2)))
        out["mean_error_m"] = float(np.mean(err))
        out["steps"] = float(len(e))
        sel = float(e["n_selected"].sum())
        out["report_loss"] = float(1.0 - e["n_reports"].sum() / sel) if sel else math.nan
    tm = tables.get("mswpf_timing")
    if tm is not None and len(tm):
        out["step_ms"] = float(tm["step_ms"].mean())
        out["select_ms"] = float(np.nanmean(tm["select_ms"].to_numpy(float)))
    return out


def interval_errors(tables: Mapping[str, pd.DataFrame]) -> dict[str, float]:
    """``step_error_m[k]`` (k zero-padded to 3 digits) -> the fused estimate's position error (m)
    at step k: a run's series for eq 37 (RMSE over runs at each interval, averaged over time)."""
    e = step_errors(tables)
    return {f"step_error_m[{int(k):03d}]": float(v) for k, v in zip(e["step"], e["error"])}
