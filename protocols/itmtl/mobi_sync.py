"""Mobi-Sync baseline: J. Liu, Z. Zhou, J.-H. Cui et al., "Mobi-Sync: efficient time
synchronization for mobile underwater sensor networks" (INFOCOM 2010 as cited by ITMTL).

The node's own velocity is the mean of its neighbours' reported velocities (spatial
correlation of the current, :func:`aquasim_py.estimation.sync.neighbour_velocity`); the delay
change over each exchange follows from the relative velocity along the straight line of
sight at the mean speed, which splits the round trip; then linear regression over all
exchanges. No ray model, no tracking. Localization as in :mod:`aquasim_py.protocols.itmtl.baseline`.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from aquasim_py.estimation.sync import ClockFit, Exchanges, itmtl_sync, neighbour_velocity
from aquasim_py.registry import register

from .baseline import BaselineNode


@register
class MobiSyncNode(BaselineNode):
    name: ClassVar[str] = "mobi_sync"

    def setup(self) -> None:
        super().setup()
        self.round_pos: dict[int, np.ndarray] = {}
        self.round_vel: dict[int, np.ndarray] = {}

    def k_rates(self) -> tuple[np.ndarray, np.ndarray]:
        n = len(self.rows)
        kn = np.zeros(n)
        r = self.rounds[-1]
        if self.p_est is not None:
            self.round_pos.setdefault(r, self.p_est.copy())
        sel = np.asarray(self.rounds) == r
        self.round_vel.setdefault(r, neighbour_velocity(np.asarray(self.ref_vel)[sel]))
        rounds = np.asarray(self.rounds)
        ok = np.array([rr in self.round_pos for rr in self.rounds])
        if ok.any():
            pos = np.array([self.round_pos[rr] for rr in rounds[ok]])
            vel = np.array([self.round_vel.get(rr, np.zeros(3)) for rr in rounds[ok]])
            kn[ok], _ = self.model.motion_rates(np.asarray(self.ref_pos)[ok], pos, vel, np.asarray(self.ref_vel)[ok])
        return kn, np.zeros(n)

    def fit(self) -> ClockFit:
        a = np.asarray(self.rows, float)
        kn, kr = self.k_rates()
        return itmtl_sync(Exchanges.build(a[:, 0], a[:, 1], a[:, 2], a[:, 3], kn, kr), self.alpha)
