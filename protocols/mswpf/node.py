"""MSWPF (Zhang et al.): target tracking by a fusion centre that weights quantized pressure
reports of PCRLB-selected sensors by their mutual information, as one network protocol ``mswpf``.

Roles (one registered protocol; the behaviour follows the node's role):

- ``target``: a sound source. It broadcasts an ``mswpf_emission`` every ``interval_s`` from local
  ``start_s`` on (``steps`` times). The channel (``[channel] pressure_kind = "mswpf_emission"``)
  gives every reception the received pressure of eq 6 plus the hydrophone noise; the payload is
  empty (a non-cooperative source sends no data).
- ``sink``: the fusion centre (FC), Algorithm 1 with PCRLB node selection. Sensors announce
  their believed position in a ``mswpf_hello``. For interval k the FC selects Ns sensors among
  the qualified candidates (eqs 35-36) from the particles predicted for k and broadcasts a
  ``mswpf_task`` (step, selected ids, the predicted target position as mean and covariance).
  At local ``start_s + k interval_s + fuse_delay_s`` it fuses the ``mswpf_report``s of step k
  that have arrived (eq 25 with the weights of eq 27 / equal / inverse), logs the estimate,
  predicts k+1, selects and broadcasts the task of k+1. Missing reports (late, lost, collided)
  are simply absent from the product of eq 25 and from the PCRLB information.
- any other role: a sensor. Its believed position is its own position fix (x, y from
  ``known_position()``, noise std = the group's ``sensors.position_noise_std_m``) and its depth
  gauge (z). With ``relocalize = true`` (default) it takes a fresh fix for every report, so the
  error of its believed position is white in time, as eq 4 models it (the node drifts with the
  water around its estimate); ``relocalize = false`` keeps the first fix for the whole run (a
  fixed bias, outside eq 10's model). It files every emission's pressure under the interval
  k = floor((rx_local - start_s) / interval_s) of its local clock (the network is assumed
  synchronized, as the paper's fixed sampling interval is), and when selected for k it
  quantizes the reading to L levels (eq 11), computes its predicted MI from the task's predicted
  position (``mi_samples`` draws from the Gaussian, its own stream; eqs 10, 19-23) and sends
  (step, level, MI, the believed position it used) to the FC in its TDMA slot (position in the
  task's list x ``slot_s``); the FC evaluates eq 25 at the reported positions.

``ideal_links = true`` reproduces the paper's instantaneous, lossless fusion: hello, task and
report exchanges bypass the acoustic channel (direct calls between the nodes of the same run,
no delay, no loss, no collision; the task then carries the FC's predicted particles themselves,
so each sensor's MI is eq 23 on exactly the FC's particles). Only the target's emissions still
travel through the channel, because that is where the sensors' pressure readings come from.
The FC's schedule is unchanged. All nodes of a run must use the same setting.

The model parameters (L, thresholds, S, k, r) are the FC's; the task carries them to the
sensors (a deployment-time configuration; not counted in ``task_bits``). The protocol never
reads ground truth: the metrics compare the ``mswpf_steps`` estimates with the ``positions``
table after the run.
"""

from __future__ import annotations

import math
import time
from collections.abc import Generator, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import pandas as pd
from pydantic import BaseModel, ConfigDict, Field

from aquasim_py.estimation import quantize
from aquasim_py.node import Node, Role
from aquasim_py.registry import register

from .math import MswpfConfig, MswpfTracker, sensor_mi, thresholds
from .metrics import interval_errors, mswpf_metrics

__all__ = ["MswpfNode"]

EMISSION = "mswpf_emission"
HELLO = "mswpf_hello"
TASK = "mswpf_task"
REPORT = "mswpf_report"


@dataclass
class _Task:
    step: int
    ids: tuple[int, ...]
    model: tuple[float, float, float, tuple[float, ...]]  # S, k, r, thresholds
    timing: tuple[float, float]  # start_s, interval_s: local time of emission 0, T
    particles: np.ndarray | None = None  # (N, 3) predicted positions (ideal links)
    mean: np.ndarray | None = None  # (3,) predicted position (acoustic links)
    cov: np.ndarray | None = None  # (3, 3)


@dataclass
class _Wire:
    """Ideal links of one run: direct calls between its sensors and fusion centre."""

    sensors: dict[int, Any] = field(default_factory=dict)
    fc: Any = None


@register
class MswpfNode(Node):
    """Target (emits), sensors (quantize and report) and fusion centre (MSWPF + PCRLB selection)."""

    name = "mswpf"
    trace_tables = ("mswpf_steps", "mswpf_timing", "nodes", "positions")  # what metrics / derived_tables / report read

    class Params(BaseModel):
        model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

        interval_s: float = Field(1.0, gt=0.0, description="sampling interval T (s)")
        start_s: float = Field(1.0, ge=0.0, description="local time of emission 0 (s)")
        steps: int = Field(80, ge=1, description="number of intervals tracked")
        ideal_links: bool = Field(False, description="FC: hello/task/report bypass the channel (paper's fusion)")
        fusion_center: int | None = Field(None, description="node id of the fusion centre (sensors)")
        # target
        emission_bits: int = Field(32, ge=1, description="length of one emission (bits of air time)")
        # sensors
        location_std_m: float | None = Field(
            None, ge=0.0, description="the sensor's stated fix accuracy r_x = r_y (m); None: its fix's spec"
        )
        relocalize: bool = Field(True, description="fresh position fix per report (eq 4's white error); false: one fix")
        hello_slot_s: float = Field(0.5, gt=0.0, description="hello TDMA slot per node id (s)")
        slot_s: float = Field(0.22, gt=0.0, description="report TDMA slot (s), from start + k T + slot0_s")
        slot0_s: float = Field(0.15, ge=0.0, description="offset of report slot 0 after emission k (s)")
        mi_samples: int = Field(1000, ge=10, description="draws from the task's predicted Gaussian for the MI")
        hello_bits: int = Field(96, ge=1)
        report_bits: int = Field(
            72, ge=1, description="step (8 bits), level (3), MI (16), believed x, y, z (15 each: 3 cm over 1 km)"
        )
        # fusion centre
        dim: Literal[2, 3] = Field(2, description="2: plane at known depth; 3: full 3-D")
        q: float = Field(1.0, ge=0.0, description="CV process noise density (m^2/s^3)")
        n_particles: int = Field(1000, ge=10)
        source_level: float = Field(5e4, gt=0.0, description="S of h = S / D^k")
        exponent: float = Field(2.0, gt=0.0, description="k of h = S / D^k (eq 6 prints the squared distance: 2)")
        noise_std: float = Field(5.0, gt=0.0, description="measurement noise std r")
        levels: int = Field(8, ge=2, description="quantization levels L")
        threshold_scheme: Literal["pressure", "distance"] = "pressure"
        near_m: float = Field(50.0, gt=0.0, description="distance of the top threshold span (m)")
        far_m: float = Field(160.0, gt=0.0, description="distance of the bottom threshold span (m)")
        weights: Literal["gw", "ew", "bw"] = "gw"
        n_select: int = Field(3, ge=1, description="Ns sensors per interval")
        sensing_range_m: float = Field(160.0, gt=0.0)
        target_depth_m: float = Field(50.0, ge=0.0, description="known target depth in 2-D (m)")
        x0: list[float] = Field(default_factory=lambda: [5.0, 5.0, 10.0, 10.0], description="prior mean [p, v]")
        p0_var: float = Field(10.0, gt=0.0, description="prior covariance P0 = p0_var I")
        fuse_delay_s: float = Field(1.3, gt=0.0, description="fusion of step k at start + k T + this (s)")
        select_ahead: Literal[1, 2] = Field(
            2, description="acoustic links: task of k + this sent after fusing k (ideal links: always 1)"
        )
        task_bits: int = Field(200, ge=1)

    # -- dispatch ---------------------------------------------------------------------------------

    def run(self) -> Generator[Any, Any, Any]:
        if self.role is Role.TARGET:
            yield from self._target()
        elif self.role is Role.SINK:
            yield from self._fusion_centre()
        else:
            yield from self._sensor()

    def _wire(self) -> _Wire:
        """The run's ideal links: one wire in the nodes' shared out-of-band store."""
        w = self.out_of_band.setdefault("mswpf_wire", _Wire())
        assert isinstance(w, _Wire)
        return w

    # -- target -----------------------------------------------------------------------------------

    def _target(self) -> Generator[Any, Any, Any]:
        p = self.params
        t = self.local_time()
        for k in range(p.steps):
            due = p.start_s + k * p.interval_s
            if due > t:
                yield self.sleep(due - t)
            yield self.broadcast(EMISSION, None, p.emission_bits)
            t = self.local_time()

    # -- sensor -----------------------------------------------------------------------------------

    def _sensor(self) -> Generator[Any, Any, Any]:
        p = self.params
        if p.fusion_center is None:
            raise ValueError(f"mswpf sensor {self.id}: params.fusion_center (the FC's node id) is required")
        self.believed = self._fix()
        self.location_std = p.location_std_m if p.location_std_m is not None else self.position_fix_std()
        self._readings: list[tuple[float, float]] = []  # (rx_local, pressure), the latest few
        self._tasks: dict[int, _Task] = {}
        self._done: set[int] = set()
        wire = self._wire()
        wire.sensors[self.id] = self
        yield self.sleep(0.0)  # every node's process has started: the FC has declared the link mode
        self.ideal = wire.fc is not None and bool(wire.fc.params.ideal_links)
        if not self.ideal:
            self.env.process(self._hello())
        kinds = (EMISSION,) if self.ideal else (EMISSION, TASK)
        while True:
            rec = yield self.recv(kinds=kinds)
            if rec.packet.kind == EMISSION:
                if math.isnan(rec.pressure):
                    continue
                self._readings.append((rec.rx_local, rec.pressure))
                del self._readings[:-8]
                for k in list(self._tasks):
                    self._try(k)
            else:
                self.on_task(rec.packet.payload)

    def _fix(self) -> np.ndarray:
        """Believed position: x, y of the own position fix, z of the depth gauge."""
        fix = self.known_position()
        return np.array([fix[0], fix[1], self.depth()])

    def _hello(self) -> Generator[Any, Any, Any]:
        p = self.params
        yield self.sleep(self.id * p.hello_slot_s)
        assert p.fusion_center is not None
        yield self.send(p.fusion_center, HELLO, (tuple(self.believed.tolist()), self.location_std), p.hello_bits)

    def on_task(self, task: _Task) -> None:
        """A task (over the channel or the ideal wire)."""
        if self.id not in task.ids:
            return
        self._tasks[task.step] = task
        self._tasks.pop(task.step - 8, None)
        self._try(task.step)

    def _reading(self, task: _Task) -> float | None:
        """The pressure of the emission heard in the task's interval (local clock bins)."""
        start, T = task.timing
        for rx, z in self._readings:
            if math.floor((rx - start) / T + 1e-9) == task.step:
                return z
        return None

    def _try(self, k: int) -> None:
        task = self._tasks.get(k)
        if task is None or k in self._done:
            return
        z = self._reading(task)
        if z is None:
            return
        self._done.add(k)
        self._tasks.pop(k, None)
        p = self.params
        S, kexp, r, gam = task.model
        level = int(quantize(z, gam))
        if p.relocalize:
            self.believed = self._fix()
        pos = tuple(self.believed.tolist())
        if task.particles is not None:
            targets = task.particles
        else:
            assert task.mean is not None and task.cov is not None
            targets = self.rng.multivariate_normal(task.mean, task.cov, size=p.mi_samples, method="eigh")
        mi = float(sensor_mi(targets, self.believed[None, :], [self.location_std], S, kexp, r, gam)[0])
        self.log("mswpf_reports", step=k, level=level, mi=mi, x=pos[0], y=pos[1], z=pos[2])
        if self.ideal:
            self._wire().fc.on_report(self.id, k, level, mi, pos)
        else:
            start, T = task.timing
            due = start + k * T + p.slot0_s + task.ids.index(self.id) * p.slot_s
            self.env.process(self._report(max(0.0, due - self.local_time()), (k, level, mi, pos)))

    def _report(self, wait: float, payload: tuple[int, int, float, tuple[float, ...]]) -> Generator[Any, Any, Any]:
        p = self.params
        if wait > 0.0:
            yield self.sleep(wait)
        assert p.fusion_center is not None
        yield self.send(p.fusion_center, REPORT, payload, p.report_bits)

    # -- fusion centre ----------------------------------------------------------------------------

    def on_report(self, sid: int, k: int, level: int, mi: float, pos: tuple[float, ...]) -> None:
        """A sensor's report of step k; its position is also the FC's latest belief of where the
        sensor is (for later selections)."""
        p = np.asarray(pos, dtype=float)
        self._reports.setdefault(k, {})[sid] = (level, mi, p)
        if sid in self._known:
            self._known[sid] = (p, self._known[sid][1])

    def _listen(self) -> Generator[Any, Any, Any]:
        while True:
            rec = yield self.recv(kinds=(HELLO, REPORT))
            src = rec.packet.src
            if rec.packet.kind == HELLO:
                pos, std = rec.packet.payload
                self._known[src] = (np.asarray(pos, dtype=float), float(std))
            else:
                k, level, mi, pos = rec.packet.payload
                self.on_report(src, int(k), int(level), float(mi), pos)

    def _fusion_centre(self) -> Generator[Any, Any, Any]:
        p = self.params
        n = 2 * p.dim
        if len(p.x0) != n:
            raise ValueError(f"mswpf fusion centre {self.id}: x0 needs {n} entries [p, v] for dim = {p.dim}")
        gam = thresholds(p.levels, p.source_level, p.exponent, p.near_m, p.far_m, p.threshold_scheme)
        cfg = MswpfConfig(
            dim=p.dim,
            q=p.q,
            T=p.interval_s,
            n_particles=p.n_particles,
            source_level=p.source_level,
            exponent=p.exponent,
            r=p.noise_std,
            gammas=tuple(gam.tolist()),
            weights=p.weights,
            n_select=p.n_select,
            sensing_range_m=p.sensing_range_m,
            target_depth_m=p.target_depth_m,
        )
        self._model = (p.source_level, p.exponent, p.noise_std, cfg.gammas)
        self._timing = (p.start_s, p.interval_s)
        tracker = MswpfTracker(cfg, p.x0, p.p0_var * np.eye(n), self.rng)
        self._known: dict[int, tuple[np.ndarray, float]] = {}
        self._reports: dict[int, dict[int, tuple[int, float, np.ndarray]]] = {}
        self._wire().fc = self  # declares the link mode to the sensors (see _sensor)
        wire = self._wire() if p.ideal_links else None
        if wire is None:
            self.env.process(self._listen())
        ahead = 1 if p.ideal_links else p.select_ahead
        # the tasks of steps 0 .. ahead-1 go out ahead intervals before their fusion
        first = p.start_s + p.fuse_delay_s - ahead * p.interval_s
        t = self.local_time()
        if first > t:
            yield self.sleep(first - t)
        if wire is not None:
            for sid, s in sorted(wire.sensors.items()):
                self._known[sid] = (s.believed, s.location_std)
        plan = {0: self._select_and_task(tracker, 0, wire, tracker.predicted, tracker.J_prior)}
        yield from self._send_task(plan[0][2])
        if ahead == 2 and p.steps > 1:
            X1, J1 = tracker.lookahead(plan[0][1])
            plan[1] = self._select_and_task(tracker, 1, wire, X1, J1)
            yield from self._send_task(plan[1][2])
        for k in range(p.steps):
            due = p.start_s + k * p.interval_s + p.fuse_delay_s
            t = self.local_time()
            if due > t:
                yield self.sleep(due - t)
            started = time.perf_counter()
            selected, infos, _ = plan.pop(k)
            got = self._reports.pop(k, {})
            ids = [s for s in selected if s in got]
            rows = [selected.index(s) for s in ids]
            pos = np.array([got[s][2] for s in ids]).reshape(-1, 3)
            std = np.array([self._known[s][1] for s in ids])
            levels = np.array([got[s][0] for s in ids], dtype=np.int64)
            mi = np.array([got[s][1] for s in ids])
            alpha, mean, cov = tracker.update(pos, std, levels, mi, infos[rows] if ids else None)
            step_s = time.perf_counter() - started
            self._log_step(tracker, k, selected, ids, alpha, mi, mean, cov)
            nxt = k + ahead
            select_s = math.nan
            if nxt < p.steps:
                started = time.perf_counter()
                if ahead == 1:
                    X, J = tracker.predicted, tracker.J_prior
                else:
                    X, J = tracker.lookahead(plan[k + 1][1])
                plan[nxt] = self._select_and_task(tracker, nxt, wire, X, J)
                select_s = time.perf_counter() - started
                yield from self._send_task(plan[nxt][2])
            # wall time: not deterministic, so in its own table (kept out of the written traces)
            self.log("mswpf_timing", step=k, step_ms=1e3 * step_s, select_ms=1e3 * select_s)

    def _select_and_task(
        self, tracker: MswpfTracker, k: int, wire: _Wire | None, X: np.ndarray, J: np.ndarray
    ) -> tuple[list[int], np.ndarray, _Task | None]:
        """Select the sensors of step k from its predicted particles X / prior information J;
        with ideal links hand them the task, else return it for :meth:`_send_task`."""
        ids_all = sorted(self._known)
        if not ids_all:
            return [], np.zeros((0, tracker.model.n, tracker.model.n)), None
        pos = np.array([self._known[s][0] for s in ids_all])
        std = np.array([self._known[s][1] for s in ids_all])
        idx, infos = tracker.select(pos, std, X, J)
        selected = [ids_all[i] for i in idx.tolist()]
        P = tracker.positions(X)
        if wire is not None:
            task = _Task(k, tuple(selected), self._model, self._timing, particles=P)
            for sid in selected:
                wire.sensors[sid].on_task(task)
            return selected, infos, None
        mean = P.mean(axis=0)
        D = P - mean
        task = _Task(k, tuple(selected), self._model, self._timing, mean=mean, cov=D.T @ D / len(P))
        return selected, infos, task

    def _send_task(self, task: _Task | None) -> Generator[Any, Any, None]:
        """Broadcast a step's task (link mode), waiting until its last bit has left."""
        if task is not None:
            yield self.broadcast(TASK, task, self.params.task_bits)

    def _log_step(
        self,
        tracker: MswpfTracker,
        k: int,
        selected: list[int],
        ids: list[int],
        alpha: np.ndarray,
        mi: np.ndarray,
        mean: np.ndarray,
        cov: np.ndarray,
    ) -> None:
        p = self.params
        d = p.dim
        pos = np.array([mean[0], mean[1], mean[2] if d == 3 else p.target_depth_m])
        vel = np.array([mean[d], mean[d + 1], mean[d + 2] if d == 3 else 0.0])
        t_step = p.start_s + k * p.interval_s
        # the FC's belief now: the step-k estimate carried to the logging instant (CV)
        now = pos + vel * (self.local_time() - t_step)
        self.log_estimate(now[0], now[1], now[2], step=k)
        try:
            Jinv = np.linalg.inv(tracker.J_post)
            pcrlb = float(np.trace(Jinv[:d, :d]))
        except np.linalg.LinAlgError:
            pcrlb = math.nan
        self.log(
            "mswpf_steps",
            step=k,
            t_step=t_step,
            x=float(pos[0]),
            y=float(pos[1]),
            z=float(pos[2]),
            var_pos=float(np.trace(cov[:d, :d])),
            pcrlb_m2=pcrlb,
            n_selected=len(selected),
            n_reports=len(ids),
            selected=" ".join(map(str, selected)),
            reported=" ".join(map(str, ids)),
            weights=" ".join(f"{a:.4g}" for a in alpha),
            mi=" ".join(f"{m:.4g}" for m in mi),
        )

    @classmethod
    def metrics(cls, tables: Mapping[str, pd.DataFrame]) -> dict[str, float]:
        return mswpf_metrics(tables)

    @classmethod
    def interval_metrics(cls, tables: Mapping[str, pd.DataFrame]) -> dict[str, float]:
        """Each interval's position error of the fused estimate (m), ``step_error_m[k]`` for
        step k: the per-run series whose RMS over runs eq 37 averages over time (kept out of
        :meth:`metrics`, one number per interval; read by ``aquasim-py reproduce mswpf``)."""
        return interval_errors(tables)
