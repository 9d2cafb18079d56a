"""Run metrics computed from trace tables only (pandas DataFrames, as `trace.load` returns).

Because nothing here touches a live simulation, the same functions serve the CLI at the end
of a run and an analyst reading CSV traces afterwards. Table layouts are those of
docs/internals.md (``packets``, ``positions``, ``estimates``, ``clocks``, ``nodes``).

One definition per quantity, shared by the generic ``localization.*`` / ``sync.*`` metrics and
every protocol family's metrics (docs/metrics.md gives the full rules):

- Evaluated nodes: those whose *role* (``nodes`` table) is an unknown-position role, by
  default ``ordinary`` and ``target``; optionally only those running one protocol. Every row
  of an evaluated node counts, including rows it logged as a promoted reference
  (``is_reference``): a promoted node is still estimating. Buoys and anchors never count.
  Without a ``nodes`` table (hand-made traces) the rows flagged ``is_reference`` are dropped
  instead.
- Rows: those with ``t_min <= time <= t_max`` (true time, s); ``final`` keeps each evaluated
  node's last row. Truth is what the kernel logged beside each row: the true position / time
  at the moment the row was logged.
- RMSE  = sqrt( mean ||x_hat - x||^2 )                                    [m]
- NMSE  = sum ||x_hat - x||^2 / sum ||x - x_bar||^2, x_bar the mean true position of the
  same rows                                                               [dimensionless]
  (ITMTL, Sun et al. Sec. 5; the printed formula is lost from our copy). Normalizing by the
  spread of the true positions about their centroid, not by ||x||^2, makes it independent of
  where the scenario's origin is.
- coverage = share of evaluated nodes with at least one row by ``until``   [0..1]
  A node that never localized counts here (as not covered) and nowhere else: it has no
  error to average.
- sync error = |error| of the ``clocks`` rows (the node's estimate of true time minus true
  time at the moment of logging, s); mean, percentiles, and the mean over final rows.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from .net.metrics import NetWindow, net_metrics

__all__ = [
    "UNKNOWN_ROLES",
    "coverage",
    "evaluated_nodes",
    "mean_error",
    "nmse",
    "packet_counts",
    "position_errors",
    "positions_at",
    "positions_source",
    "rmse",
    "rmse_h",
    "rmse_over_crb",
    "rmse_over_crb_interval",
    "rmse_per_node",
    "select_rows",
    "summarize",
    "summarize_runs",
    "sync_error_stats",
    "sync_errors",
    "tables_read",
    "unknown_nodes",
]

UNKNOWN_ROLES: tuple[str, ...] = ("ordinary", "target")
_XYZ = ["x", "y", "z"]
_TRUE_XYZ = ["true_x", "true_y", "true_z"]
_TRUE_FLAGS = [True, "True", "true"]


def evaluated_nodes(
    nodes: pd.DataFrame, roles: Iterable[str] = UNKNOWN_ROLES, protocol: str | None = None
) -> NDArray[np.int64]:
    """Ids of the nodes with one of ``roles`` (case-insensitive), optionally running ``protocol``."""
    wanted = {r.lower() for r in roles}
    mask = nodes["role"].astype(str).str.lower().isin(wanted)
    if protocol is not None and "protocol" in nodes.columns:
        mask &= nodes["protocol"].astype(str) == protocol
    return np.sort(nodes.loc[mask, "node"].to_numpy(np.int64))


def unknown_nodes(nodes: pd.DataFrame, roles: Iterable[str] = UNKNOWN_ROLES) -> NDArray[np.int64]:
    """Ids of the nodes whose role is one of ``roles`` (case-insensitive), from the ``nodes`` table."""
    return evaluated_nodes(nodes, roles)


def select_rows(
    table: pd.DataFrame,
    nodes: pd.DataFrame | None = None,
    *,
    roles: Iterable[str] = UNKNOWN_ROLES,
    protocol: str | None = None,
    t_min: float | None = None,
    t_max: float | None = None,
    final: bool = False,
) -> pd.DataFrame:
    """The rows of ``estimates`` / ``clocks`` a statistic uses (see the module docstring).

    ``nodes``: the run's ``nodes`` table (evaluated nodes by role; ``None``: drop the rows
    flagged ``is_reference`` instead). ``protocol``: only that protocol's nodes and rows.
    ``t_min`` / ``t_max``: true-time window (s, inclusive). ``final``: last row per node.
    """
    df = table
    if nodes is not None:
        df = df[df["node"].isin(evaluated_nodes(nodes, roles, protocol))]
    elif "is_reference" in df.columns:
        # None / NaN (a CSV round trip of an unset flag) count as "not a reference"
        df = df[~df["is_reference"].isin(_TRUE_FLAGS)]
    if protocol is not None and "protocol" in df.columns:
        df = df[df["protocol"].astype(str) == protocol]
    if t_min is not None and "time" in df.columns:
        df = df[df["time"] >= t_min]
    if t_max is not None and "time" in df.columns:
        df = df[df["time"] <= t_max]
    if final and len(df):
        # stable sort keeps the logging order among rows of equal time
        df = df.sort_values("time", kind="stable").groupby("node", sort=True).tail(1)
    return df


def _err_vectors(df: pd.DataFrame) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(x_hat - x, x) per row, (m, 3) each, from the estimate and truth columns."""
    x = df[_TRUE_XYZ].to_numpy(float)
    return df[_XYZ].to_numpy(float) - x, x


def position_errors(estimates: pd.DataFrame, nodes: pd.DataFrame | None = None, **select: Any) -> NDArray[np.float64]:
    """Euclidean position error ||x_hat - x|| (m) of each selected estimate row.

    Computed from the estimate and truth columns (not the logged ``error`` column), so a
    trace edited or filtered by hand stays consistent. ``select``: see :func:`select_rows`.
    """
    df = select_rows(estimates, nodes, **select)
    if len(df) == 0:
        return np.empty(0)
    d, _ = _err_vectors(df)
    return np.sqrt(np.einsum("ij,ij->i", d, d))


def rmse(estimates: pd.DataFrame, nodes: pd.DataFrame | None = None, **select: Any) -> float:
    """Root-mean-square position error (m) over the selected rows; NaN when none.

    ``nodes`` and ``select`` (``roles``, ``protocol``, ``t_min``, ``t_max``, ``final``): see
    :func:`select_rows`.
    """
    e = position_errors(estimates, nodes, **select)
    return float(np.sqrt(np.mean(e**2))) if e.size else float("nan")


def rmse_h(estimates: pd.DataFrame, nodes: pd.DataFrame | None = None, **select: Any) -> float:
    """Root-mean-square horizontal error sqrt(mean((x_hat - x)^2 + (y_hat - y)^2)) (m) over the
    selected rows (``select``: see :func:`select_rows`); NaN when none."""
    df = select_rows(estimates, nodes, **select)
    if len(df) == 0:
        return float("nan")
    d, _ = _err_vectors(df)
    return float(np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2)))


def rmse_over_crb(
    bounds: pd.DataFrame, nodes: pd.DataFrame | None = None, *, column: str = "crb_h_m", **select: Any
) -> float:
    """sqrt(mean e_h^2) / sqrt(mean b^2) over the selected rows of a run's ``bounds`` table
    (:func:`aquasim_py.estimate_bounds.estimate_bounds`) with a finite bound b in ``column``:
    the horizontal RMSE over the RMS of the bounds of the geometries the estimates used.
    ``column``: ``crb_h_m`` (the noise the simulation applied) or ``crb_h_declared_m`` (the
    noise each node declared). 1 is the bound of a one-shot unbiased fix from those ranges; a
    filter that fuses earlier rounds may go below it. NaN without such rows, or when their
    bounds are all 0 (noise-free ranges)."""
    return rmse_over_crb_interval(bounds, nodes, column=column, **select)[0]


def rmse_over_crb_interval(
    bounds: pd.DataFrame,
    nodes: pd.DataFrame | None = None,
    *,
    column: str = "crb_h_m",
    confidence: float = 0.95,
    **select: Any,
) -> tuple[float, float, float]:
    """(:func:`rmse_over_crb`, low, high): the ratio and its ``confidence`` interval, from the
    chi-square interval of a mean square with as many degrees of freedom as there are nodes
    among the rows (rows of one node are correlated: a filter's successive errors are, so
    counting rows would make the interval too narrow; counting nodes errs on the wide side).
    The bound itself is taken as exact (it is computed, not sampled)."""
    from scipy import stats

    nan = (float("nan"),) * 3
    df = select_rows(bounds, nodes, **select) if bounds is not None else None
    if df is None or len(df) == 0 or column not in df.columns:
        return nan
    crb = pd.to_numeric(df[column], errors="coerce").to_numpy(float)
    ok = np.isfinite(crb)
    if not ok.any():
        return nan
    bound = float(np.sqrt(np.mean(crb[ok] ** 2)))
    if bound == 0.0:  # noise-free ranges: no ratio
        return nan
    e = df["error_h"].to_numpy(float)[ok]
    ratio = float(np.sqrt(np.mean(e**2)) / bound)
    k = int(pd.unique(df["node"].to_numpy()[ok]).size)
    alpha = 1.0 - confidence
    low = ratio * math.sqrt(k / stats.chi2.ppf(1.0 - alpha / 2.0, k))
    high = ratio * math.sqrt(k / stats.chi2.ppf(alpha / 2.0, k))
    return ratio, low, high


def mean_error(estimates: pd.DataFrame, nodes: pd.DataFrame | None = None, **select: Any) -> float:
    """Mean Euclidean position error (m) over the selected rows; NaN when none."""
    e = position_errors(estimates, nodes, **select)
    return float(e.mean()) if e.size else float("nan")


def rmse_per_node(estimates: pd.DataFrame, nodes: pd.DataFrame | None = None, **select: Any) -> pd.Series:
    """RMSE (m) of each evaluated node over its own selected rows (index: node id)."""
    df = select_rows(estimates, nodes, **select)
    if len(df) == 0:
        return pd.Series(dtype=float)
    d, _ = _err_vectors(df)
    se = pd.Series(np.einsum("ij,ij->i", d, d), index=df["node"].to_numpy())
    return np.sqrt(se.groupby(level=0).mean())


def nmse(estimates: pd.DataFrame, nodes: pd.DataFrame | None = None, **select: Any) -> float:
    """sum ||x_hat - x||^2 / sum ||x - x_bar||^2 over the selected rows, x_bar their mean true
    position (origin-free; see the module docstring). NaN without rows or spread."""
    df = select_rows(estimates, nodes, **select)
    if len(df) == 0:
        return float("nan")
    d, x = _err_vectors(df)
    c = x - x.mean(axis=0)
    den = float(np.sum(c * c))
    return float(np.sum(d * d) / den) if den > 0.0 else float("nan")


def coverage(
    estimates: pd.DataFrame | None,
    candidates: Iterable[int],
    *,
    until: float | None = None,
) -> float:
    """Share of ``candidates`` (node ids: the evaluated nodes) with at least one row by ``until`` (s).

    Every row counts, reference-flagged ones too (a promoted node has localized). NaN when
    there are no candidates; 0 when nobody estimated anything.
    """
    cand = np.unique(np.fromiter(candidates, dtype=np.int64))
    if cand.size == 0:
        return float("nan")
    if estimates is None or len(estimates) == 0:
        return 0.0
    df = estimates if until is None else estimates[estimates["time"] <= until]
    have = np.unique(df["node"].to_numpy(np.int64))
    return float(np.isin(cand, have).sum() / cand.size)


def sync_errors(clocks: pd.DataFrame, nodes: pd.DataFrame | None = None, **select: Any) -> NDArray[np.float64]:
    """|error| (s) of the selected ``clocks`` rows (``nodes``, ``select``: see :func:`select_rows`)."""
    df = select_rows(clocks, nodes, **select)
    return np.abs(df["error"].to_numpy(float)) if len(df) else np.empty(0)


def sync_error_stats(
    clocks: pd.DataFrame,
    percentiles: Sequence[float] = (50.0, 95.0),
    *,
    nodes: pd.DataFrame | None = None,
    **select: Any,
) -> dict[str, float]:
    """Mean and percentiles of the absolute sync error over rows (s), plus the final-row mean."""
    e = sync_errors(clocks, nodes, **select)
    out: dict[str, float] = {"mean_abs_error_s": float(e.mean()) if e.size else float("nan")}
    for p in percentiles:
        out[f"p{_fmt_pct(p)}_abs_error_s"] = float(np.percentile(e, p)) if e.size else float("nan")
    ef = sync_errors(clocks, nodes, **{**select, "final": True})
    out["final_mean_abs_error_s"] = float(ef.mean()) if ef.size else float("nan")
    return out


def _fmt_pct(p: float) -> str:
    return f"{p:g}".replace(".", "_")


#: the columns of a table whose value combinations a streamed run counts as it writes them
#: (:meth:`aquasim_py.trace.Table.tally`): the packet counts, without reading ``packets`` back
TALLIED: dict[str, tuple[str, ...]] = {"packets": ("event", "reason")}


def packet_counts(
    packets: pd.DataFrame | Iterable[pd.DataFrame] | Mapping[tuple[Any, Any], int] | None,
) -> dict[str, int]:
    """Packets sent (tx), received (rx) and dropped, the drops also split by ``reason``.

    ``packets``: the ``packets`` table, or its ``event`` / ``reason`` columns in chunks
    (:meth:`aquasim_py.trace.TraceFiles.chunks`), so that a long run's table need not be
    held at once; or the rows per (event, reason) of a table of strings / None, as a
    streamed run counts them (:meth:`aquasim_py.trace.TraceFiles.tally`)."""
    out = {"sent": 0, "received": 0, "dropped": 0}
    if packets is None:
        return out
    reasons: dict[str, int] = {}
    frames: Iterable[pd.DataFrame] = [packets] if isinstance(packets, pd.DataFrame) else ()
    if isinstance(packets, Mapping):
        for (event, reason), n in packets.items():
            key = {"tx": "sent", "rx": "received", "drop": "dropped"}.get(event)
            if key is not None:
                out[key] += n
            if event == "drop":  # missing and "" are "unknown", as below
                why = "unknown" if reason is None or reason == "" else str(reason)
                reasons[why] = reasons.get(why, 0) + n
    elif not isinstance(packets, pd.DataFrame):
        frames = packets
    for chunk in frames:
        if len(chunk) == 0:
            continue
        ev = chunk["event"].astype(str)
        out["sent"] += int((ev == "tx").sum())
        out["received"] += int((ev == "rx").sum())
        drops = chunk[ev == "drop"]
        out["dropped"] += len(drops)
        if len(drops) and "reason" in drops.columns:
            why = drops["reason"].fillna("unknown").astype(str).replace("", "unknown")
            for reason, n in why.value_counts().items():
                reasons[str(reason)] = reasons.get(str(reason), 0) + int(n)
    for reason in sorted(reasons):
        out[f"dropped.{reason}"] = reasons[reason]
    return out


#: the tables the generic metrics of :func:`summarize` read (the bounds beside declared
#: estimates also read ``positions``: a protocol that declares its references lists it in its
#: ``trace_tables``, :mod:`aquasim_py.estimate_bounds`)
GENERIC_TABLES: tuple[str, ...] = ("packets", "estimates", "clocks", "nodes", "energy")


def energy_metrics(
    energy: pd.DataFrame | None,
    received: float = math.nan,
    estimates: pd.DataFrame | None = None,
    nodes: pd.DataFrame | None = None,
    roles: Iterable[str] = UNKNOWN_ROLES,
) -> dict[str, float]:
    """The ``energy.*`` metrics of a run from its ``energy`` table (aquasim_py.energy; each
    node's last row), for any protocol and MAC:

    - ``total_j``, ``per_node_j`` (mean), ``max_node_j``; ``tx_j``, ``rx_j``, ``idle_j``,
      ``sleep_j``: the network's energy by modem state;
    - ``per_delivered_packet_j``: total over ``received`` (the ``rx`` rows of ``packets``: every
      packet a node got, a broadcast counting once per receiver);
    - ``per_localized_node_j``: total over the evaluated nodes (``roles``) that logged at least
      one estimate (when ``estimates`` are given);
    - ``depleted_nodes``; ``first_depleted_s`` and ``half_depleted_s``: the network lifetime,
      the true time the first node's battery, and half of the battery-powered nodes' (rounded
      up), ran empty; NaN when that did not happen within the run.

    Empty when there is no energy table (energy is not counted)."""
    if energy is None or not len(energy):
        return {}
    last = energy.sort_values("time", kind="stable").groupby("node", sort=True).tail(1)
    total = float(last["energy_j"].sum())
    out: dict[str, float] = {
        "total_j": total,
        "per_node_j": float(last["energy_j"].mean()),
        "max_node_j": float(last["energy_j"].max()),
    }
    for state in ("tx", "rx", "idle", "sleep"):
        out[f"{state}_j"] = float(last[f"{state}_j"].sum())
    out["per_delivered_packet_j"] = total / received if received > 0 else math.nan
    if estimates is not None:
        have = estimates["node"].unique() if len(estimates) else np.zeros(0, dtype=np.int64)
        if nodes is not None:
            have = np.intersect1d(have, evaluated_nodes(nodes, roles))
        out["per_localized_node_j"] = total / len(have) if len(have) else math.nan
    batteries = int(last["capacity_j"].notna().sum())
    dead = np.sort(last["depleted_at"].dropna().to_numpy(float))
    out["depleted_nodes"] = len(dead)  # an int (a count)
    out["first_depleted_s"] = float(dead[0]) if len(dead) else math.nan
    half = math.ceil(batteries / 2)
    out["half_depleted_s"] = float(dead[half - 1]) if batteries and len(dead) >= half else math.nan
    return out


def tables_read(protocols: Iterable[type]) -> set[str] | None:
    """The trace tables :func:`summarize` and the protocols' ``metrics`` / ``derived_tables``
    / ``report`` read: the generic ones and each protocol's ``trace_tables``; None when a
    protocol does not say (then every table)."""
    out = set(GENERIC_TABLES)
    for cls in protocols:
        declared = getattr(cls, "trace_tables", None)
        if declared is None:
            return None
        out.update(declared)
    return out


def columns_kept(protocols: Iterable[type]) -> dict[str, tuple[str, ...]]:
    """The columns of trace tables the protocols' metrics read whole (each protocol's
    ``trace_columns``: table -> columns), which a streamed run keeps as it writes the files
    (:meth:`aquasim_py.trace.Table.keep`) instead of parsing them back."""
    out: dict[str, tuple[str, ...]] = {}
    for cls in protocols:
        for name, columns in getattr(cls, "trace_columns", {}).items():
            out[name] = tuple(dict.fromkeys(out.get(name, ()) + tuple(columns)))
    return out


class _AfterWarmup(Mapping[str, Any]):
    """``tables`` with the ``estimates`` and ``clocks`` rows before ``t0`` (s) left out, each
    table filtered when asked for (a lazily read trace stays lazy)."""

    def __init__(self, tables: Mapping[str, Any], t0: float) -> None:
        self._tables, self._t0 = tables, t0
        self._cache: dict[str, Any] = {}  # one filtered copy per table, whoever asks

    def __getitem__(self, name: str) -> Any:
        if name not in ("estimates", "clocks"):
            return self._tables[name]
        if name not in self._cache:
            self._cache[name] = _after(self._tables[name], self._t0)
        return self._cache[name]

    def __contains__(self, name: object) -> bool:
        return name in self._tables

    def columns(self, name: str, columns: Sequence[str]) -> Any:
        """As ``TraceFiles.columns`` (:func:`aquasim_py.trace.table_columns`), after the warm-up."""
        from aquasim_py.trace import table_columns

        if name in ("estimates", "clocks"):
            df = self[name]
            return df[[c for c in df.columns if c in columns]]
        df = table_columns(self._tables, name, columns)
        if df is None:
            raise KeyError(name)
        return df

    def __iter__(self) -> Iterator[str]:
        return iter(self._tables)

    def __len__(self) -> int:
        return len(self._tables)


def positions_at(
    positions: pd.DataFrame | Iterable[pd.DataFrame], node: ArrayLike, time: ArrayLike
) -> NDArray[np.float64]:
    """True positions (n, 3) of ``node[i]`` at ``time[i]`` from the sampled ``positions`` table.

    Between samples: linear interpolation, exact for straight motion; for curved motion the
    error is at most |acceleration| * interval^2 / 8 (choose ``trace.position_interval_s``
    accordingly). Before the first / after the last sample: extrapolation with that sample's
    velocity (``vx, vy, vz``; held constant if the table has none), since a run's last events
    (receptions still in flight) fall after its last sample. NaN for a node with no sample.

    ``positions``: the table, or the table in consecutive chunks of rows (as
    :func:`positions_source` gives for a streamed run, so that a long run's table is never
    held whole), each node's rows in time order across the chunks (the order the kernel
    samples them). Both give the same numbers, bit for bit: each query is interpolated
    between the same two samples.
    """
    node = np.asarray(node, dtype=np.int64).ravel()
    time = np.asarray(time, dtype=float).ravel()
    out = np.full((node.size, 3), np.nan)
    if node.size == 0:
        return out
    # the queries of each node in time order (stable), from one sort instead of a pass per node
    order = np.lexsort((time, node))
    ids, starts = np.unique(node[order], return_index=True)
    queries = dict(zip(ids.tolist(), np.split(order, starts[1:])))
    if isinstance(positions, pd.DataFrame):
        chunks: Iterable[pd.DataFrame] = [positions.sort_values(["node", "time"], kind="stable")]
    else:
        chunks = positions
    # node -> (its last sample so far: one-row frame; how many of its queries are answered)
    state: dict[int, tuple[pd.DataFrame, int]] = {}
    has_v = True
    for chunk in chunks:
        if len(chunk) == 0:
            continue
        has_v = all(c in chunk.columns for c in ("vx", "vy", "vz"))
        for nid, grp in chunk.groupby("node", sort=False):
            sel = queries.get(int(nid))
            if sel is None:
                continue
            first = int(nid) not in state
            last, done = state.get(int(nid), (grp.iloc[:0], 0))
            grp = pd.concat([last, grp]) if len(last) else grp
            t = grp["time"].to_numpy(float)
            # this chunk answers the queries up to its last sample (all of them, if it is the
            # last chunk: answered after the loop) and, for the node's first, those before it
            upto = done + int(np.searchsorted(time[sel[done:]], t[-1], side="right"))
            state[int(nid)] = (grp.iloc[-1:], upto)
            _interpolate(out, sel[done:upto], time, grp, t, before=first, after=False, has_v=has_v)
    for nid, (last, done) in state.items():  # after every node's last sample: extrapolation
        sel = queries[nid]
        if done < len(sel):
            _interpolate(out, sel[done:], time, last, last["time"].to_numpy(float), False, True, has_v)
    return out


def _interpolate(
    out: NDArray[np.float64],
    sel: NDArray[np.int64],
    time: NDArray[np.float64],
    grp: pd.DataFrame,
    t: NDArray[np.float64],
    before: bool,
    after: bool,
    has_v: bool,
) -> None:
    """``out[sel]`` = one node's positions at ``time[sel]`` from its samples ``grp`` (times
    ``t``): np.interp inside them, the first (``before``) / last (``after``) sample's velocity
    outside."""
    if not len(sel):
        return
    q = time[sel]
    early = q < t[0] if before else np.zeros(q.size, dtype=bool)
    late = q > t[-1] if after else np.zeros(q.size, dtype=bool)
    for k, col in enumerate(_XYZ):
        x = grp[col].to_numpy(float)
        val = np.interp(q, t, x)
        if has_v:
            v = grp[f"v{col}"].to_numpy(float)
            val = np.where(early, x[0] + v[0] * (q - t[0]), val)
            val = np.where(late, x[-1] + v[-1] * (q - t[-1]), val)
        out[sel, k] = val


#: the columns of ``positions`` that :func:`positions_at` reads
POSITION_COLUMNS: tuple[str, ...] = ("time", "node", "x", "y", "z", "vx", "vy", "vz")


def positions_source(tables: Mapping[str, pd.DataFrame], chunk_rows: int = 4096) -> Any:
    """What :func:`positions_at` should read from a run's ``tables``: the ``positions`` table in
    chunks of ``chunk_rows`` rows from a streamed run's file (memory flat in the run's length),
    else the table itself; None without one."""
    if "positions" not in tables:
        return None
    chunks = getattr(tables, "chunks", None)
    if chunks is not None:
        return chunks("positions", POSITION_COLUMNS, chunk_rows, typed=True)
    return tables["positions"]


def summarize(
    tables: Mapping[str, pd.DataFrame],
    protocols: Iterable[type] | None = None,
    *,
    percentiles: Sequence[float] = (50.0, 95.0),
    warmup_s: float = 0.0,
    unknown_roles: Iterable[str] = UNKNOWN_ROLES,
    errors: dict[str, str] | None = None,
    bounds: pd.DataFrame | None = None,
    network: NetWindow | None = None,
) -> dict[str, float]:
    """Every metric of a run, as a flat {name: number} dict (the CLI table, summary.json, sweep.csv).

    ``bounds``: the run's bounds table (:func:`aquasim_py.estimate_bounds.estimate_bounds`;
    default ``tables["bounds"]`` where there is one, as in a run's output directory), for
    ``localization.crb_h_m``, ``range_std_m`` and ``rmse_over_crb`` (``_ci95_high``, ``_declared``).

    ``errors``: when given, a metric family that raises (a protocol's ``metrics()``, e.g. a
    singular Fisher information in a bound; or the generic localization / sync metrics) is
    recorded there as ``{family: "ExceptionType: message"}`` and the other metrics are still
    computed; when None, the exception propagates.

    ``protocols``: the Node subclasses of the run; each one's ``metrics(tables)`` is added with
    its name as prefix. ``None``: the protocols named in the ``nodes`` table, through the registry.
    ``warmup_s``: ``estimates`` and ``clocks`` rows before it are dropped, for the generic
    metrics and the protocols' alike (one time window for every family).
    ``network``: the window and airtime of the network metrics (``net.*``,
    :func:`aquasim_py.net.metrics.net_metrics`), computed only when given.
    """
    out: dict[str, float] = {}
    tally = getattr(tables, "tally", None)  # a streamed run's files: counted as written
    chunks = getattr(tables, "chunks", None)  # or read in chunks, without loading the table
    packets: Any = tally("packets", TALLIED["packets"]) if tally is not None else None
    if packets is None and chunks is not None and "packets" in tables:
        # 16384 rows a chunk: two text columns, about 2 MB; 4096-row chunks took twice the CPU
        packets = chunks("packets", ["event", "reason"], 16384)
    for k, v in packet_counts(packets if packets is not None else tables.get("packets")).items():
        out[f"packets.{k}"] = v
    if bounds is None:
        bounds = tables.get("bounds")
    if warmup_s > 0:
        bounds = _after(bounds, warmup_s)
        tables = _AfterWarmup(tables, warmup_s)
    est = tables.get("estimates")
    nodes = tables.get("nodes")
    if nodes is not None and len(nodes) == 0:
        nodes = None
    roles = tuple(unknown_roles)

    def localization() -> dict[str, float]:
        loc: dict[str, float] = {}
        if est is not None and len(est):
            loc["estimates"] = len(select_rows(est, nodes, roles=roles))  # an int (a count)
            loc["rmse_m"] = rmse(est, nodes, roles=roles)
            loc["final_rmse_m"] = rmse(est, nodes, roles=roles, final=True)
            loc["nmse"] = nmse(est, nodes, roles=roles)
            if nodes is not None:
                loc["coverage"] = coverage(est, evaluated_nodes(nodes, roles))
            loc["rmse_h_m"] = rmse_h(est, nodes, roles=roles)
            loc.update(_bound_metrics(bounds, nodes, roles))
        return loc

    def sync() -> dict[str, float]:
        clk = tables.get("clocks")
        if clk is None or not len(clk):
            return {}
        return sync_error_stats(clk, percentiles, nodes=nodes, roles=roles)

    def energy() -> dict[str, float]:
        return energy_metrics(tables.get("energy"), out.get("packets.received", math.nan), est, nodes, roles)

    families: list[tuple[str, Callable[[], Mapping[str, float] | None]]] = [
        ("localization", localization),
        ("sync", sync),
        ("energy", energy),
    ]
    if network is not None:
        families.append(("net", functools.partial(net_metrics, tables, network)))
    if protocols is None:
        protocols = _protocols_from_nodes(nodes)
    seen: set[str] = set()
    for cls in protocols:
        name = getattr(cls, "name", cls.__name__)
        fn = getattr(cls, "metrics", None)
        if name in seen or fn is None:
            continue
        seen.add(name)
        families.append((name, functools.partial(fn, tables)))
    for name, compute in families:
        try:
            values: dict[str, Any] = dict(compute() or {})
        except Exception as e:  # one failed family must not lose the run (issue 20 item 5)
            if errors is None:
                raise
            errors[name] = f"{type(e).__name__}: {e}".strip()
            continue
        for k, val in values.items():
            if errors is not None and isinstance(val, (float, np.floating)) and math.isinf(val):
                # an infinite metric has no documented meaning: undefined (NaN), and said why
                errors[f"{name}.{k}"] = f"non-finite value {float(val)}"
                val = math.nan
            out[f"{name}.{k}"] = val
    return out


def _bound_metrics(bounds: pd.DataFrame | None, nodes: pd.DataFrame | None, roles: tuple[str, ...]) -> dict[str, float]:
    """The bound metrics of the evaluated rows of a bounds table; only where some estimate
    declared its references (and the ratios only where a bound is not 0)."""
    if bounds is None or len(bounds) == 0:
        return {}
    b = select_rows(bounds, nodes, roles=roles)
    out: dict[str, float] = {}
    for name, col in (("range_std_m", "range_std_m"), ("crb_h_m", "crb_h_m")):
        v = b[col].to_numpy(float) if len(b) else np.empty(0)
        v = v[np.isfinite(v)]
        if v.size:
            out[name] = float(np.sqrt(np.mean(v**2)))
    ratio, _, high = rmse_over_crb_interval(bounds, nodes, roles=roles)
    if not math.isnan(ratio):
        out["rmse_over_crb"] = ratio
        out["rmse_over_crb_ci95_high"] = high
    declared = rmse_over_crb(bounds, nodes, column="crb_h_declared_m", roles=roles)
    if not math.isnan(declared):
        out["rmse_over_crb_declared"] = declared
    return out


def _after(df: pd.DataFrame | None, t0: float) -> pd.DataFrame | None:
    return df if df is None or "time" not in df.columns else df[df["time"] >= t0]


def summarize_runs(
    runs: pd.DataFrame,
    by: Sequence[str] = (),
    metrics: Sequence[str] | None = None,
    *,
    confidence: float = 0.95,
) -> pd.DataFrame:
    """Mean over runs (seeds) with a Student-t confidence interval, per group and metric.

    ``runs``: one row per run (e.g. ``sweep.csv``); ``by``: the columns that define a point
    (swept parameters, ``variant``); ``metrics``: the columns to summarize (default: every
    numeric column but ``by``, ``run`` and ``seed``). Non-finite values (a run where a metric
    was undefined) are left out and ``n`` counts the rest.

    Returns one row per (group, metric): the ``by`` columns, ``metric``, ``n``, ``mean``,
    ``std`` (ddof 1) and ``ci95_low`` / ``ci95_high`` (named after ``confidence``):
    mean -/+ t_{(1 + confidence) / 2, n - 1} std / sqrt(n), the t interval for the mean of
    independent runs. NaN bounds for n < 2; both bounds equal the mean when std = 0.
    """
    from scipy import stats

    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence!r}")
    by = list(by)
    missing = [c for c in by if c not in runs.columns]
    if missing:
        raise ValueError(f"summarize_runs: no column {missing[0]!r} in the runs table")
    if metrics is None:
        skip = set(by) | {"run", "seed"}
        metrics = [c for c in runs.columns if c not in skip and pd.api.types.is_numeric_dtype(runs[c])]
    tag = f"ci{confidence * 100:g}".replace(".", "_")
    long = runs.melt(id_vars=by, value_vars=list(metrics), var_name="metric", value_name="value")
    long["value"] = pd.to_numeric(long["value"], errors="coerce")
    long = long[np.isfinite(long["value"].to_numpy(float))]
    keys = [*by, "metric"]
    g = long.groupby(keys, sort=False, dropna=False)["value"]
    out = g.agg(n="count", mean="mean", std="std").reset_index()
    n = out["n"].to_numpy(float)
    mean = out["mean"].to_numpy(float)
    std = out["std"].to_numpy(float)
    half = np.full(len(out), np.nan)
    ok = n >= 2
    half[ok] = stats.t.ppf(0.5 + confidence / 2.0, n[ok] - 1.0) * std[ok] / np.sqrt(n[ok])
    out[f"{tag}_low"] = mean - half
    out[f"{tag}_high"] = mean + half
    out["n"] = out["n"].astype(int)
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
