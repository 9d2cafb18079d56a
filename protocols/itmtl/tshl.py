"""TSHL baseline: A. A. Syed and J. Heidemann, "Time synchronization for high latency acoustic
networks", IEEE INFOCOM 2006.

Phase 1, skew: each reference (buoy / anchor) sends a burst of ``burst_beacons`` one-way
beacons ``burst_interval_s`` apart, once, starting at a random time in the first
``first_round_s``; a node regresses the beacons' receive stamps on their send stamps (the
frame's MAC transmit stamp, reference time) for its skew, assuming each sender's delay
constant over the burst (:func:`aquasim_py.estimation.sync.tshl_skew`, pooled over the
references heard, one intercept each). Phase 2, offset: with the skew corrected, the latest
round's two-way Req/Res exchanges give the offset with symmetric delays
(:func:`~aquasim_py.estimation.sync.tshl_offset`). Localization as in
:mod:`aquasim_protocols.itmtl.baseline`.

Open choices (TSHL's paper gives the design, not these numbers for this network): the burst
size and spacing, and one burst per reference for the whole run (TSHL assumes the skew stays
put). ``beacons = "res"`` is the former reading: no burst, the references' Res frames of every
round serve as the beacons (send stamp ``t3``, receive stamp ``T4``), which spreads phase 1
over the whole run.
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import Field

from aquasim_py.estimation.sync import ClockFit, tshl_offset, tshl_skew
from aquasim_py.registry import register

from .baseline import BaselineNode
from .reqres import ReqResParams

BEACON = "tshl_beacon"


class TshlParams(ReqResParams):
    """TSHL parameters (see the module docstring for the open choices)."""

    beacons: Literal["burst", "res"] = Field(
        "burst",
        description="phase 1's one-way beacons: a burst per reference, as published (burst), or the Res "
        "frames of every round (res: the former reading)",
    )
    burst_beacons: int = Field(10, ge=2, description="beacons in a reference's burst")
    burst_interval_s: float = Field(1.0, gt=0, description="time between two beacons of a burst (s)")
    beacon_bits: int = Field(96, ge=1, description="beacon frame size (bits)")


@register
class TshlNode(BaselineNode):
    name: ClassVar[str] = "tshl"
    paper: ClassVar[dict[str, str]] = {"sync error": "time error above ITMTL's, ITMTL-wsc's and Mobi-Sync's (Fig. 9)"}
    Params = TshlParams

    def setup(self) -> None:
        super().setup()
        self.beacon_rows: list[tuple[int, float, float]] = []  # (reference, send stamp, local receive stamp)

    def run(self) -> Generator[Any, Any, None]:
        if self.params.beacons == "burst":
            if self.is_reference:
                self.env.process(self.burst())
            else:
                self.env.process(self.listen())
        yield from super().run()

    def burst(self) -> Generator[Any, Any, None]:
        """Phase 1 at a reference: ``burst_beacons`` beacons, ``burst_interval_s`` apart; each
        beacon's send stamp is its own MAC transmit stamp (true time at a buoy / anchor)."""
        p = self.params
        start = float(self.rng.uniform(0.0, p.first_round_s)) if p.first_round_s > 0 else 0.0
        yield self.sleep(start)
        for k in range(p.burst_beacons):
            yield self.broadcast(BEACON, {"k": k}, p.beacon_bits)
            yield self.sleep(p.burst_interval_s)

    def listen(self) -> Generator[Any, Any, None]:
        """Phase 1 at an ordinary node: keep every beacon's (sender, send stamp, receive stamp)."""
        while True:
            rec = yield self.recv(kinds=BEACON)
            self.beacon_rows.append((rec.packet.src, float(rec.packet.tx_local), float(rec.rx_local)))

    def fit(self) -> ClockFit:
        a = np.asarray(self.rows, float)
        if self.params.beacons == "res":
            alpha = tshl_skew(a[:, 2], a[:, 3], np.asarray(self.ref_ids))
        elif len(self.beacon_rows) >= 2:
            b = np.asarray(self.beacon_rows, float)
            alpha = tshl_skew(b[:, 1], b[:, 2], b[:, 0].astype(int))
        else:
            alpha = 1.0  # no burst heard yet: the offset alone
        last = np.asarray(self.rounds) == self.rounds[-1]
        r = a[last]
        return ClockFit(alpha, tshl_offset(alpha, r[:, 0], r[:, 1], r[:, 2], r[:, 3]))
