"""Run metrics computed from trace tables only (pandas DataFrames, as `trace.load` returns).

Because nothing here touches a live simulation, the same functions serve the CLI at the end
of a run and an analyst reading CSV traces afterwards. Table layouts are those of
docs/internals.md (``packets``, ``positions``, ``estimates``, ``clocks``, ``nodes``).

Definitions (x_hat an estimated position, x the true one, both in metres, sums over the
selected estimate rows; "error" of a position is the Euclidean norm ||x_hat - x||):

- RMSE  = sqrt( mean ||x_hat - x||^2 )                               [m]
- NMSE  = sum ||x_hat - x||^2 / sum ||x||^2                           [dimensionless]
  The normalized mean square error of ITMTL (Sun et al., Sec. 5). Its printed formula was
  lost from our copy of the paper; this is the usual signal-normalized definition. It depends
  on where the scenario's origin is (x is measured from it), so compare NMSE only between runs
  in the same frame.
- coverage = (number of unknown-position nodes with at least one estimate up to time t)
             / (number of unknown-position nodes)                    [0..1]
  Unknown-position nodes are, by default, the ``ordinary`` and ``target`` roles.
- sync error = |error| of the ``clocks`` table rows, i.e. the absolute difference between a
  node's estimate of true time and true time, as the kernel logs it          [s]
  Reported as mean, percentiles and final (last row per node) mean.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "UNKNOWN_ROLES",
    "coverage",
    "nmse",
    "packet_counts",
    "position_errors",
    "positions_at",
    "rmse",
    "summarize",
    "sync_error_stats",
    "sync_errors",
    "unknown_nodes",
]

UNKNOWN_ROLES: tuple[str, ...] = ("ordinary", "target")
_XYZ = ["x", "y", "z"]
_TRUE_XYZ = ["true_x", "true_y", "true_z"]


def _select(
    table: pd.DataFrame,
    *,
    exclude_references: bool = True,
    t_min: float | None = None,
    t_max: float | None = None,
    final: bool = False,
) -> pd.DataFrame:
    """Rows kept for a statistic: non-reference rows in [t_min, t_max], optionally the last per node."""
    df = table
    if exclude_references and "is_reference" in df.columns:
        # None / NaN (a CSV round trip of an unset flag) count as "not a reference"
        df = df[~df["is_reference"].isin([True, "True", "true"])]
    if t_min is not None and "time" in df.columns:
        df = df[df["time"] >= t_min]
    if t_max is not None and "time" in df.columns:
        df = df[df["time"] <= t_max]
    if final and len(df):
        # stable sort keeps the logging order among rows of equal time
        df = df.sort_values("time", kind="stable").groupby("node", sort=True).tail(1)
    return df


def position_errors(estimates: pd.DataFrame, **select: Any) -> NDArray[np.float64]:
    """Euclidean position error ||x_hat - x|| (m) of each selected estimate row.

    Computed from the estimate and truth columns (not the logged ``error`` column), so a
    trace edited or filtered by hand stays consistent. ``select``: see :func:`rmse`.
    """
    df = _select(estimates, **select)
    if len(df) == 0:
        return np.empty(0)
    d = df[_XYZ].to_numpy(float) - df[_TRUE_XYZ].to_numpy(float)
    return np.sqrt(np.einsum("ij,ij->i", d, d))


def rmse(estimates: pd.DataFrame, **select: Any) -> float:
    """Root-mean-square position error (m); NaN when no row is selected.

    ``select``: ``exclude_references`` (default True: anchors logging their known position
    are not estimates), ``t_min`` / ``t_max`` (s, true time), ``final`` (last row per node).
    """
    e = position_errors(estimates, **select)
    return float(np.sqrt(np.mean(e**2))) if e.size else float("nan")


def nmse(estimates: pd.DataFrame, **select: Any) -> float:
    """Normalized mean square error sum ||x_hat - x||^2 / sum ||x||^2 (see module docstring)."""
    df = _select(estimates, **select)
    if len(df) == 0:
        return float("nan")
    x = df[_TRUE_XYZ].to_numpy(float)
    d = df[_XYZ].to_numpy(float) - x
    den = float(np.sum(x * x))
    return float(np.sum(d * d) / den) if den > 0.0 else float("nan")


def unknown_nodes(nodes: pd.DataFrame, roles: Iterable[str] = UNKNOWN_ROLES) -> NDArray[np.int64]:
    """Ids of the nodes whose role is one of ``roles`` (case-insensitive), from the ``nodes`` table."""
    wanted = {r.lower() for r in roles}
    mask = nodes["role"].astype(str).str.lower().isin(wanted)
    return np.sort(nodes.loc[mask, "node"].to_numpy(np.int64))


def coverage(
    estimates: pd.DataFrame | None,
    candidates: Iterable[int],
    *,
    until: float | None = None,
) -> float:
    """Share of ``candidates`` (node ids) with at least one non-reference estimate by ``until`` (s).

    NaN when there are no candidates; 0 when nobody estimated anything.
    """
    cand = np.unique(np.fromiter(candidates, dtype=np.int64))
    if cand.size == 0:
        return float("nan")
    if estimates is None or len(estimates) == 0:
        return 0.0
    df = _select(estimates, t_max=until)
    have = np.unique(df["node"].to_numpy(np.int64))
    return float(np.isin(cand, have).sum() / cand.size)


def sync_errors(clocks: pd.DataFrame, **select: Any) -> NDArray[np.float64]:
    """|error| (s) of the selected ``clocks`` rows (``select`` as for :func:`rmse`)."""
    df = _select(clocks, exclude_references=False, **select)
    return np.abs(df["error"].to_numpy(float)) if len(df) else np.empty(0)


def sync_error_stats(
    clocks: pd.DataFrame,
    percentiles: Sequence[float] = (50.0, 95.0),
    *,
    t_min: float | None = None,
) -> dict[str, float]:
    """Mean and percentiles of the absolute sync error over rows (s), plus the final-row mean."""
    e = sync_errors(clocks, t_min=t_min)
    out: dict[str, float] = {"mean_abs_error_s": float(e.mean()) if e.size else float("nan")}
    for p in percentiles:
        out[f"p{_fmt_pct(p)}_abs_error_s"] = float(np.percentile(e, p)) if e.size else float("nan")
    ef = sync_errors(clocks, t_min=t_min, final=True)
    out["final_mean_abs_error_s"] = float(ef.mean()) if ef.size else float("nan")
    return out


def _fmt_pct(p: float) -> str:
    return f"{p:g}".replace(".", "_")


def packet_counts(packets: pd.DataFrame | None) -> dict[str, int]:
    """Packets sent (tx), received (rx) and dropped, the drops also split by ``reason``."""
    out = {"sent": 0, "received": 0, "dropped": 0}
    if packets is None or len(packets) == 0:
        return out
    ev = packets["event"].astype(str)
    out["sent"] = int((ev == "tx").sum())
    out["received"] = int((ev == "rx").sum())
    drops = packets[ev == "drop"]
    out["dropped"] = len(drops)
    if len(drops) and "reason" in drops.columns:
        reasons = drops["reason"].fillna("unknown").astype(str).replace("", "unknown")
        for reason, n in sorted(reasons.value_counts().items()):
            out[f"dropped.{reason}"] = int(n)
    return out


def positions_at(positions: pd.DataFrame, node: ArrayLike, time: ArrayLike) -> NDArray[np.float64]:
    """True positions (n, 3) of ``node[i]`` at ``time[i]`` from the sampled ``positions`` table.

    Between samples: linear interpolation, exact for straight motion; for curved motion the
    error is at most |acceleration| * interval^2 / 8 (choose ``trace.position_interval_s``
    accordingly). Before the first / after the last sample: extrapolation with that sample's
    velocity (``vx, vy, vz``; held constant if the table has none), since a run's last events
    (receptions still in flight) fall after its last sample. NaN for a node with no sample.
    """
    node = np.asarray(node, dtype=np.int64).ravel()
    time = np.asarray(time, dtype=float).ravel()
    out = np.full((node.size, 3), np.nan)
    if node.size == 0 or len(positions) == 0:
        return out
    has_v = all(c in positions.columns for c in ("vx", "vy", "vz"))
    pos = positions.sort_values(["node", "time"], kind="stable")
    # one np.interp per node (not per query): the loop is over the few nodes, vectorized over queries
    for nid, grp in pos.groupby("node", sort=False):
        sel = np.flatnonzero(node == int(nid))
        if sel.size == 0:
            continue
        t = grp["time"].to_numpy(float)
        q = time[sel]
        before, after = q < t[0], q > t[-1]
        for k, col in enumerate(_XYZ):
            x = grp[col].to_numpy(float)
            val = np.interp(q, t, x)
            if has_v:
                v = grp[f"v{col}"].to_numpy(float)
                val = np.where(before, x[0] + v[0] * (q - t[0]), val)
                val = np.where(after, x[-1] + v[-1] * (q - t[-1]), val)
            out[sel, k] = val
    return out


def summarize(
    tables: Mapping[str, pd.DataFrame],
    protocols: Iterable[type] | None = None,
    *,
    percentiles: Sequence[float] = (50.0, 95.0),
    warmup_s: float = 0.0,
    unknown_roles: Iterable[str] = UNKNOWN_ROLES,
) -> dict[str, float]:
    """Every metric of a run, as a flat {name: number} dict (the CLI table, summary.json, sweep.csv).

    ``protocols``: the Node subclasses of the run; each one's ``metrics(tables)`` is added with
    its name as prefix. ``None``: the protocols named in the ``nodes`` table, through the registry.
    """
    out: dict[str, float] = {}
    for k, n in packet_counts(tables.get("packets")).items():
        out[f"packets.{k}"] = n
    t0 = warmup_s if warmup_s > 0 else None
    est = tables.get("estimates")
    nodes = tables.get("nodes")
    if est is not None and len(est):
        out["localization.estimates"] = len(_select(est, t_min=t0))
        out["localization.rmse_m"] = rmse(est, t_min=t0)
        out["localization.final_rmse_m"] = rmse(est, t_min=t0, final=True)
        out["localization.nmse"] = nmse(est, t_min=t0)
        if nodes is not None and len(nodes):
            out["localization.coverage"] = coverage(est, unknown_nodes(nodes, unknown_roles))
    clk = tables.get("clocks")
    if clk is not None and len(clk):
        for k, v in sync_error_stats(clk, percentiles, t_min=t0).items():
            out[f"sync.{k}"] = v
    if protocols is None:
        protocols = _protocols_from_nodes(nodes)
    seen: set[str] = set()
    for cls in protocols:
        name = getattr(cls, "name", cls.__name__)
        fn = getattr(cls, "metrics", None)
        if name in seen or fn is None:
            continue
        seen.add(name)
        for k, v in (fn(tables) or {}).items():
            out[f"{name}.{k}"] = v
    return out


def _protocols_from_nodes(nodes: pd.DataFrame | None) -> list[type]:
    if nodes is None or "protocol" not in nodes.columns:
        return []
    from aquasim_py import registry

    out = []
    for name in pd.unique(nodes["protocol"].astype(str)):
        try:
            out.append(registry.get(name))
        except KeyError:
            continue
    return out
