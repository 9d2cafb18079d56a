"""The ITMTL paper's numbers (Gao et al.) beside the same statistics of our runs.

``aquasim-py scenarios/itmtl.toml`` runs ITMTL, ITMTL-wsc, TSHL, MU-Sync and Mobi-Sync on one
network and seed; :func:`comparison` turns those runs into one row per claim of the paper
that a run of one network can check: what the paper's number is a statistic of, ours, the
paper's. The paper's Figs 9 and 10 survive only as sentences (their curves were lost), so
those rows compare orderings; Figs 11 and 12 give one number each; Figs 15-17 need the
network sweep (``scenarios/itmtl_network_sweep.toml``, docs/itmtl.md) and have no row here.

The wsc gap is computed on the (node, round) pairs that both ITMTL and ITMTL-wsc localized,
so both curves average the same nodes at the same iteration whatever their coverage.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from aquasim_py import metrics as generic

from .metrics import ordinary_nodes, protocol_rows

#: the paper's names, in the order the tables list them
ALGORITHMS = ("ITMTL", "ITMTL-wsc", "TSHL", "MU-Sync", "Mobi-Sync")
_BASELINES = {"tshl": "TSHL", "mu_sync": "MU-Sync", "mobi_sync": "Mobi-Sync"}


def algorithm(sc: Any) -> str | None:
    """The paper's name for what a scenario's ordinary nodes run (None: not one of the five,
    or groups that run different ones)."""
    runs = {(g.protocol, bool(g.params.get("compensate", True))) for g in sc.nodes if g.role == "ordinary"}
    if len(runs) != 1:
        return None
    proto, compensate = runs.pop()
    if proto == "itmtl":
        return "ITMTL" if compensate else "ITMTL-wsc"
    return _BASELINES.get(proto)


def node_rounds(tables: Mapping[str, pd.DataFrame], name: str) -> pd.DataFrame:
    """One row per (node, round) in which an ordinary node running ``name`` logged a position
    estimate: the estimate's columns and ``abs_err``, |sync error| (s) of that round's
    ``clocks`` row."""
    ids = ordinary_nodes(tables, name)
    est = protocol_rows(tables.get("estimates"), name, ids)
    clk = protocol_rows(tables.get("clocks"), name, ids)
    if len(est) == 0 or len(clk) == 0 or "round" not in est or "round" not in clk:
        return pd.DataFrame(columns=["node", "round", "abs_err"])
    c = clk[["node", "round"]].assign(abs_err=clk["error"].abs().to_numpy())
    return est.merge(c, on=["node", "round"])


def wsc_gap_per_round(itmtl: pd.DataFrame, wsc: pd.DataFrame, nodes: pd.DataFrame | None) -> pd.DataFrame:
    """Per round, on the (node, round) pairs both localized (:func:`node_rounds` of each):
    mean |sync error| (s) and NMSE (:func:`aquasim_py.metrics.nmse`) of each, and the gaps of
    the paper's Figs 11-12: ``sync_gap_pct`` = 100 (wsc - ITMTL) / ITMTL and
    ``nmse_decrease_pct`` = 100 (wsc - ITMTL) / wsc. ``nodes``: the ``nodes`` table (both runs
    are of one network)."""
    keys = itmtl[["node", "round"]].merge(wsc[["node", "round"]])
    out = {}
    for tag, df in (("itmtl", itmtl), ("wsc", wsc)):
        d = df.merge(keys)
        proto = str(d["protocol"].iloc[0]) if len(d) else None
        g = d.groupby("round")
        out[f"sync_{tag}_s"] = g["abs_err"].mean()
        out[f"nmse_{tag}"] = pd.Series({r: generic.nmse(x, nodes, protocol=proto) for r, x in g}, dtype=float)
    t = pd.DataFrame(out)
    t.index.name = "round"
    with np.errstate(divide="ignore", invalid="ignore"):
        t["sync_gap_pct"] = 100.0 * (t["sync_wsc_s"] - t["sync_itmtl_s"]) / t["sync_itmtl_s"]
        t["nmse_decrease_pct"] = 100.0 * (t["nmse_wsc"] - t["nmse_itmtl"]) / t["nmse_wsc"]
    return t


@dataclass(frozen=True)
class Claim:
    figure: str
    quantity: str
    #: what the paper's number is a statistic of (and ours, computed the same way)
    statistic: str
    paper: str
    #: (runs by algorithm, gap table or None) -> our value as text; None: not from one network
    ours: Callable[[Mapping[str, Any], pd.DataFrame | None], str] | None = None


def _ranking(metric: str, scale: float, unit: str) -> Callable[[Mapping[str, Any], pd.DataFrame | None], str]:
    def ours(runs: Mapping[str, Any], _gap: pd.DataFrame | None) -> str:
        vals = {a: float(r.metrics.get(metric, np.nan)) for a, r in runs.items()}
        vals = {a: v for a, v in vals.items() if np.isfinite(v)}
        if "ITMTL" not in vals or len(vals) < 2:
            return "-"
        order = sorted(vals, key=lambda a: vals[a])
        text = ", ".join(f"{a} {vals[a] * scale:.3g}{unit}" for a in order)
        return f"{text}: ITMTL {'lowest' if order[0] == 'ITMTL' else 'not lowest'}"

    return ours


def _gap(col: str, how: str) -> Callable[[Mapping[str, Any], pd.DataFrame | None], str]:
    def ours(_runs: Mapping[str, Any], gap: pd.DataFrame | None) -> str:
        if gap is None or col not in gap:
            return "-"
        g = gap[col][np.isfinite(gap[col].to_numpy(float))]
        if g.size == 0:
            return "-"
        if how == "max":
            return f"{g.max():.1f} % (round {int(g.idxmax())} of {g.size})"
        return f"median {g.median():.1f} %, largest {g.max():.1f} % ({g.size} rounds)"

    return ours


CLAIMS: tuple[Claim, ...] = (
    Claim(
        "Fig. 9",
        "final sync error",
        "mean |clock error| of the ordinary nodes at the end (sync.final_mean_abs_error_s), low to high",
        "ITMTL lowest of ITMTL, ITMTL-wsc, Mobi-Sync, TSHL (curves lost: no numbers)",
        _ranking("sync.final_mean_abs_error_s", 1e6, " us"),
    ),
    Claim(
        "Fig. 10",
        "localization NMSE",
        "NMSE over the run (localization.nmse), low to high; paper: anchors only, 3-6 references",
        "ITMTL lowest of the four at every number of references (no numbers)",
        _ranking("localization.nmse", 1.0, ""),
    ),
    Claim(
        "Fig. 11",
        "sync error, ITMTL-wsc above ITMTL",
        "largest over iterations (rounds) of the per-round difference, % of ITMTL's",
        "56.67 %",
        _gap("sync_gap_pct", "max"),
    ),
    Claim(
        "Fig. 12",
        "NMSE, ITMTL below ITMTL-wsc",
        "difference at the same iteration (round), % of ITMTL-wsc's",
        "about 25.8 %",
        _gap("nmse_decrease_pct", "median"),
    ),
    Claim("Fig. 15", "range of sync and localization", "30 % vs 10 % anchors, density 10", "about 1.8x"),
    Claim("Fig. 16", "average sync error", "more anchors at the same density", "up to 48.07 % lower"),
    Claim("Fig. 17", "localization NMSE", "10 % vs 30 % anchors, density 3", "about 7.6x"),
)


def comparison(results: Mapping[str, Any]) -> pd.DataFrame | None:
    """One row per claim of :data:`CLAIMS` that one network can check: figure, quantity,
    statistic, ours, paper. ``results``: variant name -> run result (``scenario``,
    ``tables``, ``metrics``); the first variant running each algorithm is used. None when no
    variant runs ITMTL."""
    runs: dict[str, Any] = {}
    for res in results.values():
        a = algorithm(res.scenario)
        if a is not None and a not in runs:
            runs[a] = res
    if "ITMTL" not in runs:
        return None
    runs = {a: runs[a] for a in ALGORITHMS if a in runs}
    gap = None
    if "ITMTL-wsc" in runs:
        i, w = runs["ITMTL"].tables, runs["ITMTL-wsc"].tables
        gap = wsc_gap_per_round(node_rounds(i, "itmtl"), node_rounds(w, "itmtl"), i.get("nodes"))
    rows = [
        {
            "figure": c.figure,
            "quantity": c.quantity,
            "statistic": c.statistic,
            "ours": c.ours(runs, gap),
            "paper": c.paper,
        }
        for c in CLAIMS
        if c.ours is not None
    ]
    return pd.DataFrame(rows)
