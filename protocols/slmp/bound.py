"""``multilateration_bound``: an upper bound for multilateration-based localization on the
STVF set-up, kept beside SLMP as a named baseline (it was this project's ``slmp`` until
issue 15; docs/stvf.md).

It is *not* SLMP as Zhou et al. designed it (that is :mod:`.node`): every period every unknown
node multilaterates on **all** references in range (about 15.7 at density 16) with linear least
squares refined by 5 Gauss-Newton steps; beacons broadcast their own position fix every period
(exact unless the scenario sets ``position_noise_std_m``); stale references (heard within
``validity_s``) make up the count with the node's predicted displacement since they were heard.
So it shows what multilateration can reach when it is given every measurement every period.

- Beacons (role ``anchor``) broadcast position, depth, confidence 1 and their predicted
  velocity every period; the first ``training_s`` only train the mobility predictors.
- With >= ``min_refs`` (3, after projection on the depth plane) references: multilateration
  and a confidence (:func:`~aquasim_protocols.slmp.math.slmp_confidence`); above ``delta``
  the node becomes a reference. Otherwise, with >= ``self_min_refs`` references in view and a
  previous estimate, the node self-estimates from its previous location and predicted velocity.

The ranging model is STVF's: one-way delays from MAC stamps (synchronized clocks), error std
``noise_ratio`` x delay, ranges at the nominal ``speed_mps``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from aquasim_py.estimation.errors import DegenerateGeometryError, InsufficientMeasurementsError
from aquasim_py.estimation.lsq import multilaterate
from aquasim_py.estimation.variational import project_delay
from aquasim_py.node import Role
from aquasim_py.registry import register

from ..common.periodic import PeriodicBeaconNode
from ..stvf.metrics import localization_metrics
from .math import MobilityPredictor, in_range, slmp_confidence

__all__ = ["MultilaterationBoundNode", "MultilaterationBoundParams"]

KIND = "mlat_bound_beacon"


class MultilaterationBoundParams(BaseModel):
    """Parameters of the multilateration bound (SLMP's STVF Sec. 5.3 defaults where shared)."""

    model_config = ConfigDict(extra="forbid")

    period_s: float = Field(1.0, gt=0, description="localization period (s)")
    listen_s: float = Field(0.9, gt=0, description="collection time after the period start (s)")
    send_window_s: float = Field(0.5, ge=0, description="random send offset range per period (s)")
    bits: int = Field(160, ge=1, description="beacon packet size (bits)")
    training_s: float = Field(100.0, ge=0, description="beacon training before unknown nodes localize (s)")
    window_s: float = Field(60.0, gt=0, description="prediction window (s)")
    overlap: float = Field(0.2, ge=0, lt=1, description="overlap of neighbouring windows (fraction)")
    order: int = Field(15, ge=1, description="prediction step: order of the linear predictor")
    range_m: float = Field(80.0, gt=0, description="communication range (m), for the error threshold")
    error_ratio: float = Field(0.05, gt=0, description="prediction error threshold / range")
    validity_s: float = Field(60.0, ge=0, description="how long a reference's beacon stays usable (s)")
    delta: float = Field(0.9, ge=0, le=1, description="confidence threshold for references")
    min_refs: int = Field(3, ge=3, description="references needed for multilateration (2-D)")
    self_min_refs: int = Field(2, ge=0, description="references in view needed to self-estimate")
    speed_mps: float = Field(1500.0, gt=0, description="nominal sound speed (m/s)")
    noise_ratio: float = Field(0.02, ge=0, description="ranging error std / delay")


@register
class MultilaterationBoundNode(PeriodicBeaconNode):
    """Beacons (anchor) broadcast; unknown nodes (ordinary) multilaterate every period on all."""

    name = "multilateration_bound"
    trace_tables = ("estimates", "nodes")  # what metrics / derived_tables / report read
    Params = MultilaterationBoundParams
    beacon_kind = KIND

    def setup(self) -> None:
        p: MultilaterationBoundParams = self.params
        self.is_beacon = self.role in (Role.ANCHOR, Role.BUOY)
        self.predictor = MobilityPredictor(
            p.period_s,
            window=int(round(p.window_s / p.period_s)),
            overlap=p.overlap,
            order=p.order,
            threshold=p.error_ratio * p.range_m,
        )
        self.confidence = 1.0 if self.is_beacon else 0.0
        self.is_reference = self.is_beacon
        self.last: tuple[float, np.ndarray] | None = None  # (local time, xy) of the last estimate
        self.table: dict[int, tuple[float, np.ndarray, float, float]] = {}  # src -> (t0, xy, r, eta)

    def beacon_payload(self) -> dict[str, Any] | None:
        now = self.local_time()
        if self.is_beacon:
            pos = self.known_position()
            self.predictor.add(now, pos[:2])
            vel = self.predictor.velocity()
            return {
                "xy": (float(pos[0]), float(pos[1])),
                "depth": float(pos[2]),
                "eta": 1.0,
                "vel": (float(vel[0]), float(vel[1])),
            }
        if self.is_reference and self.last is not None:
            vel = self.predictor.velocity()
            xy = self.last[1] + vel * (now - self.last[0])
            return {
                "xy": (float(xy[0]), float(xy[1])),
                "depth": self.depth(),
                "eta": self.confidence,
                "vel": (float(vel[0]), float(vel[1])),
            }
        return None

    def ready(self, elapsed_s: float) -> bool:
        """Unknown nodes localize only after the beacons' mobility training."""
        return elapsed_s >= self.params.training_s

    def localize(self, heard: list[Any]) -> None:
        p: MultilaterationBoundParams = self.params
        now = self.local_time()
        depth = self.depth()
        for rec in heard:
            q = rec.packet.payload
            z = rec.rx_local - rec.packet.tx_local
            if p.noise_ratio > 0:
                z *= 1.0 + p.noise_ratio * float(self.rng.standard_normal())
            zh = float(project_delay(z, q["depth"] - depth, p.speed_mps, z_scale=1.0))
            self.table[rec.packet.src] = (rec.rx_local, np.asarray(q["xy"], float), zh * p.speed_mps, q["eta"])
        self.table = {s: e for s, e in self.table.items() if now - e[0] <= p.validity_s}
        vel = self.predictor.velocity() if self.predictor.times else None
        # Fresh beacons (this period) first; stale ones (within the validity window, newest
        # first) only to make up the number multilateration needs.
        entries = sorted(self.table.values(), key=lambda e: -e[0])
        fresh = [e for e in entries if now - e[0] <= p.period_s]
        stale = [e for e in entries if now - e[0] > p.period_s] if vel is not None else []
        use = fresh + stale[: max(0, p.min_refs - len(fresh))]
        refs, ranges, etas = [], [], []
        for t0, xy, r, eta in use:
            if now - t0 > p.period_s:
                assert vel is not None  # stale entries are only used with a velocity
                xy = xy + vel * (now - t0)  # own displacement since the beacon was heard
            refs.append(xy)
            ranges.append(r)
            etas.append(eta)
        method = ""
        xy_est = None
        conf = 0.0
        if len(refs) >= p.min_refs:
            try:
                xy_est = multilaterate(np.array(refs), np.array(ranges), refine=5)
                # A node hears only nodes within range: a fix farther than that from a
                # reference, beyond the ranging noise, is a failed one (ill-conditioned
                # geometry), not an estimate.
                if in_range(xy_est, refs, p.range_m, p.noise_ratio * p.range_m):
                    conf = slmp_confidence(etas, xy_est, np.array(refs), np.array(ranges))
                    method = "multilateration"
                else:
                    xy_est = None
            except (DegenerateGeometryError, InsufficientMeasurementsError, np.linalg.LinAlgError):
                xy_est = None
        if xy_est is None and len(refs) >= p.self_min_refs and self.last is not None:
            xy_est = self.last[1] + self.predictor.velocity() * (now - self.last[0])
            method = "self"
            conf = 0.0
        if xy_est is None:
            self.is_reference = False
            return
        if method == "multilateration" and conf >= p.delta:
            # the mobility pattern is learnt from trusted fixes only
            self.predictor.add(now, xy_est)
        self.confidence = conf
        self.is_reference = method == "multilateration" and conf >= p.delta
        self.last = (now, np.asarray(xy_est, float))
        self.log_estimate(
            xy_est[0],
            xy_est[1],
            depth,
            confidence=conf,
            is_reference=self.is_reference,
            method=method,
            n_refs=len(refs),
            period_s=p.period_s,
        )

    @classmethod
    def metrics(cls, tables: Mapping[str, Any]) -> dict[str, float]:
        return localization_metrics(tables, cls.name)
