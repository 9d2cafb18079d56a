"""SVL-PF target localization (Li, Zhang, Yan, Han, Guan, Sensors 18:8, 2018) as a network.

One protocol, three roles:

- the target (role ``target``) actively sends a localization request every ``period_s``;
- each sensor (role ``anchor``) measures the request's time of arrival from the MAC stamps
  (rx - tx: the paper's time-synchronous ToA, eq 1), turns it into a distance with the nominal
  speed (distance = delay x ``speed_mps``), adds its sensing noise (Gaussian, std
  ``noise_ratio`` x distance, plus an independent ``excess_noise_ratio`` x distance: the
  paper's 10 % and 25 %; drawn from the sensor's own stream, as STVF's ranging error) and
  reports distance, received SNR and its surveyed position to the fusion node in a TDMA slot
  (slots keyed by node id, timed to *arrive* ``slot_s`` apart at the fusion node);
- the fusion node (role ``buoy``) announces its position once, collects the reports of a
  request, selects sensors with the per-sensor SVMs (eq 14), and estimates the target with
  ``algorithm``:

  ``svlpf``     LSSVR observation (eqs 15-20) + diagnosis by propagation loss (eqs 23-25),
                weights (eq 26) and iterative regression (eqs 21, 27) + PF with eq 31;
  ``lssvr_pf``  the same without the diagnosis / iterative regression (ref. [26]);
  ``toa_pf``    PF with the range likelihood of eq 29 (ref. [28]);
  ``consensus`` Consensus Estimation (ref. [14]; see math.consensus_estimate).

Training (SVMs per sensor, LSSVR per selected subset) happens during the run, seeded by
``train_seed`` and cached (math.TrainingCache). The "propagation loss" of the diagnosis is
TIL - RIL with RIL = the sensor's SNR estimate (``Reception.snr_db``: the true SNR plus the
modem's estimation error, 1 dB std by default) + the known noise level (``noise_band_db``).
Neither the sensors nor the fusion node know which links are obstructed: the diagnosis infers
it from that loss (docs/svlpf.md measures how the SNR estimate noise affects it).

Nothing here reads ground truth: distances come from MAC stamps, positions from the nodes'
own position fixes, losses from the received SNR estimate.
"""

from __future__ import annotations

from collections.abc import Generator, Mapping
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from aquasim_py.estimation import particle as pf
from aquasim_py.estimation.motion import ConstantVelocityModel
from aquasim_py.node import Node, Role
from aquasim_py.registry import register

from . import math as sv
from .metrics import svlpf_metrics

__all__ = ["SvlpfNode", "SvlpfParams"]

REQ = "svlpf_req"
REPORT = "svlpf_report"
HELLO = "svlpf_hello"

Algorithm = Literal["svlpf", "toa_pf", "lssvr_pf", "consensus"]
#: PF likelihood std per estimator (m), chosen on held-out seeds (docs/svlpf.md, "PF noise")
SIGMA = {"toa_pf": 8.0, "lssvr_pf": 4.0, "svlpf": 2.0}
ALGORITHMS = ("svlpf", "toa_pf", "lssvr_pf", "consensus")


class SvlpfParams(BaseModel):
    """SVL-PF parameters (paper Section 4 where it gives them; other choices in docs/svlpf.md)."""

    model_config = ConfigDict(extra="forbid")

    algorithm: Algorithm = Field("svlpf", description="fusion estimator: svlpf, toa_pf, lssvr_pf, consensus")
    also: list[Algorithm] = Field(
        default_factory=list,
        description="estimators run beside it on the same reports (same numbers as alone; cheap Monte Carlo)",
    )
    # target
    period_s: float = Field(1.0, gt=0, description="T: time between localization requests (s)")
    start_s: float = Field(1.0, ge=0, description="first request (s, target's clock)")
    request_bits: int = Field(64, ge=1)
    # sensors
    speed_mps: float = Field(1500.0, gt=0, description="v_s: nominal sound speed of eq 1 (m/s)")
    noise_ratio: float = Field(0.10, ge=0, description="universal sensing noise std / distance")
    excess_noise_ratio: float = Field(0.0, ge=0, description="additional (excessive) sensing noise std / distance")
    report_bits: int = Field(96, ge=1)
    uplink_start_s: float = Field(0.3, ge=0, description="first report slot arrives this long after the request (s)")
    slot_s: float = Field(0.015, gt=0, description="report slot length at the fusion node (s); slot index = node id")
    # fusion: collection, region
    collect_s: float = Field(0.8, gt=0, description="the fusion node waits this long after a request for reports (s)")
    region_lo: list[float] = Field(default_factory=lambda: [0.0, 0.0, 0.0], min_length=3, max_length=3)
    region_hi: list[float] = Field(default_factory=lambda: [100.0, 100.0, 100.0], min_length=3, max_length=3)
    # node selection (eqs 13-14)
    theta_m: float = Field(180.0, gt=0, description="distance parameter: training distances in [0, theta] (m)")
    efficient_range_m: float = Field(50.0, gt=0, description="communication-efficient range (m)")
    svm_samples: int = Field(400, ge=10, description="synthetic positions per sensor SVM")
    svm_c: float = Field(10.0, gt=0, description="P: SVM regularization constant")
    svm_gamma: float = Field(50.0, gt=0, description="RBF gamma on distance / theta")
    min_selected: int = Field(3, ge=1, description="if fewer are selected, the ones with the largest discriminant")
    # LSSVR (eqs 15-20)
    lssvr_samples: int = Field(500, ge=10, description="J: synthetic positions per selected subset")
    lssvr_c: float = Field(100.0, gt=0, description="C: LSSVR regularization gain")
    lssvr_width_m: float = Field(20.0, gt=0, description="RBF kernel width on the distance vector (m)")
    lssvr_train_noise_ratio: float = Field(0.10, ge=0, description="noise std / distance in the training inputs")
    lssvr_range_margin_m: float = Field(10.0, ge=0, description="training positions within efficient range + this")
    # diagnosis and iterative regression (eqs 23-27)
    source_level_db: float = Field(170.0, description="TIL: the target's transmitted level (dB re 1 uPa at 1 m)")
    noise_band_db: float = Field(
        66.34, description="receiver noise N(f) + 10 log10 B (dB; 10 kHz, 5 kHz band, shipping 0.5): RIL = SNR + this"
    )
    beta_db_per_km: float = Field(1.187, ge=0, description="beta of eq 24 (dB/km; Thorp at 10 kHz)")
    p_hat: float = Field(0.5, gt=0, le=1, description="gain of propagation loss (eq 25)")
    diagnosis: Literal["printed", "excess"] = Field(
        "printed",
        description="eq 25: TIL - RIL >= p tau(R) as printed (flags every link), or the loss in excess of tau(R)",
    )
    delta_clip: bool = Field(False, description="eq 26: clip delta to [0, 1] (the printed ratio exceeds 1 for R < S/2)")
    regression: Literal["printed", "repaired"] = Field(
        "printed",
        description="eq 21: Z = f(delta R) as printed, or the repaired iteration "
        "x = delta R + (1 - delta) |Z - s| (docs/svlpf.md)",
    )
    eps_b_m: float = Field(1.0, gt=0, description="eq 27: |Z - b| >= this (m)")
    eps_step_m: float = Field(0.2, gt=0, description="eq 27: |Z^(v+1) - Z^(v)| <= this (m)")
    max_iter: int = Field(50, ge=1)
    # particle filter
    n_particles: int = Field(1000, ge=10)
    q_pos_m: float = Field(1.0, ge=0, description="CV model: position noise std per period (m; paper: unit variance)")
    q_vel_mps: float = Field(0.1, ge=0, description="CV model: velocity noise std per period (m/s)")
    init_speed_mps: float = Field(1.0, ge=0, description="initial particle velocities uniform in +-this per axis")
    # The paper gives no sigma: each estimator's is chosen on held-out seeds by one rule for all
    # (docs/svlpf.md, "PF noise"; tools/svlpf_sigma.py)
    sigma_toa_pf_m: float = Field(SIGMA["toa_pf"], gt=0, description="toa_pf: sigma of eq 29 (m)")
    sigma_lssvr_pf_m: float = Field(SIGMA["lssvr_pf"], gt=0, description="lssvr_pf: sigma of eq 31 (m)")
    sigma_svlpf_m: float = Field(SIGMA["svlpf"], gt=0, description="svlpf: sigma of eq 31 (m)")
    # consensus baseline
    consensus_group: int = Field(4, ge=1, description="sensors per subnetwork")
    consensus_iters: int = Field(20, ge=0, description="average-consensus rounds")
    # training
    train_seed: int = Field(0, ge=0, description="seed of the synthetic training data (not the run seed)")
    cache: Literal["disk", "memory"] = Field("disk", description="trained models: on disk + in process, or in process")
    cache_dir: str | None = Field(None, description="on-disk cache directory (default: user cache dir)")


@register
class SvlpfNode(Node):
    """An SVL-PF node: target (requests), anchor (sensor) or buoy (fusion node) by role."""

    name = "svlpf"
    trace_tables = ("svlpf", "packets", "positions", "nodes")  # what metrics / derived_tables / report read
    Params = SvlpfParams

    def setup(self) -> None:
        p: SvlpfParams = self.params
        self.region_lo = np.asarray(p.region_lo, float)
        self.region_hi = np.asarray(p.region_hi, float)
        self._cache = sv.TrainingCache(
            None
            if p.cache == "memory"
            else (p.cache_dir if p.cache_dir is not None else sv.TrainingCache.default_directory())
        )
        self._svms: dict[int, sv.SvmModel] = {}
        self._lssvr: dict[tuple[int, ...], sv.LssvrModel] = {}
        # one estimator per algorithm, each with its own stream from one draw of the node's own
        base = int(self.rng.integers(2**63))
        algos = [p.algorithm] + [a for a in dict.fromkeys(p.also) if a != p.algorithm]
        self._estimators = [
            _Estimator(a, np.random.default_rng([base, ALGORITHMS.index(a)]), a == p.algorithm) for a in algos
        ]

    def run(self) -> Generator[Any, Any, None]:
        if self.role is Role.TARGET:
            yield from self._target()
        elif self.role in (Role.ANCHOR, Role.ORDINARY):
            yield from self._sensor()
        else:
            yield from self._fusion()

    @classmethod
    def metrics(cls, tables: Mapping[str, Any]) -> dict[str, float]:
        return svlpf_metrics(tables)

    # -- target -----------------------------------------------------------------------------------

    def _target(self) -> Generator[Any, Any, None]:
        p: SvlpfParams = self.params
        t_next, k = p.start_s, 1
        while True:
            wait = t_next - self.local_time()
            if wait > 0:
                yield self.sleep(wait)
            yield self.broadcast(REQ, {"k": k}, bits=p.request_bits)
            k += 1
            t_next += p.period_s

    # -- sensor -----------------------------------------------------------------------------------

    def _sensor(self) -> Generator[Any, Any, None]:
        p: SvlpfParams = self.params
        fusion: tuple[int, np.ndarray] | None = None
        pos = np.asarray(self.known_position(), float)
        while True:
            rec = yield self.recv(kinds=(HELLO, REQ))
            pkt = rec.packet
            if pkt.kind == HELLO:
                fusion = (pkt.src, np.asarray(pkt.payload["pos"], float))
                continue
            if fusion is None:
                continue
            d = (rec.rx_local - pkt.tx_local) * p.speed_mps  # eq 1
            # sensing noise of the measurement model: both draws always made, so the stream
            # does not depend on the scenario's ratios
            n1, n2 = self.rng.standard_normal(2)
            r = max(d + p.noise_ratio * d * n1 + p.excess_noise_ratio * d * n2, 0.1)
            # TDMA uplink: slot `id` arrives at the fusion node uplink_start_s + id * slot_s after the request
            arrive = pkt.tx_local + p.uplink_start_s + p.slot_s * self.id
            wait = arrive - float(np.linalg.norm(pos - fusion[1])) / p.speed_mps - self.local_time()
            if wait > 0:
                yield self.sleep(wait)
            payload = {
                "k": pkt.payload["k"],
                "uid": pkt.uid,
                "t_req": pkt.tx_local,
                "r": float(r),
                "snr": float(rec.snr_db),
                "pos": (float(pos[0]), float(pos[1]), float(pos[2])),
            }
            yield self.send(fusion[0], REPORT, payload, bits=p.report_bits)

    # -- fusion node ------------------------------------------------------------------------------

    def _fusion(self) -> Generator[Any, Any, None]:
        p: SvlpfParams = self.params
        pos = np.asarray(self.known_position(), float)
        yield self.broadcast(HELLO, {"pos": (float(pos[0]), float(pos[1]), float(pos[2]))}, bits=p.request_bits)
        while True:
            rec = yield self.recv(kinds=REPORT)
            first = rec.packet.payload
            reports = {rec.packet.src: first}
            deadline = first["t_req"] + p.collect_s
            while (left := deadline - self.local_time()) > 0:
                rec = yield self.recv(timeout=left, kinds=REPORT)
                if rec is None:
                    break
                if rec.packet.payload["k"] == first["k"]:
                    reports[rec.packet.src] = rec.packet.payload
            self._step(first, sorted(reports.items()))

    def _svm(self, sid: int, spos: np.ndarray) -> sv.SvmModel:
        """The SVM of sensor ``sid`` at ``spos`` (trained on first use, cached)."""
        m = self._svms.get(sid)
        if m is None:
            p: SvlpfParams = self.params
            parts = {
                "sensor": spos,
                "lo": self.region_lo,
                "hi": self.region_hi,
                "theta": p.theta_m,
                "range": p.efficient_range_m,
                "n": p.svm_samples,
                "c": p.svm_c,
                "gamma": p.svm_gamma,
                "seed": p.train_seed,
            }
            key = sv.cache_key("svm", parts)

            def train() -> dict[str, np.ndarray]:
                rng = sv.training_rng(p.train_seed, key)
                d, y = sv.svm_training_set(
                    spos, self.region_lo, self.region_hi, p.svm_samples, p.theta_m, p.efficient_range_m, rng
                )
                return sv.svm_train(d, y, c=p.svm_c, gamma=p.svm_gamma, scale=p.theta_m).arrays()

            m = self._svms[sid] = sv.SvmModel.from_arrays(self._cache.get(key, train))
        return m

    def lssvr_model(self, ids: tuple[int, ...], S: np.ndarray) -> sv.LssvrModel:
        """The LSSVR of the selected subset (trained on first use, cached)."""
        m = self._lssvr.get(ids)
        if m is None:
            p: SvlpfParams = self.params
            rng_m = p.efficient_range_m + p.lssvr_range_margin_m
            parts = {
                "sensors": S,
                "lo": self.region_lo,
                "hi": self.region_hi,
                "n": p.lssvr_samples,
                "c": p.lssvr_c,
                "width": p.lssvr_width_m,
                "noise": p.lssvr_train_noise_ratio,
                "range": rng_m,
                "seed": p.train_seed,
            }
            key = sv.cache_key("lssvr", parts)

            def train() -> dict[str, np.ndarray]:
                rng = sv.training_rng(p.train_seed, key)
                X, Y = sv.lssvr_training_set(
                    S,
                    self.region_lo,
                    self.region_hi,
                    p.lssvr_samples,
                    rng,
                    noise_ratio=p.lssvr_train_noise_ratio,
                    max_range_m=rng_m,
                )
                return sv.lssvr_fit(X, Y, c=p.lssvr_c, width=p.lssvr_width_m).arrays()

            m = self._lssvr[ids] = sv.LssvrModel.from_arrays(self._cache.get(key, train))
        return m

    def _step(self, first: Mapping[str, Any], reports: list[tuple[int, Mapping[str, Any]]]) -> None:
        """One time frame k from the reports (sensor id, payload): node selection (shared),
        then every estimator (the primary ``algorithm`` and the ``also`` ones), one log row each."""
        p: SvlpfParams = self.params
        src = [i for i, _ in reports]
        R = np.array([r["r"] for _, r in reports], float)
        snr = np.array([r["snr"] for _, r in reports], float)
        P = np.array([r["pos"] for _, r in reports], float)
        # node selection (eq 14) on the measured distances: one small SVM per sensor
        f = np.array([float(sv.svm_discriminant(self._svm(i, P[j]), R[j])) for j, i in enumerate(src)])
        sel = f > 0
        if sel.sum() < min(p.min_selected, len(R)):
            sel = np.zeros(len(R), bool)
            sel[np.argsort(-f, kind="stable")[: p.min_selected]] = True
        idx = np.flatnonzero(sel)
        S, Rs = P[idx], R[idx]
        ids = tuple(src[j] for j in idx)
        for est in self._estimators:
            row = est.step(self, float(first["t_req"]), S, Rs, snr[idx], ids)
            self.log(
                "svlpf",
                k=int(first["k"]),
                req_uid=int(first["uid"]),
                t_req_local=float(first["t_req"]),
                n_reports=len(R),
                n_selected=len(idx),
                selected=" ".join(map(str, ids)),
                **row,
            )


class _Estimator:
    """One fusion estimator (Algorithm 2 and its baselines) with its own particle set and its
    own random stream (keyed by the algorithm), so that running it alone or beside others
    gives the same numbers."""

    def __init__(self, algorithm: str, rng: np.random.Generator, primary: bool) -> None:
        self.algorithm = algorithm
        self.rng = rng
        self.primary = primary
        self.X: np.ndarray | None = None  # particles (Np, 6): position, velocity
        self.logw: np.ndarray | None = None
        self.t_last = 0.0

    def step(
        self, node: SvlpfNode, t_req: float, S: np.ndarray, Rs: np.ndarray, snr: np.ndarray, ids: tuple[int, ...]
    ) -> dict[str, Any]:
        p: SvlpfParams = node.params
        flagged_ids: list[int] = []
        iterations, converged = 0, True
        z = np.full(3, np.nan)
        algo = self.algorithm
        if algo == "consensus":
            est = sv.consensus_estimate(
                S, Rs, node.region_lo, node.region_hi, group_size=p.consensus_group, iterations=p.consensus_iters
            )
        else:
            self.predict(p, node.region_lo, node.region_hi, t_req)
            assert self.X is not None
            if algo == "toa_pf":
                loglik = sv.range_loglik(self.X, S, Rs, p.sigma_toa_pf_m)  # eq 29
            else:
                model = node.lssvr_model(ids, S)
                if algo == "svlpf":
                    loss = p.source_level_db - (snr + p.noise_band_db)  # TIL - RIL (eq 23)
                    flagged = sv.diagnose(
                        loss, Rs, p_hat=p.p_hat, beta_db_per_km=p.beta_db_per_km, excess=p.diagnosis == "excess"
                    )
                    flagged_ids = [ids[j] for j in np.flatnonzero(flagged)]
                    delta = sv.delta_weights(Rs, model.mean_input, flagged, clip=p.delta_clip)
                    res = sv.iterative_regression(
                        model,
                        Rs,
                        S,
                        delta,
                        eps_b=p.eps_b_m,
                        eps_step=p.eps_step_m,
                        max_iter=p.max_iter,
                        repaired=p.regression == "repaired",
                    )
                    z, iterations, converged = res.z, res.iterations, res.converged
                else:
                    z = sv.lssvr_predict(model, Rs)  # eq 20
                sigma = p.sigma_svlpf_m if algo == "svlpf" else p.sigma_lssvr_pf_m
                loglik = sv.observation_loglik(self.X, z, sigma)  # eq 31
            est = self.update(loglik)
        return {
            "algorithm": algo,
            "primary": self.primary,
            "x": float(est[0]),
            "y": float(est[1]),
            "z": float(est[2]),
            "obs_x": float(z[0]),
            "obs_y": float(z[1]),
            "obs_z": float(z[2]),
            "n_flagged": len(flagged_ids),
            "flagged": " ".join(map(str, flagged_ids)),
            "iterations": iterations,
            "converged": converged,
        }

    def predict(self, p: SvlpfParams, lo: np.ndarray, hi: np.ndarray, t_req: float) -> None:
        """Draw the particles of frame k from the CV model (eq 4, Section 4: unit position
        noise per period); the first frame draws them uniformly over the monitored region."""
        rng = self.rng
        n = p.n_particles
        if self.X is None:
            pos = rng.uniform(lo, hi, size=(n, 3))
            vel = rng.uniform(-p.init_speed_mps, p.init_speed_mps, size=(n, 3))
            self.X = np.hstack([pos, vel])
            self.logw = np.full(n, -np.log(n))
        else:
            dt = max(t_req - self.t_last, 0.0)
            Q = np.diag([p.q_pos_m**2] * 3 + [p.q_vel_mps**2] * 3) * (dt / p.period_s)
            self.X = pf.propagate(self.X, ConstantVelocityModel(dim=3, dt=dt).transition, Q, rng)
        self.t_last = t_req

    def update(self, loglik: np.ndarray) -> np.ndarray:
        """Weights (eqs 29 / 31), estimate (eq 12), systematic resampling (Algorithm 2, step 13)."""
        assert self.X is not None and self.logw is not None
        self.logw = pf.update_log_weights(self.logw, loglik)
        est = pf.weighted_mean(self.X[:, :3], np.exp(self.logw))
        self.X, self.logw = pf.resample(self.X, self.logw, self.rng)
        return est
