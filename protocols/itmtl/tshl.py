"""TSHL baseline: A. A. Syed and J. Heidemann, "Time synchronization for high latency acoustic
networks", IEEE INFOCOM 2006.

Phase 1: one-way beacons; the node regresses receive stamps on send stamps for the skew,
assuming each sender's delay constant (:func:`aquasim_py.estimation.sync.tshl_skew`, pooled
over references with one intercept each). The references' Res frames serve as the beacons
(send stamp ``t3`` in the frame, receive stamp ``T4``). Phase 2: the latest round's two-way
exchanges give the offset with symmetric delays (:func:`~aquasim_py.estimation.sync.tshl_offset`).
Localization as in :mod:`aquasim_protocols.itmtl.baseline`.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from aquasim_py.estimation.sync import ClockFit, tshl_offset, tshl_skew
from aquasim_py.registry import register

from .baseline import BaselineNode


@register
class TshlNode(BaselineNode):
    name: ClassVar[str] = "tshl"
    paper: ClassVar[dict[str, str]] = {"sync error": "time error above ITMTL's, ITMTL-wsc's and Mobi-Sync's (Fig. 9)"}

    def fit(self) -> ClockFit:
        a = np.asarray(self.rows, float)
        alpha = tshl_skew(a[:, 2], a[:, 3], np.asarray(self.ref_ids))
        last = np.asarray(self.rounds) == self.rounds[-1]
        b = a[last]
        return ClockFit(alpha, tshl_offset(alpha, b[:, 0], b[:, 1], b[:, 2], b[:, 3]))
