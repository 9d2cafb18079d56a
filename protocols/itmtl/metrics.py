"""Metrics and per-round report of ITMTL and its baselines, from trace tables only.

Ordinary nodes are selected by role (the ``nodes`` table), not by ``is_reference``: a promoted
node stays an ordinary node whose errors count.

- sync error, RMSE, NMSE and coverage are :mod:`aquasim_py.metrics`'s definitions (one per
  quantity, docs/metrics.md), called with this protocol's evaluated nodes: so
  ``loc_rmse_m`` = ``localization.rmse_m``, ``loc_final_rmse_m`` = ``localization.final_rmse_m``,
  ``loc_nmse`` = ``localization.nmse`` (origin-free), ``coverage`` = ``localization.coverage``
  and ``sync_final_mean_all_s`` = ``sync.final_mean_abs_error_s`` in a one-protocol run.
- sync error: |estimated true time - true time| at each ``clocks`` row (s). ``sync_final_*``:
  mean and 95th percentile over the final rows of the *covered* nodes (localized in one of
  their last three rounds: the paper's "range of synchronization and localization");
  ``sync_final_*_all``: over every evaluated node, covered or not; per round: over the nodes
  localized in that round (and ``sync_all_mean_s`` over all).
- localization: RMSE (m) and NMSE over all rows and over the final rows; ``*_fixed``: only
  rounds with a fix (not the track's predictions while coasting).
- coverage: share of evaluated nodes with at least one position estimate; ``coverage_final``:
  share covered at the end (localized in one of their last three rounds).
- coverage upper bound: iterated ">= 3 localized neighbours" promotion on the connectivity
  graph seen in the ``packets`` table (an edge wherever a frame was received), from the
  buoys and anchors (networkx).
- no "rounds to converge": the per-round means are over a different set of nodes each round
  (those localized in it), so their trend mixes convergence with coverage, and the former
  "within twice the last value" rule hinged on one noisy round; the per-round table
  (:func:`per_round`, :func:`round_table`) shows the trend itself (docs/metrics.md).
- promoted: share of evaluated nodes that ever logged ``is_reference``.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from aquasim_py import metrics as generic

REFERENCE_ROLES = ("buoy", "anchor")


def ordinary_nodes(tables: Mapping[str, pd.DataFrame], name: str) -> np.ndarray:
    """Ids of the ordinary nodes that run protocol ``name`` (from the ``nodes`` table)."""
    nodes = tables.get("nodes")
    if nodes is None or len(nodes) == 0:
        return np.empty(0, dtype=int)
    sel = (nodes["role"].astype(str) == "ordinary") & (nodes["protocol"].astype(str) == name)
    return nodes.loc[sel, "node"].to_numpy(int)


def protocol_rows(df: pd.DataFrame | None, name: str, ids: np.ndarray) -> pd.DataFrame:
    """The rows of ``df`` that protocol ``name`` logged for the nodes ``ids``."""
    if df is None or len(df) == 0:
        return pd.DataFrame()
    return df[(df["protocol"].astype(str) == name) & df["node"].isin(ids)]


def per_round(tables: Mapping[str, pd.DataFrame], name: str) -> pd.DataFrame:
    """Per round: mean and p95 |sync error| (s), RMSE (m) and NMSE of position, nodes reporting."""
    ids = ordinary_nodes(tables, name)
    clk = protocol_rows(tables.get("clocks"), name, ids)
    est = protocol_rows(tables.get("estimates"), name, ids)
    out = pd.DataFrame()
    if len(clk) and "round" in clk:
        c = clk.assign(abs_err=clk["error"].abs())
        if len(est) and "round" in est:
            loc = c.merge(est[["node", "round"]], on=["node", "round"])
            e = loc.groupby("round")["abs_err"]
            out["sync_mean_s"] = e.mean()
            out["sync_p95_s"] = e.quantile(0.95)
        out["sync_all_mean_s"] = c.groupby("round")["abs_err"].mean()
    if len(est) and "round" in est:
        g = est.assign(se=est["error"] ** 2).groupby("round")
        out["loc_rmse_m"] = np.sqrt(g["se"].mean())
        out["loc_nmse"] = _per_round_nmse(est, tables.get("nodes"), name)
        out["nodes"] = g["node"].nunique()
        if "is_reference" in est:
            out["promoted"] = est[est["is_reference"].astype(bool)].groupby("round")["node"].nunique()
    out.index.name = "round"
    return out.fillna({"promoted": 0}) if "promoted" in out else out


def round_series(tables: Mapping[str, pd.DataFrame], name: str) -> dict[str, float]:
    """Per round r (:func:`per_round`): ``sync_error_s[r]``, the mean |sync error| (s) of the
    ordinary nodes localized in round r, and ``nmse[r]``, the round's NMSE; r zero-padded to 3
    digits. A run's curves of the paper's Figs 11-12 (``aquasim-py reproduce itmtl`` averages
    them over runs, round by round)."""
    pr = per_round(tables, name)
    out: dict[str, float] = {}
    for col, key in (("sync_mean_s", "sync_error_s"), ("loc_nmse", "nmse")):
        if col in pr:
            out.update({f"{key}[{int(r):03d}]": float(v) for r, v in pr[col].items() if np.isfinite(v)})
    return out


def coverage_upper_bound(tables: Mapping[str, pd.DataFrame], min_neighbours: int = 3) -> float:
    """Share of ordinary nodes reachable by iterated promotion on the observed link graph."""
    nodes, pk = tables.get("nodes"), tables.get("packets")
    if nodes is None or pk is None or len(nodes) == 0:
        return float("nan")
    # imported here: every run imports every built-in protocol (the registry), and networkx
    # adds about 12 MiB to each one's memory
    import networkx as nx

    rx = pk[pk["event"].astype(str) == "rx"]
    G = nx.Graph()
    G.add_nodes_from(nodes["node"].to_numpy(int))
    G.add_edges_from(zip(rx["src"].to_numpy(int), rx["node"].to_numpy(int)))
    roles = dict(zip(nodes["node"].to_numpy(int), nodes["role"].astype(str)))
    known = {n for n, r in roles.items() if r in REFERENCE_ROLES}
    unknown = {n for n, r in roles.items() if r == "ordinary"}
    if not unknown:
        return float("nan")
    grew = True
    while grew:
        new = {n for n in unknown - known if sum(1 for m in G.neighbors(n) if m in known) >= min_neighbours}
        grew = bool(new)
        known |= new
    return len(known & unknown) / len(unknown)


def protocol_metrics(tables: Mapping[str, pd.DataFrame], name: str) -> dict[str, float]:
    nodes = tables.get("nodes")
    if nodes is not None and len(nodes) == 0:
        nodes = None
    ids = generic.evaluated_nodes(nodes, protocol=name) if nodes is not None else np.empty(0, dtype=np.int64)
    nan = float("nan")
    out: dict[str, float] = {}
    clk_t, est_t = tables.get("clocks"), tables.get("estimates")
    clk = (
        generic.select_rows(clk_t, nodes, protocol=name) if nodes is not None and clk_t is not None else pd.DataFrame()
    )
    est = (
        generic.select_rows(est_t, nodes, protocol=name) if nodes is not None and est_t is not None else pd.DataFrame()
    )
    out["sync_final_mean_s"] = out["sync_final_p95_s"] = out["sync_mean_s"] = nan
    out["sync_final_mean_all_s"] = out["sync_final_p95_all_s"] = nan
    out["coverage_final"] = 0.0 if len(ids) else nan
    if len(clk):
        last = generic.select_rows(clk, nodes, protocol=name, final=True)
        fin = generic.sync_errors(last, nodes, protocol=name)
        out["sync_final_mean_all_s"] = float(fin.mean())
        out["sync_final_p95_all_s"] = float(np.percentile(fin, 95))
        if len(est) and "round" in clk and "round" in est:
            # covered nodes: localized in one of their last three rounds
            last_est = est.groupby("node")["round"].max()
            ok = (last["node"].map(last_est).fillna(-np.inf) >= last["round"] - 2).to_numpy()
            if ok.any():
                out["sync_final_mean_s"] = float(fin[ok].mean())
                out["sync_final_p95_s"] = float(np.percentile(fin[ok], 95))
            loc = generic.sync_errors(clk.merge(est[["node", "round"]], on=["node", "round"]), nodes, protocol=name)
            out["sync_mean_s"] = float(loc.mean()) if loc.size else nan
            out["coverage_final"] = float(ok.sum() / max(len(ids), 1))
    if len(est):
        out["loc_rmse_m"] = generic.rmse(est, nodes, protocol=name)
        out["loc_nmse"] = generic.nmse(est, nodes, protocol=name)
        out["loc_final_rmse_m"] = generic.rmse(est, nodes, protocol=name, final=True)
        out["loc_final_nmse"] = generic.nmse(est, nodes, protocol=name, final=True)
        out["promoted_share"] = float(est[est["is_reference"].astype(bool)]["node"].nunique() / max(len(ids), 1))
        if "fixed" in est:
            fx = est[est["fixed"].astype(bool)]
            out["loc_rmse_fixed_m"] = generic.rmse(fx, nodes, protocol=name)
            out["loc_nmse_fixed"] = generic.nmse(fx, nodes, protocol=name)
    else:
        for k in ("loc_rmse_m", "loc_nmse", "loc_final_rmse_m", "loc_final_nmse"):
            out[k] = nan
        out["promoted_share"] = 0.0
    out["coverage"] = generic.coverage(est, ids)
    out["coverage_upper_bound"] = coverage_upper_bound(tables)
    # coverage against what the link graph allows (nodes that can reach enough references)
    bound = out["coverage_upper_bound"]
    out["coverage_of_bound"] = out["coverage"] / bound if bound > 0 else nan
    return out


def round_table(tables: Mapping[str, pd.DataFrame], name: str) -> str:
    """Plain-text per-round table of the ordinary nodes' sync and localization errors."""
    pr = per_round(tables, name)
    if len(pr) == 0:
        return f"{name}: no ordinary-node estimates"
    lines = [
        f"{name}: ordinary nodes per round (nodes = localized that round; sync over them, 'all' over every ordinary node)",
        f"{'round':>5} {'nodes':>5} {'promoted':>8} {'sync mean (us)':>15} {'sync p95 (us)':>14} {'loc RMSE (m)':>13} {'sync all (us)':>14}",
    ]
    for r, row in pr.iterrows():
        n_nodes = row.get("nodes", 0)
        n_prom = row.get("promoted", 0)
        n_nodes = 0 if not np.isfinite(n_nodes) else int(n_nodes)
        n_prom = 0 if not np.isfinite(n_prom) else int(n_prom)
        lines.append(
            f"{int(r):>5} {n_nodes:>5} {n_prom:>8} "
            f"{row.get('sync_mean_s', np.nan) * 1e6:>15.2f} {row.get('sync_p95_s', np.nan) * 1e6:>14.2f} "
            f"{row.get('loc_rmse_m', np.nan):>13.3f} {row.get('sync_all_mean_s', np.nan) * 1e6:>14.2f}"
        )
    return "\n".join(lines)


def mac_metrics(tables: Mapping[str, pd.DataFrame], name: str, res_kind: str = "sync_res") -> dict[str, float]:
    """How the Req/Res exchange fared (added for the slotted reply MAC).

    - ``res_collision_fraction``: Res frames lost to a collision at their addressee / Res
      frames sent (``packets`` table; every node of a Req/Res run shares the frame kinds);
    - ``short_round_fraction``: rounds that ended with fewer answers than the node needs
      (``min_refs``) although at least that many references scheduled an answer to them
      (``reqres_replies``), i.e. rounds the MAC made short / rounds (``reqres_rounds``);
    - ``short_round_fraction_all``: rounds with fewer answers than needed for any reason
      (including nodes that do not reach enough references) / rounds;
    - ``retry_fraction``: rounds that needed the retry.
    """
    nan = float("nan")
    out = {
        "res_collision_fraction": nan,
        "short_round_fraction": nan,
        "short_round_fraction_all": nan,
        "retry_fraction": nan,
    }
    pk = tables.get("packets")
    if pk is not None and len(pk):
        res = pk[pk["kind"].astype(str) == res_kind]
        sent = int((res["event"].astype(str) == "tx").sum())
        lost = int(((res["event"].astype(str) == "drop") & (res["reason"].astype(str) == "collision")).sum())
        if sent:
            out["res_collision_fraction"] = lost / sent
    rounds = tables.get("reqres_rounds")
    if rounds is None or len(rounds) == 0:
        return out
    rounds = rounds[rounds["protocol"].astype(str) == name]
    if len(rounds) == 0:
        return out
    short = rounds["answers"].to_numpy(int) < rounds["needed"].to_numpy(int)
    out["short_round_fraction_all"] = float(short.mean())
    out["retry_fraction"] = float(rounds["retried"].astype(bool).mean())
    rep = tables.get("reqres_replies")
    scheduled = pd.Series(0, index=pd.MultiIndex.from_arrays([rounds["node"], rounds["round"]]))
    if rep is not None and len(rep):
        n = rep.groupby(["requester", "round"])["node"].nunique()
        n.index = n.index.set_names(["node", "round"])
        scheduled = n.reindex(scheduled.index, fill_value=0)
    could = scheduled.to_numpy(int) >= rounds["needed"].to_numpy(int)
    out["short_round_fraction"] = float((short & could).mean())
    return out


def _per_round_nmse(est: pd.DataFrame, nodes: pd.DataFrame | None, name: str) -> pd.Series:
    """Per round: :func:`aquasim_py.metrics.nmse` (origin-free) of the ordinary nodes'
    estimates logged in that round, the paper's Fig. 12 ordinate; NaN for a round whose rows
    have no spread (one node)."""
    return pd.Series({r: generic.nmse(g, nodes, protocol=name) for r, g in est.groupby("round")}, dtype=float)
