"""STVF: spatial-temporal variational filtering localization (Hu et al., Sensors 18:2078, 2018).

Every localization period (1 s):

- beacon nodes (role ``anchor``) and unknown nodes promoted to references broadcast a beacon
  signal carrying their position, depth, confidence eta and horizontal velocity; the packet's
  MAC transmit stamp is the send timestamp;
- an unknown node (role ``ordinary``) listens for ``listen_s``, turns each reception into a
  one-way delay z = rx - tx (ms; the paper assumes synchronized clocks, so the scenario gives
  perfect clocks), adds the ranging error of the paper's measurement model (std
  ``noise_ratio`` x delay, drawn from the node's own stream), projects the neighbour onto its
  own depth plane with its depth gauge, ranks the measurements by gamma (eqs 27-29), keeps the
  best ``n_ref`` (none if fewer are heard), runs the variational prediction and update of
  Algorithm 1 (:mod:`aquasim_py.estimation.variational`), computes its confidence (eqs 24-26)
  and becomes a reference when eta >= ``delta``.

Nothing here reads ground truth: positions come from the beacons' own position fix, depths
from depth gauges, delays from MAC stamps.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import partial
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from aquasim_py.estimation import variational as vf
from aquasim_py.estimation.promotion import promote
from aquasim_py.node import Role
from aquasim_py.registry import register

from ..common.periodic import PeriodicBeaconNode
from ..common.track import EpochTrack
from .genie import crb_metrics
from .metrics import localization_metrics

__all__ = ["StvfNode"]

KIND = "stvf_beacon"
#: the beacon payload, a flat tuple of floats: position x, y (m), depth (m), confidence eta,
#: horizontal velocity vx, vy (m/s)
BEACON_FIELDS = ("x", "y", "depth", "eta", "vx", "vy")
#: own-velocity window (s) of :class:`~aquasim_protocols.common.track.EpochTrack` (docs/stvf.md,
#: "Beacon timing": chosen on held-out seeds)
VELOCITY_WINDOW_S = 60.0
_BATCH = "stvf_update_batch"  # key of the run's _UpdateBatch in Node.out_of_band


@dataclass(frozen=True)
class _Job:
    """One node's prediction and update, handed in: its inputs (q(mu_{t-1}) and the transition
    precision Lambda / gaps for eq 11) and what to call with the result."""

    node: StvfNode
    z: np.ndarray
    refs: np.ndarray
    mu: np.ndarray
    mu_precision: np.ndarray
    transition: np.ndarray
    done: Callable[[vf.VariationalResult], None]


class _UpdateBatch:
    """Algorithm 1's updates handed in at one instant, run together after the instant's other
    events (``NodeEnv.at_instant_end``) by ``variational_update_batch``: with a common period
    every unknown node localizes at the same instant, and one numpy call for all of them costs
    about what one node's costs alone (docs/performance.md). Each node's result has the bits of
    its update alone, drawn from its own stream; no node sees another's data. The nodes then
    finish in the order they handed in, so rows are logged as with one update per node."""

    def __init__(self) -> None:
        self.jobs: list[_Job] = []

    def add(self, job: _Job) -> None:
        if not self.jobs:
            job.node.env.at_instant_end(self._run)
        self.jobs.append(job)

    def _run(self, _event: object) -> None:
        jobs, self.jobs = self.jobs, []
        groups: dict[tuple[int, int], list[_Job]] = {}  # one batch per parameter set and Nr
        for job in jobs:
            groups.setdefault((id(job.node.params), job.z.size), []).append(job)
        outs: dict[int, vf.VariationalResult] = {}
        for part in groups.values():
            # eq 11 for the whole part: predict's inverses loop over the stack, each matrix
            # inverted as on its own (same bits as one node's predict)
            mu_p, lp = vf.predict(
                np.stack([j.mu for j in part]),
                np.stack([j.mu_precision for j in part]),
                np.stack([j.transition for j in part]),
            )
            res = vf.variational_update_batch(
                np.stack([j.z for j in part]),
                np.stack([j.refs for j in part]),
                mu_p,
                lp,
                part[0].node.prior,
                [j.node.rng for j in part],
            )
            outs.update((id(j), r) for j, r in zip(part, res))
        for job in jobs:
            job.done(outs[id(job)])


class StvfParams(BaseModel):
    """STVF parameters (Table 1 defaults; z in ms, see docs/stvf.md)."""

    model_config = ConfigDict(extra="forbid")

    period_s: float = Field(1.0, gt=0, description="localization period (s)")
    listen_s: float = Field(0.9, gt=0, description="time after the period start to collect beacons (s)")
    n_ref: int = Field(3, ge=1, description="Nr: measurements used (and needed) per localization")
    n_samples: int = Field(100, ge=2, description="Ns = Nv: importance samples (Table 1)")
    delta: float = Field(0.9, ge=0, le=1, description="confidence threshold for promotion")
    c1: float = Field(0.7, ge=0, description="gamma weight of the reference confidence")
    c2: float = Field(0.2, ge=0, description="gamma weight of the normalized delay")
    c3: float = Field(0.1, ge=0, description="gamma weight of the normalized reference speed")
    penalize_far_fast: bool = Field(
        False,
        description="eq 27: gamma = C1 eta + C2 f_z + C3 f_v as printed (false), or with (1 - f_z), (1 - f_v) "
        "as the text motivating it reads (true: far and fast references ranked down)",
    )
    absolute_error: bool = Field(
        False, description="eq 26: E sums the signed errors as printed (false), or |error| per reference (true)"
    )
    transition_precision: float = Field(1 / 900, gt=0, description="Lambda = this * I (1/m^2)")
    wishart_scale: float = Field(5.0, gt=0, description="W = this * I")
    wishart_dof: float = Field(10.0, gt=0, description="n")
    speed_mps: float = Field(1500.0, gt=0, description="v: prior mean sound speed (m/s)")
    speed_precision: float = Field(0.01, gt=0, description="V: prior precision of the sound speed (1/(m/s)^2)")
    noise_shape: float = Field(3.0, gt=0, description="alpha")
    noise_rate_ms2: float = Field(200.0, gt=0, description="beta (ms^2): Gam(alpha, beta) on the precision (1/ms^2)")
    tol_m: float = Field(0.1, gt=0, description="stop when mu* moves less than this (m)")
    max_iter: int = Field(50, ge=1)
    common_random_numbers: bool = Field(
        False,
        description="reuse one set of importance samples for every pass of a localization (Algorithm 1 draws new ones)",
    )
    noise_ratio: float = Field(0.02, ge=0, description="ranging error std / delay (measurement model)")
    range_m: float = Field(
        80.0, gt=0, description="modem range (m): a first fix must lie within it (up to 3 std) of every reference"
    )
    first_fix_refs: int = Field(
        3, ge=1, description="references needed to start the filter (prior from multilateration)"
    )
    initial_std_m: float = Field(
        10.0, gt=0, description="std of q(mu_0) around a first fix, and the most a fix may have in any direction (m)"
    )
    keep_prior_across_gaps: bool = Field(
        False, description="after a missed period keep q(mu) (inflated by Lambda per period) instead of restarting"
    )
    bits: int = Field(160, ge=1, description="beacon packet size (bits)")
    send_window_s: float = Field(
        0.5, ge=0, description="references send at a uniform random offset in [0, this) of each period (s)"
    )
    estimate_epoch: Literal["measurement", "listen_end"] = Field(
        "measurement",
        description="an estimate is the position at the mean receive stamp of its measurements "
        "(measurement) or at the end of the listening window (listen_end: the former stamp)",
    )
    velocity_window_s: float = Field(
        VELOCITY_WINDOW_S,
        ge=0,
        description="own velocity: least-squares slope of the estimates of this many seconds "
        "(0: the last two, a one-period difference); carries an estimate to its beacon and log instants",
    )


@register
class StvfNode(PeriodicBeaconNode):
    """An STVF node: beacons (role anchor) broadcast; unknown nodes (ordinary) localize."""

    name = "stvf"
    trace_tables = ("estimates", "nodes", "positions")  # what metrics / derived_tables / report read
    #: run the updates of one instant as one batch (_UpdateBatch; same results, faster);
    #: False runs each node's update inline
    batch_updates = True
    Params = StvfParams
    beacon_kind = KIND

    def setup(self) -> None:
        p: StvfParams = self.params
        self.prior = vf.STVFPrior(
            transition=np.eye(4) * p.transition_precision,
            wishart_scale=np.eye(4) * p.wishart_scale,
            wishart_dof=p.wishart_dof,
            speed=p.speed_mps,
            speed_precision=p.speed_precision,
            noise_shape=p.noise_shape,
            noise_rate=p.noise_rate_ms2,
            n_state_samples=p.n_samples,
            n_speed_samples=p.n_samples,
            tol=p.tol_m,
            max_iter=p.max_iter,
            common_random_numbers=p.common_random_numbers,
        )
        self.is_beacon = self.role in (Role.ANCHOR, Role.BUOY)
        self.confidence = 1.0 if self.is_beacon else 0.0
        self.mu: np.ndarray | None = None
        self.mu_precision: np.ndarray | None = None
        self.track = EpochTrack(p.velocity_window_s)  # own estimates at their measurement epochs
        self.missed = 0

    # -- beacon side -------------------------------------------------------------------------

    def advertises(self) -> bool:
        """Beacon nodes always; an unknown node while its last localization (in the last
        period) made it a reference (eta >= delta)."""
        if self.is_beacon:
            return True
        return len(self.track) > 0 and self.confidence >= self.params.delta and self.missed == 0

    def beacon_payload(self) -> tuple[float, ...]:
        """The beacon (``BEACON_FIELDS``) at its send instant: a beacon node's position fix and
        velocity sensor; a promoted node's estimate carried from its measurement epoch to now.
        A flat tuple of floats is immutable, so every receiver shares it
        (``packet.copy_payload``) instead of getting its own copy."""
        if self.is_beacon:
            pos = np.asarray(self.known_position(), float)
            vel = np.asarray(self.velocity(), float)[:2]
            return (float(pos[0]), float(pos[1]), float(pos[2]), 1.0, float(vel[0]), float(vel[1]))
        xy = self.track.at(self.local_time())
        vx, vy = self.track.velocity()
        return (float(xy[0]), float(xy[1]), self.depth(), self.confidence, float(vx), float(vy))

    # -- localization ------------------------------------------------------------------------

    def measurements(
        self, heard: list[Any]
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
        """(z ms projected, refs (n, 2), eta (n,), speed (n,), receive stamps (n,) local s, own
        depth) from receptions."""
        p: StvfParams = self.params
        depth = self.depth()
        if not heard:
            return np.empty(0), np.empty((0, 2)), np.empty(0), np.empty(0), np.empty(0), depth
        pay = np.array([r.packet.payload for r in heard], float)  # (n, 6): BEACON_FIELDS
        z = 1e3 * np.array([r.rx_local - r.packet.tx_local for r in heard])
        if p.noise_ratio > 0:
            z = z * (1.0 + p.noise_ratio * self.rng.standard_normal(z.size))
        z = vf.project_delay(z, pay[:, 2] - depth, p.speed_mps)
        # contiguous copies, as before: a reduction's order can depend on the memory layout
        refs = np.ascontiguousarray(pay[:, :2])
        eta = np.ascontiguousarray(pay[:, 3])
        speed = np.hypot(pay[:, 4], pay[:, 5])
        return z, refs, eta, speed, np.array([r.rx_local for r in heard]), depth

    def localize(self, heard: list[Any]) -> None:
        p: StvfParams = self.params
        z, refs, eta, speed, t_rx, depth = self.measurements(heard)
        now = self.local_time()
        if z.size < p.n_ref:
            self.missed += 1
            return
        fresh = self.mu is None or (self.missed > 0 and not p.keep_prior_across_gaps)
        if fresh and z.size < p.first_fix_refs:
            # No prior and too few references for an unambiguous fix (two circles cross
            # twice): wait rather than start the filter on a mirror image.
            self.missed += 1
            return
        fix = self.first_fix(z, refs) if fresh else None
        if fresh and fix is None:
            # no fix as good as q(mu_0) claims (e.g. references near one line): wait
            self.missed += 1
            return
        gamma = vf.measurement_confidence(eta, z, speed, (p.c1, p.c2, p.c3), penalize=p.penalize_far_fast)
        sel = vf.select_references(gamma, p.n_ref)
        z, refs, eta = z[sel], refs[sel], eta[sel]
        used = " ".join(str(heard[i].packet.src) for i in sel)
        # the estimate is the position when its ranges were measured (their mean receive stamp)
        epoch = float(t_rx[sel].mean()) if p.estimate_epoch == "measurement" else now

        if fix is not None:
            self.mu, self.mu_precision = vf.initial_prior(fix, p.initial_std_m)
            gaps = 1
        else:
            gaps = self.missed + 1
        assert self.mu is not None and self.mu_precision is not None
        transition = self.prior.transition / gaps
        done = partial(
            self._localized,
            z=z,
            refs=refs,
            eta=eta,
            now=now,
            epoch=epoch,
            depth=depth,
            fresh=fresh,
            n_heard=len(heard),
            used=used,
        )
        # Deferred to the end of this instant, unless the next period starts at it (listen_s >=
        # period_s): the node then reads its own confidence for its beacon at this instant.
        if self.batch_updates and p.listen_s < p.period_s:
            job = _Job(self, z, refs, self.mu, self.mu_precision, transition, done)
            self.out_of_band.setdefault(_BATCH, _UpdateBatch()).add(job)
        else:
            mu_p, lp = vf.predict(self.mu, self.mu_precision, transition)
            done(vf.variational_update(z, refs, mu_p, lp, self.prior, self.rng))

    def _localized(
        self,
        out: vf.VariationalResult,
        *,
        z: np.ndarray,
        refs: np.ndarray,
        eta: np.ndarray,
        now: float,
        epoch: float,
        depth: float,
        fresh: bool,
        n_heard: int,
        used: str,
    ) -> None:
        """The rest of a localization once Algorithm 1's update ``out`` is in: the estimate is
        recorded at its measurement ``epoch`` and logged carried to ``now``."""
        p: StvfParams = self.params
        self.mu, self.mu_precision = out.mu, out.mu_precision
        self.missed = 0
        xy = out.position
        self.track.add(epoch, xy)
        self.confidence = vf.localization_confidence(eta, xy, refs, z, out.speed, absolute=p.absolute_error)
        is_ref = promote(self.confidence, p.delta)
        logged = self.track.at(now)
        self.log_estimate(
            logged[0],
            logged[1],
            depth,
            confidence=self.confidence,
            is_reference=is_ref,
            iterations=out.iterations,
            converged=out.converged,
            n_heard=n_heard,
            fresh=fresh,
            period_s=p.period_s,
            epoch_lag_s=now - epoch,
            refs=used,
            range_rel_std=p.noise_ratio,
        )

    def first_fix(self, z: np.ndarray, refs: np.ndarray) -> np.ndarray | None:
        """(x, y) for q(mu_0) (Algorithm 1 takes mu*_0 as given), or None to wait:
        :func:`~aquasim_py.estimation.variational.initial_fix` on the nominal-speed ranges to
        every reference heard, judged with the node's own error model (ToA ``noise_ratio`` and
        the sound-speed prior's std, relative to the range) against the std q(mu_0) claims."""
        p: StvfParams = self.params
        rel_std = math.hypot(p.noise_ratio, 1.0 / (math.sqrt(p.speed_precision) * p.speed_mps))
        return vf.initial_fix(refs, z * p.speed_mps / 1e3, rel_std, p.initial_std_m, p.range_m)

    # -- metrics -----------------------------------------------------------------------------

    @classmethod
    def metrics(cls, tables: Mapping[str, Any]) -> dict[str, float]:
        return {**localization_metrics(tables, cls.name, converge_within=5), **crb_metrics(tables, cls.name)}
