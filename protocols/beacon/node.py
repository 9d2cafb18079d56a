"""Beacon ranging: the smallest useful protocol, and the template for new ones.

Anchors (and buoys) broadcast a ``beacon`` every ``period_s`` seconds of their own clock,
carrying their position as they know it; the modem adds the MAC transmit stamp ``tx_local``.
Every other node listens and turns each beacon into a one-way time-of-arrival range

    range = (rx_local - tx_local) * nominal_speed_mps                       [m]

which is exact only when both clocks agree, the sound speed equals the nominal one and the
ray is straight: the range error measures exactly those effects (clock offset and skew,
timestamp jitter, ray bending, sound-speed mismatch). Each range goes to the ``ranges`` table.

The protocol never sees ground truth. The true range is computed afterwards, in
:meth:`BeaconNode.metrics`, from the trace alone: the packet's true send and arrival times (the
``packets`` table, by uid) and the true positions at those times (the ``positions`` table,
interpolated), so the same numbers come out of a CSV trace read back later.
"""

from __future__ import annotations

from collections.abc import Generator, Mapping
from typing import Any, ClassVar

import numpy as np
import pandas as pd
from pydantic import BaseModel, ConfigDict, Field

from aquasim_py.metrics import positions_at, positions_source
from aquasim_py.node import Node, Role, SensorUnavailable
from aquasim_py.registry import register
from aquasim_py.trace import table_columns

__all__ = ["BeaconNode", "range_errors", "true_ranges"]

_BROADCASTERS = (Role.ANCHOR, Role.BUOY)
#: the columns of ``ranges`` the metrics read (only these are parsed from a streamed run's file)
_RANGE_COLUMNS = ("uid", "node", "anchor", "range_m")
#: the columns of ``packets`` they read (kept as a streamed run writes them: trace_columns)
_PACKET_COLUMNS = ("event", "uid", "node", "time")


@register
class BeaconNode(Node):
    """Anchors and buoys broadcast beacons; everyone else logs one-way ToA ranges."""

    name = "beacon"
    trace_tables = ("ranges", "packets", "positions")  # what metrics / derived_tables / report read
    # read whole: kept as a streamed run writes them, not parsed back (metrics.columns_kept)
    trace_columns: ClassVar[dict[str, tuple[str, ...]]] = {"packets": _PACKET_COLUMNS}
    # anchors never take the beacons they hear from each other: keep only the last few (the
    # default 4096 per node grew a long run's memory by their packets, issue 35 item 8)
    inbox_capacity: ClassVar[int | None] = 256

    class Params(BaseModel):
        model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

        period_s: float = Field(10.0, gt=0.0, description="time between an anchor's beacons (s, local clock)")
        nominal_speed_mps: float = Field(1500.0, gt=0.0, description="sound speed assumed for ranging (m/s)")
        bits: int = Field(128, ge=1, description="beacon length (bits)")
        random_phase: bool = Field(True, description="first beacon at a random time in [0, period_s)")

    def run(self) -> Generator[Any, Any, None]:
        if self.role in _BROADCASTERS:
            yield from self._broadcast_loop()
        else:
            yield from self._listen_loop()

    def _own_position(self) -> list[float] | None:
        # An anchor knows where it is (survey or GPS fix, with the group's noise). A broadcaster
        # without a fix (sensors.position_fix = false) sends no position: ranging and its
        # metrics do not need it.
        try:
            return np.asarray(self.known_position(), dtype=float).ravel().tolist()  # Python floats
        except SensorUnavailable:
            return None

    def _broadcast_loop(self) -> Generator[Any, Any, None]:
        p = self.params
        if p.random_phase:
            yield self.sleep(float(self.rng.uniform(0.0, p.period_s)))
        while True:
            started = self.local_time()
            yield self.broadcast("beacon", {"position": self._own_position()}, bits=p.bits)
            # keep a fixed period on the local clock whatever the air time was
            yield self.sleep(max(0.0, p.period_s - (self.local_time() - started)))

    def _listen_loop(self) -> Generator[Any, Any, None]:
        c = self.params.nominal_speed_mps
        while True:
            rx = yield self.recv(kinds="beacon")
            pkt = rx.packet
            pos = (pkt.payload or {}).get("position") or [np.nan, np.nan, np.nan]
            self.log(
                "ranges",
                anchor=pkt.src,
                uid=pkt.uid,
                tx_local=pkt.tx_local,
                rx_local=rx.rx_local,
                range_m=(rx.rx_local - pkt.tx_local) * c,
                anchor_x=float(pos[0]),
                anchor_y=float(pos[1]),
                anchor_z=float(pos[2]),
            )

    # -- after the run ------------------------------------------------------------------------

    @classmethod
    def metrics(cls, tables: Mapping[str, pd.DataFrame]) -> dict[str, float]:
        """Range error statistics (m): count, mean, std (ddof 1), RMSE, max |error|."""
        err = range_errors(tables)
        e = err["error_m"].to_numpy(float) if len(err) else np.empty(0)
        e = e[np.isfinite(e)]
        nan = float("nan")
        return {
            "ranges": int(e.size),
            "range_error_mean_m": float(e.mean()) if e.size else nan,
            "range_error_std_m": float(e.std(ddof=1)) if e.size > 1 else nan,
            "range_rmse_m": float(np.sqrt(np.mean(e**2))) if e.size else nan,
            "range_error_max_abs_m": float(np.abs(e).max()) if e.size else nan,
        }

    @classmethod
    def derived_tables(cls, tables: Mapping[str, pd.DataFrame]) -> dict[str, pd.DataFrame]:
        """The per-anchor range-error table the report prints, as ``beacon_range_errors``."""
        err = range_errors(tables)
        if len(err) == 0:
            return {}
        g = err.groupby("anchor", sort=True)["error_m"]
        rmse = g.apply(lambda e: float(np.sqrt(np.mean(e.to_numpy(float) ** 2))))
        agg = pd.DataFrame({"ranges": g.size(), "mean_m": g.mean(), "std_m": g.std(ddof=1), "rmse_m": rmse})
        return {"beacon_range_errors": agg.reset_index()}

    @classmethod
    def report(cls, tables: Mapping[str, pd.DataFrame]) -> Any:
        """Per-anchor range error table (a rich Table), printed by the CLI after the metrics."""
        from rich.table import Table

        err = range_errors(tables)
        t = Table(title="beacon: range error per anchor (m)")
        for col in ("anchor", "ranges", "mean", "std", "RMSE"):
            t.add_column(col, justify="right")
        if len(err) == 0:
            return t
        for anchor, g in err.groupby("anchor", sort=True):
            e = g["error_m"].to_numpy(float)
            std = f"{e.std(ddof=1):.4g}" if e.size > 1 else "-"
            t.add_row(str(anchor), str(e.size), f"{e.mean():.4g}", std, f"{np.sqrt(np.mean(e**2)):.4g}")
        return t


def true_ranges(tables: Mapping[str, pd.DataFrame], ranges: pd.DataFrame | None = None) -> pd.DataFrame:
    """True ranges (m) for the rows of ``ranges``: the distance from the sender's position when
    the first bit left to the receiver's position when it arrived (the times from the
    ``packets`` table by uid, the positions interpolated from the ``positions`` table)."""
    r = table_columns(tables, "ranges", _RANGE_COLUMNS) if ranges is None else ranges
    packets = table_columns(tables, "packets", _PACKET_COLUMNS)
    if r is None or len(r) == 0 or packets is None or "positions" not in tables:
        return pd.DataFrame(columns=["uid", "node", "anchor", "t_tx", "t_rx", "true_range_m"])
    ev = packets["event"].astype(str)
    tx = packets.loc[ev == "tx", ["uid", "time"]].rename(columns={"time": "t_tx"})
    rx = packets.loc[ev == "rx", ["uid", "node", "time"]].rename(columns={"time": "t_rx"})
    df = r[["uid", "node", "anchor"]].merge(tx, on="uid", how="left").merge(rx, on=["uid", "node"], how="left")
    # both ends in one pass over the positions (read in chunks from a streamed run's file)
    n = len(df)
    ends = positions_at(
        positions_source(tables),
        np.concatenate([df["anchor"].to_numpy(), df["node"].to_numpy()]),
        np.concatenate([df["t_tx"].to_numpy(float), df["t_rx"].to_numpy(float)]),
    )
    p_tx, p_rx = ends[:n], ends[n:]
    df["true_range_m"] = np.linalg.norm(p_rx - p_tx, axis=1)
    return df


def range_errors(tables: Mapping[str, pd.DataFrame]) -> pd.DataFrame:
    """The ``ranges`` rows with their true range and error = estimate - truth (m); computed
    once per run's tables (``memo`` of :class:`~aquasim_py.trace.TraceFiles`), whose metrics,
    derived table and report all use it."""
    memo = getattr(tables, "memo", None)
    if memo is not None:  # (a copy each: a caller may change its frame)
        return memo("beacon.range_errors", lambda: _range_errors(tables)).copy()
    return _range_errors(tables)


def _range_errors(tables: Mapping[str, pd.DataFrame]) -> pd.DataFrame:
    r = table_columns(tables, "ranges", _RANGE_COLUMNS)
    if r is None or len(r) == 0:
        return pd.DataFrame(columns=["uid", "node", "anchor", "range_m", "true_range_m", "error_m"])
    truth = true_ranges(tables, r)
    out = r[["uid", "node", "anchor", "range_m"]].reset_index(drop=True).copy()
    out["true_range_m"] = truth["true_range_m"].to_numpy()
    out["error_m"] = out["range_m"] - out["true_range_m"]
    return out
