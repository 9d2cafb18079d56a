"""Mobi-Sync baseline: J. Liu, Z. Zhou, Z. Peng, J.-H. Cui, M. Zuba, L. Fiondella,
"Mobi-Sync: efficient time synchronization for mobile underwater sensor networks",
IEEE Trans. Parallel Distrib. Syst. 24(2), 2013 (first: IEEE Globecom 2010).

As published (abstract and method description): the references ("super nodes") are mobile
and announce their velocity with their timestamps; an ordinary node cannot measure its own
velocity, so it estimates it from its neighbours' velocities through the *spatial
correlation* of the mobility (nodes close together drift alike, and less so the farther
apart); with both velocities the dynamic propagation delay of every message is predicted;
then linear regression of the local stamps on the reference times gives skew and offset.

How each step is built here (open choices marked):

- velocity: ``v_hat = sum_j w_j v_j / sum_j w_j`` over the references that answered the round,
  ``w_j = exp(-d_j / corr_length_m)``, ``d_j`` the range from half the round trip (open
  choice: the correlation function and its length; an exponential in distance is the usual
  model of a spatially correlated current, and 1 km is a fraction of the scenario's
  current length scale of 4.5 km);
- delay change: the node moves with ``v_hat`` during the whole exchange, the reference with
  its announced velocity between its stamps (``motion_mode = "separate"`` of
  :meth:`~aquasim_protocols.itmtl.math.DelayModel.motion_rates`, straight rays at the mean
  speed), which splits each round trip into forward and backward delays (open choice: the
  paper predicts the delays from the trajectories; this is its first-order form);
- regression: iterated least squares over all exchanges so far
  (:func:`aquasim_py.estimation.sync.itmtl_sync`, unweighted);
- what Mobi-Sync adds over MU-Sync is exactly the velocity term: with static references
  (``v_j = 0``) the estimate is zero and Mobi-Sync reduces to one regression on half round
  trips, i.e. MU-Sync.

Localization as in :mod:`aquasim_protocols.itmtl.baseline`.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from pydantic import Field

from aquasim_py.estimation.sync import ClockFit, Exchanges, itmtl_sync, neighbour_velocity
from aquasim_py.registry import register

from .baseline import BaselineNode
from .reqres import ReqResParams, Round


class MobiSyncParams(ReqResParams):
    """Mobi-Sync parameters (see the module docstring for the open choices)."""

    corr_length_m: float = Field(
        1000.0, gt=0, description="length of the spatial correlation of velocities, w = exp(-d / L) (m)"
    )


def correlation_weights(ranges_m: np.ndarray, corr_length_m: float) -> np.ndarray:
    """Spatial-correlation weights of neighbours at ``ranges_m`` (m): ``exp(-d / L)``."""
    return np.exp(-np.asarray(ranges_m, dtype=float) / corr_length_m)


@register
class MobiSyncNode(BaselineNode):
    name: ClassVar[str] = "mobi_sync"
    paper: ClassVar[dict[str, str]] = {"sync error": "time error above ITMTL's (Fig. 9)"}
    Params = MobiSyncParams

    def setup(self) -> None:
        super().setup()
        self.round_pos: dict[int, np.ndarray] = {}
        self.round_vel: dict[int, np.ndarray] = {}

    def process_round(self, rnd: Round) -> None:
        ans = rnd.answers
        if ans:
            # the round's own-velocity estimate, from the answering neighbours (spatial correlation)
            S = np.array([(a.T4 - a.T1) / self.alpha - (a.t3 - a.t2) for a in ans])
            w = correlation_weights(0.5 * S * self.params.mean_speed_mps, self.params.corr_length_m)
            self.round_vel[rnd.index] = neighbour_velocity(np.array([a.vel for a in ans]), w)
        super().process_round(rnd)

    def k_rates(self) -> tuple[np.ndarray, np.ndarray]:
        n = len(self.rows)
        kn, kr = np.zeros(n), np.zeros(n)
        if self.p_est is not None:
            self.round_pos.setdefault(self.rounds[-1], self.p_est.copy())
        ok = np.array([rr in self.round_pos for rr in self.rounds])
        if ok.any():
            rounds = np.asarray(self.rounds)[ok]
            pos = np.array([self.round_pos[rr] for rr in rounds])
            vel = np.array([self.round_vel.get(rr, np.zeros(3)) for rr in rounds])
            kn[ok], kr[ok] = self.model.motion_rates(
                np.asarray(self.ref_pos)[ok], pos, vel, np.asarray(self.ref_vel)[ok], "separate"
            )
        return kn, kr

    def fit(self) -> ClockFit:
        a = np.asarray(self.rows, float)
        kn, kr = self.k_rates()
        return itmtl_sync(Exchanges.build(a[:, 0], a[:, 1], a[:, 2], a[:, 3], kn, kr), self.alpha)
