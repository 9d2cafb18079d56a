"""Common body of the sync baselines (TSHL, MU-Sync, Mobi-Sync) on the Req/Res exchange.

Each baseline keeps every exchange, fits its clock its own way (:meth:`BaselineNode.fit`),
then localizes like ITMTL-wsc without tracking: one-way delays to >= ``min_refs`` references
turned into ranges at the mean speed, multilateration refined by least squares. Position
estimates are the raw fixes (the node's position at its Req, logged when the round closes).
"""

from __future__ import annotations

import contextlib
from typing import ClassVar

import numpy as np

from aquasim_py.channel.ssp import Constant
from aquasim_py.estimation.errors import EstimationError
from aquasim_py.estimation.lsq import multilaterate
from aquasim_py.estimation.sync import ClockFit, Exchanges, split_delays

from .math import DelayModel, position_fix
from .reqres import ReqResNode, Round


class BaselineNode(ReqResNode):
    name: ClassVar[str] = "_baseline"

    def setup(self) -> None:
        super().setup()
        self.model = DelayModel(Constant(self.params.mean_speed_mps), False, self.params.mean_speed_mps)
        self.rows: list[tuple[float, float, float, float]] = []
        self.ref_ids: list[int] = []
        self.rounds: list[int] = []
        self.ref_pos: list[np.ndarray] = []
        self.ref_vel: list[np.ndarray] = []
        self.p_est: np.ndarray | None = None

    def k_rates(self) -> tuple[np.ndarray, np.ndarray]:
        n = len(self.rows)
        return np.zeros(n), np.zeros(n)

    def fit(self) -> ClockFit:
        raise NotImplementedError

    def process_round(self, rnd: Round) -> None:
        ans = rnd.answers
        if not ans:
            return
        for a in ans:
            self.rows.append((a.T1, a.t2, a.t3, a.T4))
            self.ref_ids.append(a.ref)
            self.rounds.append(rnd.index)
            self.ref_pos.append(a.pos)
            self.ref_vel.append(a.vel)
        depth = self.depth()
        ref_pos = np.array([a.pos for a in ans])
        if len(ans) >= self.params.min_refs:
            S = np.array([(a.T4 - a.T1) / self.alpha - (a.t3 - a.t2) for a in ans])
            with contextlib.suppress(EstimationError):  # degenerate geometry: keep the last fix
                self.p_est = multilaterate(ref_pos, 0.5 * S * self.params.mean_speed_mps, depth=depth)
        fit = self.fit()
        self.alpha, self.beta = fit.alpha, fit.beta
        self.synced = True
        self.log_clock(fit.alpha - 1.0, fit.beta, round=rnd.index, n_refs=len(ans))
        if len(ans) < self.params.min_refs or self.p_est is None:
            return
        rows = np.asarray(self.rows, float)
        kn, kr = self.k_rates()
        ex = Exchanges.build(rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3], kn, kr)
        tau_f, _ = split_delays(ex, fit.alpha)
        sel = np.array(self.rounds) == rnd.index
        fx = position_fix(self.model, ref_pos, tau_f[sel], self.p_est, depth=depth)
        self.p_est = fx.position
        self.log_estimate(
            *fx.position,
            confidence=np.nan,
            is_reference=False,
            round=rnd.index,
            n_refs=len(ans),
            residual_m=fx.rms_residual * self.params.mean_speed_mps,
        )
