"""SVL-PF metrics from trace tables (metrics only: reads the kernel's ground truth).

The fusion node logs one ``svlpf`` row per time frame k (its estimate of the target at the
request's send instant, and the request's packet uid). The truth for that row is the target's
position at the request's true send time (``packets`` tx row of that uid), interpolated
linearly in the sampled ``positions`` table (exact for a constant-velocity target when the
samples bracket the instant).

E_k = |X_hat_k - X_k| (Section 4), and the "average of accumulated error" of eq 32, which the
paper prints as sum_k E_k / k but tabulates as the running mean (sum_{k <= t} E_k) / t (its
Tables 2-3 are of the size of E_k, not of E_k times a harmonic number): we use the running mean.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

__all__ = ["TABLE_STEPS", "step_errors", "svlpf_metrics"]

#: the frames of the paper's Tables 2-3
TABLE_STEPS = tuple(range(10, 101, 10))


def _target_truth(tables: Mapping[str, Any], times: np.ndarray) -> np.ndarray:
    """True target positions (n, 3) at true ``times`` (s), interpolated in ``positions``."""
    nodes = tables["nodes"]
    target = int(nodes.loc[nodes["role"].astype(str) == "target", "node"].iloc[0])
    pos = tables["positions"]
    pos = pos[pos["node"] == target].sort_values("time")
    t = pos["time"].to_numpy(float)
    return np.column_stack([np.interp(times, t, pos[c].to_numpy(float)) for c in ("x", "y", "z")])


def step_errors(tables: Mapping[str, Any]) -> pd.DataFrame:
    """Per-frame errors: the ``svlpf`` rows plus t_true, true_x/y/z, error (E_k, m) and
    eave (eq 32 running mean, m), sorted by k."""
    sv = tables.get("svlpf")
    if sv is None or len(sv) == 0 or tables.get("positions") is None or tables.get("packets") is None:
        return pd.DataFrame()
    if "algorithm" not in sv.columns:
        sv = sv.assign(algorithm="svlpf", primary=True)
    sv = sv.sort_values(["algorithm", "k"], kind="stable").reset_index(drop=True)
    pk = tables["packets"]
    tx = pk[pk["event"] == "tx"].drop_duplicates("uid").set_index("uid")["time"]
    t_true = tx.reindex(sv["req_uid"].to_numpy()).to_numpy(float)
    truth = _target_truth(tables, t_true)
    out = sv.copy()
    out["t_true"] = t_true
    out[["true_x", "true_y", "true_z"]] = truth
    est = out[["x", "y", "z"]].to_numpy(float)
    out["error"] = np.linalg.norm(est - truth, axis=1)
    grp = out.groupby("algorithm", sort=False)["error"]
    out["eave"] = grp.cumsum() / (grp.cumcount() + 1)
    return out


def svlpf_metrics(tables: Mapping[str, Any]) -> dict[str, float]:
    """Of the primary estimator: accumulated_error_m (eq 32 at the last frame), eave_kNN_m at
    the frames of Tables 2-3, mean / final error, frames, mean selected / flagged sensors, mean
    regression iterations; of every estimator run (``also``): ``<algorithm>.<metric>``."""
    e = step_errors(tables)
    if len(e) == 0:
        return {"frames": 0.0}
    prim = e[e["primary"].astype(str).isin(["True", "true", "1"])]
    out = _one(prim if len(prim) else e)
    if e["algorithm"].nunique() > 1:
        for algo, g in e.groupby("algorithm", sort=True):
            for k, v in _one(g).items():
                if k.startswith(("accumulated", "eave", "mean_error")):
                    out[f"{algo}.{k}"] = v
    return out


def _one(e: pd.DataFrame) -> dict[str, float]:
    out: dict[str, float] = {
        "accumulated_error_m": float(e["eave"].iloc[-1]),
        "mean_error_m": float(e["error"].mean()),
        "final_error_m": float(e["error"].iloc[-1]),
        "frames": float(len(e)),
        "mean_selected": float(e["n_selected"].mean()),
        "mean_flagged": float(e["n_flagged"].mean()),
        "mean_iterations": float(e["iterations"].mean()),
    }
    by_k = e.set_index("k")["eave"]
    for k in TABLE_STEPS:
        if k in by_k.index:
            out[f"eave_k{k}_m"] = float(by_k.loc[k])
    return out
