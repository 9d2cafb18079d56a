"""Network metrics (``net.*``) from the ``packets`` trace: load, throughput, delivery, delay,
collisions. One definition each (docs/metrics.md, "Network"):

- A *frame* is a data packet a protocol offered (every packet but the MAC control frames,
  :data:`~aquasim_py.net.mac.CONTROL_KINDS`), one uid. Its *offer time* is its ``offer`` row,
  or, under ``direct`` (which writes none), its first ``tx`` row. The frames counted are those
  offered in the window [``start_s``, ``end_s``) (the warm-up to the run's end).
- Its *addressees*: ``dst`` for a unicast, every node that got a row of it for a broadcast.
  A *delivery* is a frame's first ``rx`` row at an addressee.
- Loads and throughput are airtime per window time, i.e. frames per frame duration T when
  every frame has the same length:
  ``offered_load`` G = sum of the offered frames' airtime / window;
  ``channel_load`` = sum of the airtime of their transmissions (retransmissions included);
  ``throughput`` S = sum of the airtime of their deliveries / window.
- ``delivery_ratio`` = unicast frames delivered / unicast frames offered.
- ``delay_s`` = mean over deliveries of (last bit at the addressee - offer time), s; it
  includes the MAC's queueing, backoff and retransmissions (not ``direct``'s modem queue).
- ``collisions_per_packet`` = ``collision`` drops of the frames at their addressees / their
  transmissions.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .mac.base import CONTROL_KINDS

__all__ = ["PACKET_COLUMNS", "NetWindow", "net_metrics"]

#: the columns of ``packets`` the metrics read
PACKET_COLUMNS = ("time", "event", "reason", "node", "dst", "uid", "kind", "bits")


@dataclass(frozen=True)
class NetWindow:
    """What the network metrics need beyond the trace: the window [start_s, end_s) in true s
    (the warm-up and the run's duration) and the modem's airtime (s) of a packet of ``bits``."""

    start_s: float
    end_s: float
    airtime: Callable[[Any], Any]


def net_metrics(tables: Mapping[str, Any], window: NetWindow) -> dict[str, float]:
    """The ``net.*`` metrics (without the prefix) of a run's tables (module docstring)."""
    from aquasim_py.trace import table_columns

    packets = table_columns(tables, "packets", PACKET_COLUMNS)
    span = window.end_s - window.start_s
    nan = float("nan")
    out: dict[str, float] = {
        "frames": 0,
        "delivered": 0,
        "offered_load": nan,
        "channel_load": nan,
        "throughput": nan,
        "delivery_ratio": nan,
        "delay_s": nan,
        "collisions_per_packet": nan,
    }
    if packets is None or not len(packets) or not span > 0.0:
        return out
    df = packets[~packets["kind"].astype(str).isin(CONTROL_KINDS)]
    event = df["event"].astype(str)
    # each frame's offer time: its offer row, or its first transmission (direct)
    first = df[event.isin(("offer", "tx"))].sort_values("time", kind="stable").drop_duplicates("uid")
    frames = first[(first["time"] >= window.start_s) & (first["time"] < window.end_s)]
    frames = frames.set_index("uid")[["time", "dst", "bits"]]
    if not len(frames):
        return out
    mine = df["uid"].isin(frames.index)
    at_addressee = (df["dst"] == -1) | (df["dst"] == df["node"])
    airtime = window.airtime
    tx = df[mine & (event == "tx")]
    rx = df[mine & (event == "rx") & at_addressee].drop_duplicates(["uid", "node"])
    collisions = int((mine & (event == "drop") & (df["reason"] == "collision") & at_addressee).sum())
    unicast = frames["dst"] >= 0
    delivered_unicast = rx.loc[rx["dst"] >= 0, "uid"].nunique()
    rx_air = airtime(rx["bits"].to_numpy(float))
    delay = rx["time"].to_numpy(float) + rx_air - frames.loc[rx["uid"], "time"].to_numpy(float)
    out.update(
        frames=len(frames),
        delivered=len(rx),
        offered_load=float(np.sum(airtime(frames["bits"].to_numpy(float)))) / span,
        channel_load=float(np.sum(airtime(tx["bits"].to_numpy(float)))) / span,
        throughput=float(np.sum(rx_air)) / span,
        delivery_ratio=delivered_unicast / int(unicast.sum()) if unicast.any() else nan,
        delay_s=float(delay.mean()) if delay.size else nan,
        collisions_per_packet=collisions / len(tx) if len(tx) else nan,
    )
    return out
