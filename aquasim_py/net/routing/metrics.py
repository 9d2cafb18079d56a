"""End-to-end network metrics of a routed run, from its ``routes`` trace (one definition each;
docs/metrics.md, "Routing").

A *packet* here is a datagram (origin, sequence number), counted when its ``originate`` row
falls in the window [``start_s``, ``end_s``) (the warm-up to the run's end; a packet
originated near the end may not have had the time to arrive: stop the sources earlier).

- ``packets_originated``, ``packets_delivered``: the packets, and those a sink delivered;
- ``pdr`` = packets delivered / packets originated (the packet delivery ratio);
- ``delay_s`` = mean over delivered packets of (delivery at the first sink - origination), s
  (the end-to-end delay: holding times, MAC queues and backoff, airtime and propagation);
- ``hops_mean`` = mean hops of the delivered packets (transmissions on the path to the sink);
- ``copies_per_delivered`` = transmissions of the packets (the source's and every forward)
  / packets delivered (the redundancy: 1 copy per hop on a single path);
- ``sink_copies_per_delivered`` = copies the sinks received (the first and the duplicates)
  / packets delivered.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

__all__ = ["ROUTE_METRIC_COLUMNS", "route_metrics"]

#: the columns of ``routes`` the metrics read
ROUTE_METRIC_COLUMNS = ("time", "event", "origin", "seq", "hops")


def route_metrics(tables: Mapping[str, Any], start_s: float, end_s: float) -> dict[str, float]:
    """The routing metrics (without a prefix) of a run's tables; empty without a ``routes``
    table (module docstring)."""
    from aquasim_py.trace import table_columns

    routes = table_columns(tables, "routes", ROUTE_METRIC_COLUMNS)
    if routes is None or not len(routes):
        return {}
    event = routes["event"].astype(str).to_numpy()
    key = routes["origin"].to_numpy(np.int64) * (1 << 32) + routes["seq"].to_numpy(np.int64)
    time = routes["time"].to_numpy(float)
    orig = event == "originate"
    window = orig & (time >= start_s) & (time < end_s)
    born = dict(zip(key[window].tolist(), time[window].tolist()))
    counted = np.isin(key, np.fromiter(born, np.int64, len(born)))
    deliver = counted & (event == "deliver")
    n = len(born)
    got = int(deliver.sum())
    nan = math.nan
    delay = time[deliver] - np.array([born[k] for k in key[deliver].tolist()], dtype=float)
    return {
        "packets_originated": n,
        "packets_delivered": got,
        "pdr": got / n if n else nan,
        "delay_s": float(delay.mean()) if got else nan,
        "hops_mean": float(routes["hops"].to_numpy(float)[deliver].mean()) if got else nan,
        "copies_per_delivered": int((counted & (event == "forward")).sum()) / got if got else nan,
        "sink_copies_per_delivered": int((counted & ((event == "deliver") | (event == "sink_copy"))).sum()) / got
        if got
        else nan,
    }
