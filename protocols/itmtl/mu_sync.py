"""MU-Sync baseline: N. Chirdchoo, W.-S. Soh, K. C. Chua, "MU-Sync: a time synchronization
protocol for underwater mobile networks", ACM WUWNet 2008.

Two-way exchanges with the references; one-way delay = half the round trip; a first linear
regression for the skew, the delays recomputed with it, a second regression
(:func:`aquasim_py.estimation.sync.mu_sync`). Localization as in :mod:`aquasim_protocols.itmtl.baseline`.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from aquasim_py.estimation.sync import ClockFit, Exchanges, mu_sync
from aquasim_py.registry import register

from .baseline import BaselineNode


@register
class MuSyncNode(BaselineNode):
    name: ClassVar[str] = "mu_sync"

    def fit(self) -> ClockFit:
        a = np.asarray(self.rows, float)
        return mu_sync(Exchanges.build(a[:, 0], a[:, 1], a[:, 2], a[:, 3]))
