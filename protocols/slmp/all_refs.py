"""``multilateration_all_refs``: multilateration on every reference in range, every period, on
the STVF set-up; a baseline beside SLMP (it was this project's ``slmp`` until issue 15, then
``multilateration_bound``: it is no bound, see docs/stvf.md; the bounds are the genie
multilateration and the CRB, :mod:`aquasim_protocols.stvf.genie`).

It is *not* SLMP as Zhou et al. designed it (that is :mod:`.node`): every period every unknown
node multilaterates on **all** references in range (about 15.7 at density 16) with linear least
squares refined by 5 Gauss-Newton steps; beacons broadcast their own position fix every period
(exact unless the scenario sets ``position_noise_std_m``); stale references (heard within
``validity_s``) make up the count with the node's predicted displacement since they were heard.
So it shows what multilateration reaches when it is given every measurement every period.

- Beacons (role ``anchor``) broadcast position, depth, confidence 1 and their predicted
  velocity every period; the first ``training_s`` only train the mobility predictors.
- With >= ``min_refs`` (3, after projection on the depth plane) references: multilateration
  and a confidence (:func:`~aquasim_protocols.slmp.math.slmp_confidence`); above ``delta``
  the node becomes a reference. Otherwise, with >= ``self_min_refs`` references in view and a
  previous estimate, the node self-estimates from its previous location and predicted velocity.
- The predicted velocity is capped at ``max_speed_mps``: the SLMP/STVF account has nodes drift
  with the kinematic current, whose speed is bounded (2.0 m/s at Table 1's parameter means:
  sqrt((k1 iota omega + k1 iota + k4)^2 + (iota omega + k5)^2) x the 0.1 m/s speed scale);
  uncapped, an AR(15) fit to noisy fixes predicted -48 m/s and carried a node 2.7 km off.

The ranging model is STVF's: one-way delays from MAC stamps (synchronized clocks), error std
``noise_ratio`` x delay, ranges at the nominal ``speed_mps``. A fix is the position at the mean
receive stamp of the fresh ranges it used, carried to the log and beacon instants.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from pydantic import Field

from aquasim_py.estimation.errors import DegenerateGeometryError, InsufficientMeasurementsError
from aquasim_py.estimation.lsq import multilaterate
from aquasim_py.estimation.variational import project_delay
from aquasim_py.node import Role
from aquasim_py.registry import register

from ..common.periodic import PeriodicBeaconNode
from ..stvf.metrics import localization_metrics
from .math import MobilityPredictor, in_range, slmp_confidence
from .node import SlmpSharedParams

__all__ = ["MultilaterationAllRefsNode", "MultilaterationAllRefsParams"]

KIND = "mlat_all_beacon"


class MultilaterationAllRefsParams(SlmpSharedParams):
    """Parameters of ``multilateration_all_refs``: SLMP's (:class:`~.node.SlmpSharedParams`),
    and how stale references and self-estimates are used."""

    validity_s: float = Field(60.0, ge=0, description="how long a reference's beacon stays usable (s)")
    self_min_refs: int = Field(2, ge=0, description="references in view needed to self-estimate")
    max_speed_mps: float | None = Field(
        2.0, gt=0, description="cap on the predicted velocity (m/s): the kinematic current's speed bound; null = none"
    )


@register
class MultilaterationAllRefsNode(PeriodicBeaconNode):
    """Beacons (anchor) broadcast; unknown nodes (ordinary) multilaterate every period on all."""

    name = "multilateration_all_refs"
    trace_tables = ("estimates", "nodes")  # what metrics / derived_tables / report read
    Params = MultilaterationAllRefsParams
    beacon_kind = KIND

    def setup(self) -> None:
        p: MultilaterationAllRefsParams = self.params
        self.is_beacon = self.role in (Role.ANCHOR, Role.BUOY)
        self.predictor = MobilityPredictor(
            p.period_s,
            window=int(round(p.window_s / p.period_s)),
            overlap=p.overlap,
            order=p.order,
            threshold=p.error_ratio * p.range_m,
            max_speed=p.max_speed_mps,
        )
        self.confidence = 1.0 if self.is_beacon else 0.0
        self.is_reference = self.is_beacon
        self.last: tuple[float, np.ndarray] | None = None  # (local time, xy) of the last estimate
        self.table: dict[int, tuple[float, np.ndarray, float, float]] = {}  # src -> (t0, xy, r, eta)
        self._fix = np.zeros(3)  # a beacon's position fix of this period (localize_reference)

    def advertises(self) -> bool:
        """Beacons always; an unknown node while its last fix made it a reference."""
        return self.is_beacon or (self.is_reference and self.last is not None)

    def localize_reference(self) -> None:
        """A beacon's position fix at the send instant trains its mobility predictor."""
        if self.is_beacon:
            self._fix = np.asarray(self.known_position(), float)
            self.predictor.add(self.local_time(), self._fix[:2])

    def beacon_payload(self) -> dict[str, Any]:
        """The beacon at its send instant: a beacon's fix (:meth:`localize_reference`), or a
        reference's last fix carried to now with the predicted velocity."""
        vel = self.predictor.velocity()
        if self.is_beacon:
            xy, depth, eta = self._fix[:2], float(self._fix[2]), 1.0
        else:
            assert self.last is not None
            xy, depth, eta = self.last[1] + vel * (self.local_time() - self.last[0]), self.depth(), self.confidence
        return {"xy": (float(xy[0]), float(xy[1])), "depth": depth, "eta": eta, "vel": (float(vel[0]), float(vel[1]))}

    def ready(self, elapsed_s: float) -> bool:
        """Unknown nodes localize only after the beacons' mobility training."""
        return elapsed_s >= self.params.training_s

    def localize(self, heard: list[Any]) -> None:
        p: MultilaterationAllRefsParams = self.params
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
        # the fix is the position when the fresh ranges were measured (their mean receive stamp)
        epoch = float(np.mean([e[0] for e in fresh])) if fresh and p.estimate_epoch == "measurement" else now
        refs, ranges, etas = [], [], []
        for t0, xy, r, eta in use:
            if now - t0 > p.period_s:
                assert vel is not None  # stale entries are only used with a velocity
                xy = xy + vel * (epoch - t0)  # own displacement since the beacon was heard
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
            xy_est = self.last[1] + self.predictor.velocity() * (epoch - self.last[0])
            method = "self"
            conf = 0.0
        if xy_est is None:
            self.is_reference = False
            return
        if method == "multilateration" and conf >= p.delta:
            # the mobility pattern is learnt from trusted fixes only
            self.predictor.add(epoch, xy_est)
        self.confidence = conf
        self.is_reference = method == "multilateration" and conf >= p.delta
        self.last = (epoch, np.asarray(xy_est, float))
        logged = self.last[1] + self.predictor.velocity() * (now - epoch)
        self.log_estimate(
            logged[0],
            logged[1],
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
