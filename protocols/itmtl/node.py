"""ITMTL: joint time synchronization and localization by iterative tracing.

R. Gao, D. Qiao, M. Zhang, G. Xu et al., mobile target localization based on iterative
tracing for underwater wireless sensor networks. The equations of the paper were lost; the
maths follows the reconstruction in docs/itmtl.md (see :mod:`aquasim_protocols.itmtl.math` and
:mod:`aquasim_py.estimation.sync`).

Roles: buoys and anchors answer Req messages (true time, known position); ordinary nodes run
rounds. Per round an ordinary node:

1. broadcasts Req and collects the Res answers (``t2``, ``t3``, position, velocity, confidence);
2. phase 1 (first localization): TDOA rough position with reference 1 as pivot and the initial
   clock; later rounds: the IMM prediction to this round's send time;
3. phase 2: delay rates from the ray-traced gradient at the rough position (ITMTL) or the
   line of sight / mean speed (ITMTL-wsc, ``compensate = false``), relative-motion split of
   every round trip, weighted linear regression over all exchanges so far, iterated;
4. phase 3: position fix from the one-way forward delays (least squares through the eigenray
   time or, for wsc, distance / mean speed), filtered by an IMM of a constant-velocity KF and a
   coordinated-turn EKF (``imm = false``: raw fixes);
5. phase 4: the outer loop 2-3 repeats with the new fix as rough position until it moves less
   than ``outer_tol_m``; the estimate is the next round's rough position;
6. network-wide: confidence = mean reference confidence x (1 - normalized residual); after
   ``promote_min_rounds`` rounds above ``promote_threshold`` the node becomes a reference
   and answers Req with its synchronized time and estimated position.

Logged per round: ``clocks`` (skew = alpha - 1, offset = beta) and ``estimates`` (the position
extrapolated to the logging instant, confidence, is_reference), with a ``round`` column.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Mapping
from typing import Any, ClassVar, Literal

import numpy as np
import pandas as pd
from pydantic import Field

from aquasim_py.estimation.errors import EstimationError
from aquasim_py.estimation.imm import IMM
from aquasim_py.estimation.lsq import multilaterate, tdoa_ls
from aquasim_py.estimation.motion import ConstantVelocityModel, CoordinatedTurnModel
from aquasim_py.estimation.promotion import promote
from aquasim_py.estimation.sync import Exchanges, fit_clock, itmtl_sync, regression_points, split_delays
from aquasim_py.registry import register

from .math import DelayModel, fix_confidence, initial_clock, position_fix
from .paper import CLAIMS
from .paper import comparison as paper_comparison
from .reqres import ReqResNode, ReqResParams, Round

__all__ = ["ItmtlNode"]


class ItmtlParams(ReqResParams):
    """ITMTL parameters (ITMTL-wsc: ``compensate = false``; no tracking: ``imm = false``)."""

    hierarchy: bool = Field(
        True, description="with >= min_refs buoy / anchor answers, use those alone (the paper's hierarchy)"
    )
    compensate: bool = Field(True, description="stratification compensation through the ray tracer (False = ITMTL-wsc)")
    delay_source: Literal["round_trip", "model"] = Field(
        "round_trip",
        description="regression delays: the round trip split by the motion term (round_trip), or the "
        "delay model (eq 17: ray-traced, or distance / c for wsc) at the round's position (model)",
    )
    imm: bool = Field(True, description="IMM (CV KF + coordinated-turn EKF) filtering of the fixes; False = raw fixes")
    motion_split: bool = Field(True, description="relative-motion split of the round trip (False = half round trip)")
    motion_mode: Literal["relative", "separate"] = Field(
        "relative", description="Delta from the relative LOS speed (paper) or node/reference motion separately"
    )
    own_velocity: Literal["track", "sensor", "none"] = Field(
        "track", description="where the node's own velocity comes from"
    )
    min_skew_span_s: float = Field(
        20.0, ge=0, description="fit the skew only once the data span this long (s); before, offset only"
    )
    max_outer_iter: int = Field(4, ge=1, description="phase 2-3 iterations per round")
    outer_tol_m: float = Field(0.01, gt=0, description="stop when the fix moves less (m)")
    weighted: bool = Field(
        True, description="weighted least squares: fix by announced position std, regression by time-point variance"
    )
    residual_scale_m: float = Field(5.0, gt=0, description="range residual that drives confidence to 0 (m)")
    promotion: bool = Field(True, description="promote confident ordinary nodes to references")
    promote_threshold: float = Field(0.9, ge=0, le=1, description="confidence needed for promotion")
    ref_max_std_m: float = Field(
        3.0, gt=0, description="a promoted node answers only while its position std stays below this (m)"
    )
    promote_min_rounds: int = Field(3, ge=1, description="consecutive confident rounds before promotion")
    imm_q_cv: float = Field(1e-3, gt=0, description="CV acceleration noise density (m^2/s^3)")
    imm_q_ct: float = Field(1e-3, gt=0, description="CT acceleration noise density (m^2/s^3)")
    imm_q_turn: float = Field(1e-6, gt=0, description="CT turn-rate noise density (rad^2/s^3)")
    imm_switch: float = Field(0.05, gt=0, lt=1, description="IMM mode switching probability per round")
    max_coast_rounds: int = Field(2, ge=0, description="rounds without a fix after which the track is dropped from use")
    speed_prior_mps: float = Field(
        1.5, gt=0, description="velocity std per axis when the node's velocity is unknown (m/s)"
    )
    ref_time_weight: float = Field(
        1.0, ge=0, description="factor on the reference's announced time variance in the regression weights"
    )
    gate_chi2: float = Field(13.8, gt=0, description="innovation gate (chi-square, 2 dof; 13.8 = 99.9 %)")
    gate_floor_m: float = Field(20.0, ge=0, description="std added to the gate's innovation covariance (m)")
    fix_max_std_m: float = Field(20.0, gt=0, description="fixes less determined than this are not used (m)")
    max_speed_mps: float = Field(
        5.0, gt=0, description="a track faster than this is not used for the motion split (m/s)"
    )
    fix_std_floor_m: float = Field(0.5, gt=0, description="floor of the fix noise std fed to the IMM (m)")


@register
class ItmtlNode(ReqResNode):
    """ITMTL node (see module docstring)."""

    name: ClassVar[str] = "itmtl"
    Params = ItmtlParams
    paper: ClassVar[dict[str, str]] = {f"{c.quantity} ({c.figure})": f"{c.paper}; {c.statistic}" for c in CLAIMS}

    @classmethod
    def paper_comparison(cls, results: Mapping[str, Any]) -> pd.DataFrame | None:
        """The paper's numbers beside the same statistics of the variants of one network and
        seed (variant name -> run result), for the variants runner (:mod:`.paper`)."""
        return paper_comparison(results)

    def setup(self) -> None:
        super().setup()
        p = self.params
        self.model = DelayModel(self.profile(), p.compensate, p.mean_speed_mps)
        self.localized = False
        self.conf_hist: list[float] = []
        # exchanges so far, one row per answer
        # T1, t2, t3, T4, reference confidence, announced velocity std (m/s), time std (s)
        self._ex: list[tuple[float, ...]] = []
        self._ex_round: list[int] = []
        self._ref_pos: list[np.ndarray] = []
        self._ref_vel: list[np.ndarray] = []
        # per round: node position estimate at t1 and velocity estimate (None = unknown yet)
        self._round_pos: dict[int, np.ndarray] = {}
        self._round_vel: dict[int, np.ndarray | None] = {}
        self._round_vstd: dict[int, float] = {}  # node velocity std per round (m/s)
        self.imm_filter: IMM | None = None
        self.t_est: float = np.nan  # true time (estimated) of the last position estimate
        self.p_est = np.zeros(3)
        self.v_est: np.ndarray | None = None
        self._last_fix: tuple[float, np.ndarray] | None = None
        self._n_fixes = 0
        self._coast = 0
        self._pos_cov: np.ndarray | None = None

    # -- reference side -----------------------------------------------------------------------

    def answers_requests(self) -> bool:
        return self.is_reference

    def estimated_position_at(self, t: float) -> np.ndarray:
        v = self.v_est if self.v_est is not None else np.zeros(3)
        return self.p_est + v * (t - self.t_est)

    def estimated_velocity(self) -> np.ndarray:
        v = self._velocity_now()
        return v if v is not None else np.zeros(3)

    # -- ordinary side ------------------------------------------------------------------------

    def _exchanges(self, k_node: np.ndarray, k_ref: np.ndarray) -> Exchanges:
        """All exchanges so far, weighted by the inverse variance of their time points
        (weighted least squares, as the paper's abstract says): MAC stamp precision, the
        motion split's doubt ``sigma_v (t3 - t2 + S) / (2 c)`` from the node's and the
        reference's velocity uncertainty, and the reference's own time uncertainty."""
        p = self.params
        a = np.asarray(self._ex, dtype=float)
        if not p.weighted:
            return Exchanges.build(a[:, 0], a[:, 1], a[:, 2], a[:, 3], k_node, k_ref)
        S = (a[:, 3] - a[:, 0]) / self.alpha - (a[:, 2] - a[:, 1])
        span = a[:, 2] - a[:, 1] + S
        sv_node = np.array([self._round_vstd.get(r, p.speed_prior_mps) for r in self._ex_round])
        sv = np.hypot(sv_node, a[:, 5]) if p.motion_split else np.full(len(a), p.speed_prior_mps)
        var = p.stamp_std_s**2 + (sv * span / (2.0 * p.mean_speed_mps)) ** 2 + p.ref_time_weight * a[:, 6] ** 2
        return Exchanges.build(a[:, 0], a[:, 1], a[:, 2], a[:, 3], k_node, k_ref, p.stamp_std_s**2 / var)

    def _rates(self) -> tuple[np.ndarray, np.ndarray]:
        """Delay rates of every stored exchange from its round's position / velocity estimate."""
        n = len(self._ex)
        if not self.params.motion_split:
            return np.zeros(n), np.zeros(n)
        pos = np.array([self._round_pos.get(r, np.full(3, np.nan)) for r in self._ex_round])
        vel = np.array(
            [self._round_vel.get(r) if self._round_vel.get(r) is not None else np.zeros(3) for r in self._ex_round]
        )
        ok = np.all(np.isfinite(pos), axis=1)
        kn, kr = np.zeros(n), np.zeros(n)
        if ok.any():
            a, b = self.model.motion_rates(
                np.array(self._ref_pos)[ok], pos[ok], vel[ok], np.array(self._ref_vel)[ok], self.params.motion_mode
            )
            kn[ok], kr[ok] = a, b
        return kn, kr

    def _sync(self) -> None:
        ex = self._exchanges(*self._rates())
        t = np.concatenate([ex.t2, ex.t3])
        fix_skew = float(t.max() - t.min()) < self.params.min_skew_span_s
        if self.params.delay_source == "model":
            tau_f, tau_b = self._model_delays(ex)
            self.alpha, self.beta = fit_clock(
                *regression_points(ex, tau_f, tau_b), alpha_fixed=self.alpha if fix_skew else None
            )
        else:
            fit = itmtl_sync(ex, self.alpha, fix_skew=fix_skew)
            self.alpha, self.beta = fit.alpha, fit.beta
        self.synced = True

    def _model_delays(self, ex: Exchanges) -> tuple[np.ndarray, np.ndarray]:
        """Phase 2a with ``delay_source = "model"``: each exchange's forward delay from the delay
        model (eq 17; ray-traced with compensation, distance / c without) between the reference
        and the node's position estimate of that round, the backward one that plus the motion
        term of eqs 19-23 (the round trip's S taken as 2 tau_f). Exchanges of rounds without a
        position estimate keep the round-trip split."""
        tau_f, tau_b = split_delays(ex, self.alpha)
        pos = np.array([self._round_pos.get(r, np.full(3, np.nan)) for r in self._ex_round])
        ok = np.all(np.isfinite(pos), axis=1)
        if ok.any():
            tf = self.model.delay(np.array(self._ref_pos)[ok], pos[ok])
            hold = ex.t3[ok] - ex.t2[ok]
            tau_f[ok] = tf
            tau_b[ok] = tf + ex.k_node[ok] * (hold + 2.0 * tf) + ex.k_ref[ok] * hold
        return tau_f, tau_b

    def position_std(self) -> float:
        """Std of this node's position estimate (m): the IMM's (or the last fix's) covariance;
        0 for a buoy / anchor (surveyed)."""
        if self.is_anchor:
            return 0.0
        P = self._pos_cov
        return float(np.sqrt(np.trace(P) / 2.0)) if P is not None else 1e3

    def velocity_std(self) -> float:
        """Std per axis of the velocity this node uses (m/s)."""
        if self.is_anchor or self.params.own_velocity == "sensor":
            return self.params.velocity_sensor_std_mps
        if self.params.own_velocity == "track" and self.imm_filter is not None and self._n_fixes >= 2:
            return float(np.sqrt(np.trace(self.imm_filter.P[2:4, 2:4]) / 2.0))
        return self.params.speed_prior_mps

    def time_std(self, t: float) -> float:
        """Standard error (s) of this node's synchronized time at ``t``: the weighted
        regression's error of the fitted line there (weights are inverse variances)."""
        if self.is_anchor or not self._ex:
            return 0.0
        ex = self._exchanges(*self._rates())
        tt = np.concatenate([ex.t2, ex.t3])
        w = np.concatenate([ex.weight, ex.weight]) / self.params.stamp_std_s**2
        sw = w.sum()
        tm = (w * tt).sum() / sw
        sxx = (w * (tt - tm) ** 2).sum()
        return float(np.sqrt(1.0 / sw + ((t - tm) ** 2 / sxx if sxx > 0 else 0.0)))

    def _velocity_now(self) -> np.ndarray | None:
        src = self.params.own_velocity
        if src == "sensor":
            return self.own_velocity()
        if src == "none":
            return np.zeros(3)
        return self._plausible(self.v_est)

    def _plausible(self, v: np.ndarray | None) -> np.ndarray | None:
        """A track faster than ``max_speed_mps`` is lost: its velocity is not used."""
        if v is None or np.linalg.norm(v) > self.params.max_speed_mps:
            return None
        return v

    def _fix_cov(self, fix: Any) -> np.ndarray:
        p = self.params
        sigma = max(fix.rms_residual, p.fix_std_floor_m / p.mean_speed_mps)
        return fix.cov_unit * sigma**2

    def _accept(self, fix: Any) -> bool:
        """Validation gate: a fix too poorly determined (std above ``fix_max_std_m``) or
        inconsistent with the track (Mahalanobis distance^2 of the innovation above
        ``gate_chi2``) is not used; after ``max_coast_rounds`` rejections in a row the track is
        restarted from the next well-determined fix."""
        p = self.params
        R = self._fix_cov(fix)
        if not np.all(np.isfinite(R)) or np.sqrt(np.max(np.linalg.eigvalsh(R))) > p.fix_max_std_m:
            return False
        if self._coast >= p.max_coast_rounds:
            self._restart = True
            return True
        if p.imm and self.imm_filter is not None:
            prior, P = self.imm_filter.x[:2], self.imm_filter.P[:2, :2]
        elif self.v_est is not None:
            prior, P = self.p_est[:2], np.eye(2) * (p.speed_prior_mps * 10.0) ** 2
        else:
            return True
        d = fix.position[:2] - prior
        # the floor keeps a manoeuvre the motion models did not foresee from locking the track
        # out; mirror solutions (the failure this gate is for) lie hundreds of metres away
        return float(d @ np.linalg.solve(P + R + np.eye(2) * p.gate_floor_m**2, d)) <= p.gate_chi2

    def _ambiguous(self, ref_pos: np.ndarray, fix: Any, depth: float) -> bool:
        """Is the fix's mirror image across the references' horizontal principal axis an
        equally good solution (references nearly in a vertical plane)?"""
        xy = ref_pos[:, :2]
        c = xy.mean(axis=0)
        u = np.linalg.svd(xy - c)[2][0]
        d = fix.position[:2] - c
        mirror = c + 2.0 * (d @ u) * u - d
        sel = np.array(self._ex_round) == self._ex_round[-1]
        ex = self._exchanges(np.zeros(len(self._ex)), np.zeros(len(self._ex)))
        tau_f, _ = split_delays(ex, self.alpha)
        alt = position_fix(self.model, ref_pos, tau_f[sel], np.append(mirror, depth), depth=depth)
        apart = np.linalg.norm(alt.position - fix.position) > 2.0 * self.params.residual_scale_m
        return bool(
            apart
            and alt.rms_residual
            <= 2.0 * fix.rms_residual + self.params.residual_scale_m / self.params.mean_speed_mps / 5
        )

    def _imm_step(self, t1: float, fix: np.ndarray | None, R: np.ndarray | None) -> None:
        """Predict the IMM to true time t1 and (if a fix came) update it."""
        p = self.params
        if self.imm_filter is None:
            if fix is None or R is None:
                return
            x0 = np.array([fix[0], fix[1], 0.0, 0.0, 0.0])
            P0 = np.diag([R[0, 0], R[1, 1], 1.0, 1.0, 0.01**2])
            P0[:2, :2] = R
            Pi = np.array([[1 - p.imm_switch, p.imm_switch], [p.imm_switch, 1 - p.imm_switch]])
            self.imm_filter = IMM(
                [ConstantVelocityModel(2, 1.0, p.imm_q_cv), CoordinatedTurnModel(2, 1.0, p.imm_q_ct, p.imm_q_turn)],
                Pi,
                x0,
                P0,
            )
            self._imm_t = t1
            return
        f = self.imm_filter
        dt = max(t1 - self._imm_t, 1e-6)
        f.models = [dataclasses.replace(m, motion=dataclasses.replace(m.motion, dt=dt)) for m in f.models]
        f.predict()
        self._imm_t = t1
        if fix is not None and R is not None:
            H = np.zeros((2, 5))
            H[0, 0] = H[1, 1] = 1.0
            f.update(fix[:2], R, H=H)

    def process_round(self, rnd: Round) -> None:
        p = self.params
        ans = rnd.answers
        anchors = [a for a in ans if a.anchor]
        if p.hierarchy and len(anchors) >= p.min_refs:
            # the paper's hierarchy: a node that reaches enough buoys / anchors synchronizes and
            # localizes on them alone; promoted references serve the nodes that do not
            ans = anchors
        if not ans:
            return
        r = rnd.index
        for a in ans:
            self._ex.append((a.T1, a.t2, a.t3, a.T4, a.conf, a.vel_std, a.time_std))
            self._ex_round.append(r)
            self._ref_pos.append(a.pos)
            self._ref_vel.append(a.vel)
        depth = self.depth()
        ref_pos = np.array([a.pos for a in ans])
        # answers to the retry saw the node later: with a track velocity, move their reference
        # back by the node's displacement since the first Req (same relative geometry)
        late = np.array([(a.T1 - rnd.T1) / self.alpha for a in ans])
        v_now = self._velocity_now()
        if v_now is not None and np.any(late > 0):
            ref_pos = ref_pos - late[:, None] * np.array([v_now[0], v_now[1], 0.0])
        ref_conf = np.array([a.conf for a in ans])
        ref_pstd = np.array([a.pos_std for a in ans])
        can_fix = len(ans) >= p.min_refs

        # phase 1 / rough position
        if not self.localized:
            if not can_fix:
                if len(self._ex) >= 1:
                    self._sync()
                    self.log_clock(self.alpha - 1.0, self.beta, round=r, n_refs=len(ans))
                return
            t2 = np.array([a.t2 for a in ans])
            # TDOA needs the answers to one Req (the first or the retry, whichever has more)
            first = np.array([a.T1 == rnd.T1 for a in ans])
            grp = first if first.sum() >= (~first).sum() else ~first
            piv = int(np.flatnonzero(grp)[0])
            # Two hyperbola intersections (3 references), or a linearized solution thrown far
            # off by a reference outside the node's hull: keep the candidate whose ranges agree
            # best with the round trips (half of each at the mean speed; alpha ~ 1 is enough),
            # the round-trip multilateration being one candidate.
            S = np.array([(a.T4 - a.T1) - (a.t3 - a.t2) for a in ans])
            rr = 0.5 * S * p.mean_speed_mps
            cands: list[tuple[np.ndarray, float]] = []
            if grp.sum() >= p.min_refs:
                with contextlib.suppress(ValueError, np.linalg.LinAlgError, EstimationError):
                    td = tdoa_ls(ref_pos[grp], t2[grp], p.mean_speed_mps, depth=depth)
                    cands = list(td.candidates) or [(td.x, td.range_pivot)]
            with contextlib.suppress(ValueError, np.linalg.LinAlgError, EstimationError):
                q = multilaterate(ref_pos, rr, depth=depth)
                cands.append((q, float(np.linalg.norm(ref_pos[piv] - q))))
            if cands:
                mis = [np.sum((np.linalg.norm(ref_pos - c, axis=1) - rr) ** 2) for c, _ in cands]
                rough, d1 = cands[int(np.argmin(mis))]
                if not self.synced:
                    self.alpha, self.beta = initial_clock(ans[piv].T1, ans[piv].t2, d1, p.mean_speed_mps)
            else:
                rough = np.append(ref_pos[:, :2].mean(axis=0), depth)
            t1 = self.ref_time(rnd.T1)
        else:
            t1 = self.ref_time(rnd.T1)
            if p.imm and self.imm_filter is not None:
                self._imm_step(t1, None, None)
                x = self.imm_filter.x
                rough = np.array([x[0], x[1], depth])
            else:
                v = self.v_est if self.v_est is not None else np.zeros(3)
                rough = self.p_est + v * (t1 - self.t_est)
                rough[2] = depth
        self._round_pos[r] = rough
        self._round_vel[r] = self._velocity_now()
        self._round_vstd[r] = self.velocity_std() if self._round_vel[r] is not None else p.speed_prior_mps

        rough_prior = rough.copy()
        # phases 2-3, iterated
        fix = None
        for _ in range(p.max_outer_iter):
            self._sync()
            if not can_fix:
                break
            ex = self._exchanges(*self._rates())
            sel = np.array(self._ex_round) == r
            tau_f, _ = split_delays(ex, self.alpha)
            fix = position_fix(
                self.model,
                ref_pos,
                tau_f[sel],
                rough,
                depth=depth,
                weights=1.0 / (p.fix_std_floor_m**2 + ref_pstd**2) if p.weighted else None,
            )
            moved = float(np.linalg.norm(fix.position - rough))
            rough = fix.position
            self._round_pos[r] = rough
            if moved < p.outer_tol_m:
                break
        t1 = self.ref_time(rnd.T1)

        if fix is not None and not self.localized and self._ambiguous(ref_pos, fix, depth):
            # first fix with a mirror solution as good as this one: wait for better geometry
            self.log_clock(self.alpha - 1.0, self.beta, round=r, n_refs=len(ans))
            self._round_pos.pop(r, None)
            return

        if fix is not None and self.localized and not self._accept(fix):
            fix = None
            self._round_pos[r] = rough_prior
            self._sync()

        if fix is not None:
            res_m = fix.rms_residual * p.mean_speed_mps
            sigma = max(fix.rms_residual, p.fix_std_floor_m / p.mean_speed_mps)
            R = fix.cov_unit * sigma**2
            conf = fix_confidence(ref_conf, res_m, p.residual_scale_m)
        else:
            R, conf, res_m = None, self.confidence * 0.9, np.nan

        if getattr(self, "_restart", False) and fix is not None:
            self.imm_filter, self._last_fix, self.v_est, self._n_fixes = None, None, None, 0
            self._restart = False
        if p.imm:
            if fix is not None and R is not None:
                if self.imm_filter is None:
                    self._imm_step(t1, fix.position, R)
                else:
                    # the prediction to t1 was done above; only the update is left
                    H = np.zeros((2, 5))
                    H[0, 0] = H[1, 1] = 1.0
                    self.imm_filter.update(fix.position[:2], R, H=H)
            if self.imm_filter is not None:
                x = self.imm_filter.x
                self.p_est = np.array([x[0], x[1], depth])
                self.v_est = np.array([x[2], x[3], 0.0]) if self.localized else None
        else:
            if fix is not None:
                if self._last_fix is not None and t1 > self._last_fix[0]:
                    self.v_est = (fix.position - self._last_fix[1]) / (t1 - self._last_fix[0])
                    self.v_est[2] = 0.0
                self._last_fix = (t1, fix.position)
                self.p_est = fix.position
            else:
                v = self.v_est if self.v_est is not None else np.zeros(3)
                self.p_est = self.p_est + v * (t1 - self.t_est)
        self.t_est = t1
        self.localized = True
        if p.imm and self.imm_filter is not None:
            self._pos_cov = self.imm_filter.P[:2, :2].copy()
        elif R is not None:
            self._pos_cov = R
        if fix is not None:
            self._n_fixes += 1
            self._coast = 0
        else:
            self._coast += 1
        # coasting is useless before the track has a velocity (two fixes)
        lost = self._coast > p.max_coast_rounds or (self._coast > 0 and self._n_fixes < 2)
        self._round_pos[r] = self.p_est.copy()
        if lost:
            # a track coasting this long is not trusted: no motion correction from it, no
            # position estimate, and no reference duty (until fixes come back)
            self._round_vel[r] = np.zeros(3)
            self._round_vstd[r] = p.speed_prior_mps
            if not self.is_anchor:
                self.is_reference = False
        elif p.own_velocity == "track":
            # the round's velocity is the track's after this round's fix; rounds before the
            # track had two fixes get the first velocity it gave, and the clock is refitted
            v_track = self._plausible(self.v_est) if self._n_fixes >= 2 else None
            mature = v_track is not None
            self._round_vel[r] = v_track.copy() if v_track is not None else None
            self._round_vstd[r] = self.velocity_std() if mature else p.speed_prior_mps
            if v_track is not None:
                for k, vk in self._round_vel.items():
                    if vk is None:
                        self._round_vel[k] = v_track.copy()
                        self._round_vstd[k] = self.velocity_std()
                self._sync()

        # network-wide
        self.confidence = conf
        self.conf_hist.append(conf)
        if self.is_reference and not self.is_anchor and self.position_std() > p.ref_max_std_m:
            self.is_reference = False  # demoted: its position is no longer good enough to share
        if (
            p.promotion
            and not self.is_reference
            and not lost
            and self.position_std() <= p.ref_max_std_m
            and promote(self.conf_hist, p.promote_threshold, p.promote_min_rounds)
        ):
            self.is_reference = True

        now = self.ref_time(self.local_time())
        pos_now = self.estimated_position_at(now)
        self.log_clock(self.alpha - 1.0, self.beta, round=r, n_refs=len(ans))
        if not lost:
            self.log_estimate(
                pos_now[0],
                pos_now[1],
                depth,
                confidence=conf,
                is_reference=self.is_reference,
                round=r,
                n_refs=len(ans),
                residual_m=res_m,
                fixed=fix is not None,
                promoted_refs=int(sum(a.conf < 1.0 for a in ans)),
            )
