"""Trackers' output as Stone Soup tracks and ground truth, scored by OSPA and GOSPA.

A tracker's estimates are read from the trace tables it already writes (:class:`TrackSource`:
which table, which column is the estimate's instant, whose truth it is, which columns split
it into tracks). :func:`track_data` gives, per track, the estimate and the true position at
every step the tracker ran, and also the truth at the steps it skipped (a gap in its step
counter): a missed step costs OSPA / GOSPA their cut-off, where our RMSE, over the logged
estimates only, does not see it. :func:`to_stonesoup` turns one into a Stone Soup
:class:`~stonesoup.types.track.Track` and :class:`~stonesoup.types.groundtruth.GroundTruthPath`
(timestamps: seconds of simulation time after :data:`EPOCH`), and :func:`scores` computes
Stone Soup's :class:`~stonesoup.metricgenerator.ospametric.OSPAMetric` and
:class:`~stonesoup.metricgenerator.ospametric.GOSPAMetric` (alpha = 2) per track, each track
against its own target's path (estimators of one target are scored apart, not as clutter of
each other), beside the RMSE of the same estimates.

Stone Soup is the optional extra ``aquasim-py[stonesoup]``; without it the reports say how to
get the scores and everything else works.

Sources: a protocol class may declare ``track_source`` (a :class:`TrackSource`);
:data:`SOURCES` holds the readings of the shipped trackers' tables (MSWPF, SVL-PF, Ramezani
tracking), by protocol name, for those that do not.
"""

from __future__ import annotations

import html
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any, Literal

import numpy as np
import pandas as pd

__all__ = [
    "C_M",
    "EPOCH",
    "SOURCES",
    "P",
    "TrackData",
    "TrackSource",
    "report_section",
    "scores",
    "to_stonesoup",
    "track_data",
]

#: Stone Soup timestamps: simulation time t (s) is EPOCH + t
EPOCH = datetime(2000, 1, 1)
#: OSPA / GOSPA cut-off (m): an error above it, or a missed step, counts as this much
C_M = 10.0
#: OSPA / GOSPA order
P = 2

_STONESOUP = "pip install 'aquasim-py[stonesoup]'"


@dataclass(frozen=True)
class TrackSource:
    """Where a tracker's estimates are in its trace tables.

    ``table``: the table (columns x, y, z and those named here); ``time``: the column holding
    the instant each estimate is of (s; local time, taken as true time as the protocols'
    metrics do, unless ``uid``); ``uid``: a packet uid column whose transmission (``packets``
    tx row) is that instant; ``truth``: ``"target"`` (the target-role node of the protocol,
    from ``positions``) or ``"self"`` (the logging node, the row's true_x/y/z); ``step``: the
    step counter (a gap is a missed step); ``by``: columns that split rows into tracks;
    ``where``: (column, value) pairs a row must have."""

    table: str
    time: str = "time"
    truth: Literal["target", "self"] = "target"
    uid: str | None = None
    step: str | None = None
    by: tuple[str, ...] = ()
    where: tuple[tuple[str, str], ...] = ()


#: the shipped trackers, read from the tables they log (protocol name -> source)
SOURCES: dict[str, TrackSource] = {
    "mswpf": TrackSource("mswpf_steps", time="t_step", step="step"),
    "svlpf": TrackSource("svlpf", time="t_req_local", uid="req_uid", step="k", by=("algorithm",)),
    "ramezani": TrackSource(
        "estimates", truth="self", step="frame", by=("node", "model"), where=(("mode", "tracking"),)
    ),
}


@dataclass
class TrackData:
    """One track: per step the instant (s), the estimate (NaN when the step was missed) and
    the truth, (n,) and (n, 3) arrays in time order."""

    name: str
    protocol: str
    time: np.ndarray
    est: np.ndarray
    truth: np.ndarray

    @property
    def logged(self) -> np.ndarray:
        return np.isfinite(self.est).all(axis=1)

    def rmse(self) -> float:
        """sqrt(mean squared position error) over the logged estimates (m)."""
        d = np.linalg.norm(self.est[self.logged] - self.truth[self.logged], axis=1)
        return float(np.sqrt(np.mean(d**2))) if d.size else float("nan")


def _source(name: str) -> TrackSource | None:
    from aquasim_py import registry

    try:
        own = getattr(registry.get(name), "track_source", None)
    except KeyError:
        own = None
    return own if isinstance(own, TrackSource) else SOURCES.get(name)


def track_data(tables: Mapping[str, pd.DataFrame]) -> list[TrackData]:
    """Every track of every tracker in a run's tables (the protocols of its ``nodes`` table)."""
    nodes = tables.get("nodes")
    if nodes is None or "protocol" not in nodes.columns:
        return []
    out: list[TrackData] = []
    for name in pd.unique(nodes["protocol"].astype(str)):
        src = _source(name)
        if src is None or tables.get(src.table) is None:
            continue
        out += _tracks(tables, str(name), src)
    return out


def _tracks(tables: Mapping[str, pd.DataFrame], protocol: str, src: TrackSource) -> list[TrackData]:
    from aquasim_py.metrics import positions_at

    rows = tables[src.table]
    if "protocol" in rows.columns:
        rows = rows[rows["protocol"].astype(str) == protocol]
    for col, value in src.where:
        rows = rows[rows[col].astype(str) == value] if col in rows.columns else rows
    if rows.empty:
        return []
    pos = tables.get("positions")
    if src.uid is not None:
        pk = tables["packets"]
        tx = pk[pk["event"] == "tx"].drop_duplicates("uid").set_index("uid")["time"]
        rows = rows.assign(_t=tx.reindex(rows[src.uid].to_numpy()).to_numpy(float))
    else:
        rows = rows.assign(_t=rows[src.time].to_numpy(float))
    target = None
    if src.truth == "target":
        n = tables["nodes"]
        t = n.loc[(n["role"].astype(str) == "target") & (n["protocol"].astype(str) == protocol), "node"]
        if not len(t) or pos is None:
            return []
        target = int(t.iloc[0])
    groups = rows.groupby(list(src.by), sort=False) if src.by else [((), rows)]
    out = []
    for key, g in groups:
        key = key if isinstance(key, tuple) else (key,)
        g = g.sort_values(src.step or "_t", kind="stable").drop_duplicates(src.step or "_t", keep="last")
        t_log = g["_t"].to_numpy(float)
        est_log = g[["x", "y", "z"]].to_numpy(float)
        if src.step is not None:  # every step from the first to the last, the missed ones too
            k_log = g[src.step].to_numpy(float)
            steps = np.arange(k_log[0], k_log[-1] + 1)
            t = np.interp(steps, k_log, t_log)
            est = np.full((steps.size, 3), np.nan)
            est[np.searchsorted(steps, k_log)] = est_log
        else:
            t, est = t_log, est_log
        node = target if target is not None else int(g["node"].iloc[0])
        truth = positions_at(pos, np.full(t.size, node), t) if pos is not None else np.full((t.size, 3), np.nan)
        if src.truth == "self":  # the kernel's truth at the logging instant, where there is a row
            truth[np.isin(t, t_log)] = g[["true_x", "true_y", "true_z"]].to_numpy(float)
        label = " ".join([protocol, *(f"{c}={v}" for c, v in zip(src.by, key))])
        out.append(TrackData(label, protocol, t, est, truth))
    return out


def _stamp(t: float) -> datetime:
    return EPOCH + timedelta(seconds=float(t))


def to_stonesoup(track: TrackData) -> tuple[Any, Any]:
    """``(Track, GroundTruthPath)`` of Stone Soup: the logged estimates as states [x, y, z]
    (m), the truth at every step (missed ones included), timestamps :data:`EPOCH` + t."""
    from stonesoup.types.groundtruth import GroundTruthPath, GroundTruthState
    from stonesoup.types.state import State
    from stonesoup.types.track import Track

    ok = track.logged
    states = [State(e.reshape(3, 1), timestamp=_stamp(t)) for t, e in zip(track.time[ok], track.est[ok])]
    truth = [GroundTruthState(x.reshape(3, 1), timestamp=_stamp(t)) for t, x in zip(track.time, track.truth)]
    return Track(states, id=track.name), GroundTruthPath(truth, id=f"truth of {track.name}")


def scores(tracks: Sequence[TrackData], c: float = C_M, p: int = P) -> pd.DataFrame:
    """Per track: steps, missed steps, our RMSE (m), and the time means (over every step) of
    Stone Soup's OSPA and GOSPA (cut-off ``c`` m, order ``p``, GOSPA alpha = 2), each track
    against its own truth path. Raises ImportError without Stone Soup."""
    from stonesoup.measures import Euclidean
    from stonesoup.metricgenerator.manager import MultiManager
    from stonesoup.metricgenerator.ospametric import GOSPAMetric, OSPAMetric

    rows = []
    for tr in tracks:
        track, truth = to_stonesoup(tr)
        gens = [OSPAMetric(c=c, p=p, measure=Euclidean()), GOSPAMetric(c=c, p=p, measure=Euclidean())]
        manager = MultiManager(gens)
        manager.add_data({"tracks": {track}, "groundtruth_paths": {truth}})
        metrics = manager.generate_metrics()
        ospa = _series(metrics["ospa_generator"]["OSPA distances"])
        gospa = _series(metrics["gospa_generator"]["GOSPA Metrics"], key="distance")
        rows.append(
            {
                "track": tr.name,
                "steps": int(tr.time.size),
                "missed": int((~tr.logged).sum()),
                "rmse_m": tr.rmse(),
                "ospa_mean_m": float(np.mean(ospa)),
                "gospa_mean_m": float(np.mean(gospa)),
            }
        )
    return pd.DataFrame(rows, columns=["track", "steps", "missed", "rmse_m", "ospa_mean_m", "gospa_mean_m"])


def _series(metric: Any, key: str | None = None) -> np.ndarray:
    values = metric.value if isinstance(metric.value, list) else [metric]
    return np.array([v.value[key] if key else v.value for v in values], dtype=float)


def report_section(tables: Mapping[str, pd.DataFrame], metrics: Mapping[str, Any]) -> str:
    """The run report's HTML section on the trackers' tracks ("" when the run has none)."""
    found = track_data(tables)
    if not found:
        return ""
    head = "<h2>Tracks scored by Stone Soup</h2>"
    try:
        s = scores(found)
    except ImportError:
        return head + f"<p>{len(found)} tracks; OSPA and GOSPA need Stone Soup: <code>{_STONESOUP}</code>.</p>"
    ours = {
        p: [k for k in metrics if k.startswith(f"{p}.") and k.endswith("rmse_m")] for p in {t.protocol for t in found}
    }
    body = s.to_html(index=False, float_format=lambda v: f"{v:.4g}")
    note = (
        f"<p>OSPA and GOSPA (alpha = 2) of order p = {P} with cut-off c = {C_M:g} m, by Stone Soup, time means over "
        "every step of each track (a missed step counts c for OSPA, c / 2^(1/p) for GOSPA); rmse_m over the logged "
        "estimates of the same table. The protocols' own RMSE metrics: "
        + html.escape(", ".join(f"{k} = {metrics[k]:.4g}" for ks in ours.values() for k in ks if _finite(metrics[k])))
        + ".</p>"
    )
    return head + body + note


def _finite(v: Any) -> bool:
    return isinstance(v, (int, float)) and np.isfinite(v)
