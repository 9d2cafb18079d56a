"""Two-way ranging in one file: the protocol of the tutorial "A protocol in one file".

Each sensor polls the anchors in turn. An anchor answers a poll a fixed turnaround after the
poll's first bit arrived, on its own clock; the sensor times the whole exchange on its own
clock, so neither clock's offset enters the range:

    range = sound_speed * (rx_local - tx_local - turnaround) / 2          [m]

(tx_local: the poll's transmit stamp, rx_local: the reply's arrival stamp, both the sensor's).
"""

import itertools
from collections.abc import Mapping

import numpy as np
import pandas as pd
from pydantic import BaseModel, Field

from aquasim_py.metrics import positions_at
from aquasim_py.node import Node, Role


class TWRParams(BaseModel):
    """Every parameter with a type, a default and its unit (checked when the scenario loads)."""

    anchors: list[int] = Field(description="ids of the anchors to poll, in turn")
    period_s: float = Field(20.0, gt=0, description="time between polls (local s)")
    slot_s: float = Field(3.0, gt=0, description="node i polls i slots into a period (s)")
    turnaround_s: float = Field(0.5, gt=0, description="an anchor's reply delay (local s)")
    sound_speed_mps: float = Field(1500.0, gt=0, description="speed the ranges assume (m/s)")


class TWRNode(Node):
    name = "twr"
    Params = TWRParams
    trace_tables = ("twr", "positions")  # the tables metrics() reads

    def run(self):
        if self.role is Role.ANCHOR:
            yield from self.answer_polls()
        else:
            yield from self.poll_anchors()

    def answer_polls(self):
        """Anchor: reply to each poll turnaround_s after its first bit arrived."""
        while True:
            rx = yield self.recv(kinds="poll")
            wait = self.params.turnaround_s - (self.local_time() - rx.rx_local)
            yield self.sleep(max(wait, 0.0))
            yield self.send(rx.packet.src, "reply")

    def poll_anchors(self):
        """Sensor: poll one anchor per period; a reply gives one range."""
        p = self.params
        # one exchange at a time on the channel: node i starts i slots into the period
        yield self.sleep((self.id * p.slot_s) % p.period_s)
        for anchor in itertools.cycle(p.anchors):
            started = self.local_time()
            tx_local = yield self.send(anchor, "poll")
            rx = yield self.recv(timeout=p.period_s / 2, kinds="reply")
            if rx is not None and rx.packet.src == anchor:
                round_trip = rx.rx_local - tx_local
                range_m = p.sound_speed_mps * (round_trip - p.turnaround_s) / 2
                self.log("twr", anchor=anchor, round_trip_s=round_trip, range_m=range_m)
            yield self.sleep(max(0.0, p.period_s - (self.local_time() - started)))

    @classmethod
    def metrics(cls, tables: Mapping[str, pd.DataFrame]) -> dict[str, float]:
        """Range error statistics (m)."""
        error = range_errors(tables)["error_m"].to_numpy()
        if error.size == 0:
            return {"ranges": 0}
        return {
            "ranges": error.size,
            "range_error_mean_m": float(error.mean()),
            "range_rmse_m": float(np.sqrt(np.mean(error**2))),
        }


def range_errors(tables: Mapping[str, pd.DataFrame]) -> pd.DataFrame:
    """The ``twr`` table with the true distance (``true_m``) when the reply arrived and the
    range error (``error_m``), m: exact for moored nodes; a moving sensor would add its radial
    speed times about half the exchange."""
    twr = tables["twr"]
    sensor = positions_at(tables["positions"], twr["node"], twr["time"])
    anchor = positions_at(tables["positions"], twr["anchor"], twr["time"])
    true = np.linalg.norm(sensor - anchor, axis=1)
    return twr.assign(true_m=true, error_m=twr["range_m"].to_numpy() - true)
