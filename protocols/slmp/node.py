"""SLMP as designed: Z. Zhou, Z. Peng, J.-H. Cui, Z. Shi, A. Bagtzoglou, "Scalable localization
with mobility prediction for underwater sensor networks", IEEE Trans. Mobile Computing 10(3),
2011 (INFOCOM 2008; UConn tech. report UbiNet-TR07-01), with the parameters the STVF paper
(Hu et al., Sensors 2018, Sec. 5.3) ran it with. docs/stvf.md lists each choice the paper
leaves open.

SLMP is hierarchical (the paper's abstract): *anchor node localization* and *ordinary node
localization*; every node predicts its future mobility pattern from its past known locations
and estimates its location from that prediction, so that localization (and its messages) is
needed only when the prediction goes wrong.

- Anchors (role ``anchor``) localize against the surface buoys (here: the kernel's position
  fix, ``Node.known_position()``, whose noise is the group's ``position_noise_std_m``) and
  learn their mobility pattern (:class:`~aquasim_protocols.slmp.math.MobilityPredictor`).
  What they advertise is their *predicted* position; the pattern is re-advertised (the fix
  replaces the prediction) only when the prediction misses the buoy fix by more than the
  threshold ``error_ratio`` x ``range_m`` (5 % of the range).
- Ordinary nodes (role ``ordinary``) wait ``training_s`` (the anchors' training), then
  predict their position from their own mobility pattern each period. They check the
  prediction against the references they hear: if the RMS range residual of the prediction
  exceeds the threshold (or there is no prediction yet), they **re-localize** with plain
  linear least squares on the references heard this period (>= ``min_refs``) and feed the fix
  to their predictor; otherwise the prediction stands (and is recorded as a known location).
- Every localized node reports a position each period (its fix or its prediction) with a
  confidence (:func:`~aquasim_protocols.slmp.math.slmp_confidence` against the references
  heard); at or above ``delta`` it is a reference and broadcasts that position and confidence
  from the next period start (beacons go out in the first half of a period, localization ends
  it).

The ranging model is STVF's: one-way delays from MAC stamps (synchronized clocks), error std
``noise_ratio`` x delay, ranges at the nominal ``speed_mps``. Nothing here reads ground truth.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Literal

import numpy as np
from pydantic import Field

from aquasim_py.estimation.errors import DegenerateGeometryError, InsufficientMeasurementsError
from aquasim_py.estimation.lsq import multilaterate
from aquasim_py.estimation.variational import project_delay
from aquasim_py.node import Role
from aquasim_py.registry import register

from ..common.periodic import PeriodicBeaconNode, PeriodicParams
from ..stvf.genie import crb_metrics
from ..stvf.metrics import localization_metrics
from .math import MobilityPredictor, in_range, prediction_residual, slmp_confidence

__all__ = ["SlmpNode", "SlmpParams", "SlmpSharedParams"]

KIND = "slmp_beacon"


class SlmpSharedParams(PeriodicParams):
    """What SLMP and ``multilateration_all_refs`` share (STVF Sec. 5.3 defaults; SLMP's own
    where STVF is silent): the anchors' training, the mobility predictor and its threshold,
    references and their confidence, the ranging model, the epoch of a fix."""

    training_s: float = Field(100.0, ge=0, description="anchor training before ordinary nodes localize (s)")
    window_s: float = Field(60.0, gt=0, description="prediction window (s)")
    overlap: float = Field(0.2, ge=0, lt=1, description="overlap of neighbouring windows (fraction)")
    order: int = Field(15, ge=1, description="prediction step: order of the linear predictor")
    range_m: float = Field(80.0, gt=0, description="communication range (m), for the error threshold")
    error_ratio: float = Field(0.05, gt=0, description="prediction error threshold / range")
    delta: float = Field(0.9, ge=0, le=1, description="confidence threshold for references")
    min_refs: int = Field(3, ge=3, description="references needed for least squares (2-D after projection)")
    speed_mps: float = Field(1500.0, gt=0, description="nominal sound speed (m/s)")
    noise_ratio: float = Field(0.02, ge=0, description="ranging error std / delay")
    estimate_epoch: Literal["measurement", "listen_end"] = Field(
        "measurement",
        description="a fix is the position at the mean receive stamp of the ranges heard this period "
        "(measurement) or at the end of the listening window (listen_end: the former stamp)",
    )


class SlmpParams(SlmpSharedParams):
    """SLMP parameters: the shared ones (:class:`SlmpSharedParams`), no others."""


@register
class SlmpNode(PeriodicBeaconNode):
    """An SLMP node: anchors advertise their predicted positions; ordinary nodes predict and
    re-localize when the prediction misses."""

    name = "slmp"
    trace_tables = ("estimates", "nodes", "positions")  # what metrics / derived_tables / report read
    Params = SlmpParams
    beacon_kind = KIND

    def setup(self) -> None:
        p: SlmpParams = self.params
        self.is_beacon = self.role in (Role.ANCHOR, Role.BUOY)
        self.threshold = p.error_ratio * p.range_m
        self.predictor = MobilityPredictor(
            p.period_s,
            window=int(round(p.window_s / p.period_s)),
            overlap=p.overlap,
            order=p.order,
            threshold=self.threshold,
        )
        self.confidence = 1.0 if self.is_beacon else 0.0
        self.is_reference = self.is_beacon
        self.relocalizations = 0
        # an anchor's advertisement of this period (localize_reference): position, re-advertised
        self._advert: tuple[np.ndarray, float, bool] | None = None

    # -- references ---------------------------------------------------------------------------

    def advertises(self) -> bool:
        """Anchors always; an ordinary node while its last localization made it a reference."""
        return self.is_beacon or (self.is_reference and bool(self.predictor.times))

    def localize_reference(self) -> None:
        """Anchor node localization (SLMP's first level), at the send instant: the buoy fix
        (``known_position()``) against the mobility pattern's prediction. What an anchor
        advertises is the prediction while it stays within the threshold of the fix; a miss
        re-advertises (the fix). The fix is a known location of the pattern either way."""
        if not self.is_beacon:
            return
        now = self.local_time()
        fix = np.asarray(self.known_position(), float)
        pred = self.predictor.predict(now)
        miss = pred is None or float(np.linalg.norm(pred - fix[:2])) > self.threshold
        self._advert = (fix[:2] if pred is None or miss else pred, float(fix[2]), bool(miss))
        self.predictor.add(now, fix[:2])

    def beacon_payload(self) -> dict[str, Any]:
        """The beacon at its send instant: an anchor's advertisement, or an ordinary
        reference's own prediction for now; with the pattern's predicted velocity."""
        vel = self.predictor.velocity()
        if self.is_beacon:
            assert self._advert is not None  # localize_reference ran just before
            xy, depth, update = self._advert
            eta = 1.0
        else:
            own = self.predictor.predict(self.local_time())
            assert own is not None
            xy, depth, update, eta = own, self.depth(), False, self.confidence
        return {
            "xy": (float(xy[0]), float(xy[1])),
            "depth": depth,
            "eta": eta,
            "vel": (float(vel[0]), float(vel[1])),
            "update": update,
        }

    def ready(self, elapsed_s: float) -> bool:
        """Ordinary nodes localize only after the anchors' mobility training."""
        return elapsed_s >= self.params.training_s

    # -- ordinary node localization -------------------------------------------------------------

    def ranges(self, heard: list[Any], depth: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(reference xy (n, 2), horizontal ranges (n,) m, confidences (n,)) of this period."""
        p: SlmpParams = self.params
        if not heard:
            return np.empty((0, 2)), np.empty(0), np.empty(0)
        pay = [r.packet.payload for r in heard]
        z = np.array([r.rx_local - r.packet.tx_local for r in heard])
        if p.noise_ratio > 0:
            z = z * (1.0 + p.noise_ratio * self.rng.standard_normal(z.size))
        dz = np.array([q["depth"] for q in pay]) - depth
        zh = project_delay(z, dz, p.speed_mps, z_scale=1.0)
        refs = np.array([q["xy"] for q in pay], float)
        eta = np.array([q["eta"] for q in pay], float)
        return refs, np.asarray(zh, float) * p.speed_mps, eta

    def localize(self, heard: list[Any]) -> None:
        p: SlmpParams = self.params
        now = self.local_time()
        depth = self.depth()
        refs, r, eta = self.ranges(heard, depth)
        # the fix (or the prediction it is checked against) is the position when the ranges
        # were measured: their mean receive stamp
        epoch = now
        if heard and p.estimate_epoch == "measurement":
            epoch = float(np.mean([rec.rx_local for rec in heard]))
        pred = self.predictor.predict(epoch)
        method = "predicted"
        xy: np.ndarray | None = pred
        miss = prediction_residual(pred, refs, r) if pred is not None and len(r) else float("nan")
        attempted = pred is None or miss > self.threshold
        if attempted:
            fix = self.least_squares(refs, r)
            if fix is not None:
                xy, method = fix, "least_squares"
                self.relocalizations += 1
        if xy is None:
            return  # never localized yet and too few references
        if method == "least_squares" or (method == "predicted" and len(r)):
            # a fix, or a prediction the references confirmed: a known location of the pattern
            self.predictor.add(epoch, xy)
        conf = slmp_confidence(eta, xy, refs, r) if len(r) >= p.min_refs else 0.0
        self.confidence = conf
        self.is_reference = conf >= p.delta
        logged = xy + self.predictor.velocity() * (now - epoch)
        self.log_estimate(
            logged[0],
            logged[1],
            depth,
            confidence=conf,
            is_reference=self.is_reference,
            method=method,
            n_refs=len(r),
            miss_m=miss,
            attempted=attempted,
            period_s=p.period_s,
            epoch_lag_s=now - epoch,
            refs=[rec.packet.src for rec in heard],  # this period's ranges, with the noise model
            range_rel_std=p.noise_ratio,
        )

    def least_squares(self, refs: np.ndarray, r: np.ndarray) -> np.ndarray | None:
        """Plain linear least squares (SLMP's multilateration) on this period's references; a
        fix farther than ``range_m`` from a reference it heard, beyond 3 std of the ranging
        noise there (:func:`.math.in_range`), is a failed one (ill-conditioned geometry)."""
        p: SlmpParams = self.params
        if len(r) < p.min_refs:
            return None
        try:
            xy = multilaterate(refs, r)
        except (DegenerateGeometryError, InsufficientMeasurementsError, np.linalg.LinAlgError):
            return None
        if not in_range(xy, refs, p.range_m, p.noise_ratio * p.range_m):
            return None
        return xy

    @classmethod
    def metrics(cls, tables: Mapping[str, Any]) -> dict[str, float]:
        out = {**localization_metrics(tables, cls.name), **crb_metrics(tables, cls.name)}
        est = tables.get("estimates")
        if est is not None and len(est) and "method" in est.columns:
            e = est[est["protocol"] == cls.name]
            if len(e):
                out["relocalization_share"] = float((e["method"] == "least_squares").mean())
        return out
