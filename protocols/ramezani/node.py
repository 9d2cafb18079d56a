"""Ramezani et al. (IEEE TSP 2013): ToF localization (GNA-ESSP / GNA-ASSP, Algorithm 1) and
tracking (EKF-ESSP / EKF-ASSP, Algorithm 2) in an isogradient sound-speed profile, as one
network protocol ``ramezani``.

One registered protocol; the behaviour is chosen by parameters:

- ``mode = "localization"``: a fresh Gauss-Newton fix per frame (eq 29, Algorithm 1 with
  K = ``max_iter``, eps = ``tol_m``, started at the anchors' centroid; optional depth row, eq 37);
- ``mode = "tracking"``: an EKF on s = [x, xdot] with Phi, Q of Section V (eq 38), ToF rows
  every frame and a depth row every ``rho`` frames (eqs 39-40);
- ``model = "essp"``: the exact isogradient ray model (eqs 13, 15-18) with the node's own
  profile knowledge c(z) = ``surface_speed_mps`` + ``gradient_per_s`` z (which a scenario may
  set equal to or different from the environment's); with ``continue_above_surface`` (default)
  the closed form is also evaluated above the surface, so an iterate that strays there keeps a
  model value (as the paper's formulas do; the Levenberg-Marquardt fallback of
  :func:`aquasim_py.estimation.gauss_newton` stays in place either way); ``model = "assp"``: straight rays at
  v_bar = [C(max anchor depth) + C(min anchor depth)] / 2 with the same knowledge.

Network: the nodes are synchronized (the paper's assumption: give every group a perfect
clock). Anchors (role ``anchor``) broadcast a ``rz_ping`` in their TDMA slot of each frame,
``start_s + slot * slot_s + frame * frame_s`` local seconds, carrying their surveyed position
(``anchor_positions[slot]``, the anchor with node id ``anchor_ids[slot]``) and the frame number.
Any other role is a target: the ToF of a ping is its local arrival stamp minus the sender's
transmit stamp (exact through the channel's ray-traced delay), plus the paper's measurement
noise N(0, ``sigma_t_s``^2) drawn from the node's own random stream. A frame is processed when
all anchors were heard, or when a later frame starts / nothing arrives for a frame period.

The protocol never reads ground truth; the bounds are computed after the run in
:meth:`RamezaniNode.metrics` from the trace (true positions from the ``estimates`` truth columns
and the ``positions`` table), evaluated with the profile the node was configured with.
"""

from __future__ import annotations

import math
from collections.abc import Generator, Mapping
from typing import Annotated, Any, Literal

import annotated_types as at
import numpy as np
import pandas as pd
from pydantic import BaseModel, ConfigDict, Field, model_validator

from aquasim_py.estimation import EstimationError, ekf_update, gauss_newton, tof_model
from aquasim_py.metrics import positions_at
from aquasim_py.node import Node, Role
from aquasim_py.registry import register

from .math import TETRAHEDRON, fix_crb, paper_transition, pcrb_along, tof_functions

__all__ = ["RamezaniNode"]

Vec3 = Annotated[list[float], at.Len(3, 3)]  # not Field(...): see PosFloat in aquasim_py/scenario/ocean_schema.py
_ANCHOR_ROLES = (Role.ANCHOR, Role.BUOY)
_PING = "rz_ping"


@register
class RamezaniNode(Node):
    """Anchors ping in TDMA slots; targets localize (GNA) or track (EKF) from the ToFs."""

    name = "ramezani"
    trace_tables = ("estimates", "positions", "nodes")  # what metrics / derived_tables / report read

    class Params(BaseModel):
        model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

        mode: Literal["localization", "tracking"] = Field("localization", description="GN fix per frame, or EKF")
        model: Literal["essp", "assp"] = Field("essp", description="exact isogradient rays, or straight rays at v_bar")
        surface_speed_mps: float = Field(1480.0, gt=0.0, description="b of the node's c(z) = b + a z (m/s)")
        gradient_per_s: float = Field(0.1, description="a of the node's c(z) = b + a z (1/s)")
        anchor_positions: list[Vec3] = Field(
            default_factory=TETRAHEDRON.tolist,
            min_length=1,
            description="surveyed anchor positions (m), one per TDMA slot",
        )
        anchor_ids: list[int] | None = Field(None, description="node id of the anchor in each slot (default 0..N-1)")
        frame_s: float = Field(10.0, gt=0.0, description="frame period Ts (s)")
        slot_s: float = Field(0.25, gt=0.0, description="TDMA slot length (s)")
        start_s: float = Field(1.0, ge=0.0, description="local time of frame 0, slot 0 (s)")
        bits: int = Field(32, ge=1, description="ping length (bits)")
        sigma_t_s: float = Field(1e-3, gt=0.0, description="ToF measurement noise std, added and assumed (s)")
        use_depth: bool = Field(False, description="localization: add the depth gauge reading (eq 37)")
        sigma_z_m: float = Field(1.0, gt=0.0, description="depth gauge std the estimator assumes (m)")
        rho: int = Field(10, ge=0, description="tracking: depth report every rho-th frame (0: never)")
        q_xy_mps: float = Field(1e-2, gt=0.0, description="velocity process noise std per frame, x and y (m/s)")
        q_z_mps: float = Field(1e-3, gt=0.0, description="velocity process noise std per frame, z (m/s)")
        initial_guess: Vec3 | None = Field(None, description="tracking prior position (m); default the first GN fix")
        p0_pos_std_m: float = Field(30.0, gt=0.0, description="tracking prior position std per axis (m)")
        p0_vel_std_mps: float = Field(0.1, gt=0.0, description="tracking prior velocity std per axis (m/s)")
        continue_above_surface: bool = Field(
            True, description="essp: evaluate eq 13 also above the surface (an iterate may stray there)"
        )
        max_iter: int = Field(7, ge=1, description="Algorithm 1: K")
        tol_m: float = Field(1e-3, gt=0.0, description="Algorithm 1: eps (m)")
        min_anchors: int = Field(4, ge=1, description="fewest anchors heard in a frame to use it")
        rmse_from_step: int = Field(300, ge=1, description="tracking RMSE over steps K1..K: K1")

        @model_validator(mode="after")
        def _ids(self) -> RamezaniNode.Params:
            if self.anchor_ids is not None and len(self.anchor_ids) != len(self.anchor_positions):
                raise ValueError(
                    f"anchor_ids has {len(self.anchor_ids)} entries for {len(self.anchor_positions)} anchor_positions"
                )
            if self.slot_s * len(self.anchor_positions) > self.frame_s:
                raise ValueError("the anchors' slots do not fit in one frame (slot_s * N > frame_s)")
            return self

    # -- common ---------------------------------------------------------------------------------

    def setup(self) -> None:
        p = self.params
        ids = p.anchor_ids if p.anchor_ids is not None else list(range(len(p.anchor_positions)))
        self._ids = [int(i) for i in ids]
        self._n = len(ids)
        # target state: EKF posterior (tracking), last frame used, frame of the prior s_0
        self._state: tuple[np.ndarray, np.ndarray] | None = None
        self._last_frame = -1
        self._frame0 = 0

    def run(self) -> Generator[Any, Any, None]:
        if self.role in _ANCHOR_ROLES:
            yield from self._anchor()
        else:
            yield from self._target()

    # -- anchors --------------------------------------------------------------------------------

    def _anchor(self) -> Generator[Any, Any, None]:
        p = self.params
        if self.id not in self._ids:
            raise ValueError(f"ramezani: anchor node {self.id} is not in anchor_ids {self._ids}")
        slot = self._ids.index(self.id)
        pos = [float(v) for v in p.anchor_positions[slot]]
        frame = 0
        while True:
            due = p.start_s + slot * p.slot_s + frame * p.frame_s
            yield self.sleep(max(0.0, due - self.local_time()))
            yield self.broadcast(_PING, {"slot": slot, "frame": frame, "position": pos}, bits=p.bits)
            frame += 1

    # -- targets --------------------------------------------------------------------------------

    def _target(self) -> Generator[Any, Any, None]:
        p = self.params
        pending: dict[int, dict[int, tuple[float, list[float], int]]] = {}
        while True:
            rec = yield self.recv(timeout=p.frame_s, kinds=_PING)
            if rec is None:
                for f in sorted(pending):
                    self._process(f, pending.pop(f))
                continue
            pl = rec.packet.payload
            f = int(pl["frame"])
            # synchronized clocks: the one-way delay from the two MAC stamps, plus the paper's
            # measurement noise (eq 27) from this node's own stream
            tof = rec.rx_local - rec.packet.tx_local + p.sigma_t_s * float(self.rng.standard_normal())
            pending.setdefault(f, {})[int(pl["slot"])] = (tof, list(pl["position"]), rec.packet.src)
            for g in sorted(pending):
                if g < f or len(pending[g]) == self._n:
                    self._process(g, pending.pop(g))

    def _process(self, frame: int, got: dict[int, tuple[float, list[float], int]]) -> None:
        p = self.params
        if len(got) < p.min_anchors or frame <= self._last_frame:
            return
        slots = sorted(got)
        tofs = np.array([got[s][0] for s in slots])
        anchors = np.array([got[s][1] for s in slots], dtype=float)
        srcs = " ".join(str(got[s][2]) for s in slots)
        time_fn, grad_fn = tof_functions(
            p.model, p.surface_speed_mps, p.gradient_per_s, anchors, continued=p.continue_above_surface
        )
        common = dict(
            mode=p.mode,
            model=p.model,
            frame=frame,
            n_anchors=len(slots),
            anchor_nodes=srcs,
            sigma_t=p.sigma_t_s,
            b=p.surface_speed_mps,
            a=p.gradient_per_s,
        )
        if p.mode == "localization":
            depth = self.depth() if p.use_depth else None
            fun = tof_model(
                anchors,
                tofs,
                time_fn,
                grad_fn,
                sigma=p.sigma_t_s,
                depth=depth,
                sigma_depth=p.sigma_z_m if p.use_depth else None,
            )
            try:
                fix = gauss_newton(fun, anchors.mean(axis=0), p.max_iter, p.tol_m)
            except EstimationError as exc:
                self.log("ramezani_failures", frame=frame, reason=str(exc))
                return
            self._last_frame = frame
            self.log_estimate(
                *fix.x,
                confidence=math.sqrt(float(np.trace(fix.cov))),
                step=frame,
                sigma_z=p.sigma_z_m if p.use_depth else math.nan,
                depth_used=bool(p.use_depth),
                iterations=fix.iterations,
                method=fix.method,
                **common,
            )
            return
        res = self._track(frame, anchors, tofs, time_fn, grad_fn)
        if res is not None:
            x, P, step, used_depth = res
            self.log_estimate(
                *x[:3],
                confidence=math.sqrt(float(np.trace(P[:3, :3]))),
                step=step,
                sigma_z=p.sigma_z_m,
                depth_used=used_depth,
                rho=p.rho,
                frame_s=p.frame_s,
                q_xy=p.q_xy_mps,
                q_z=p.q_z_mps,
                p0_pos_std=p.p0_pos_std_m,
                p0_vel_std=p.p0_vel_std_mps,
                k1=p.rmse_from_step,
                **common,
            )

    def _track(
        self, frame: int, anchors: np.ndarray, tofs: np.ndarray, time_fn: Any, grad_fn: Any
    ) -> tuple[np.ndarray, np.ndarray, int, bool] | None:
        """Algorithm 2 for one frame; the first frame sets the prior s_0."""
        p = self.params
        P0 = np.diag([p.p0_pos_std_m**2] * 3 + [p.p0_vel_std_mps**2] * 3)
        if self._state is None:
            if p.initial_guess is not None:
                # the operator's prior stands for the frame before this one: this is step 1
                self._state = (np.r_[np.asarray(p.initial_guess, float), np.zeros(3)], P0)
                self._frame0 = frame - 1
            else:
                fun = tof_model(anchors, tofs, time_fn, grad_fn, sigma=p.sigma_t_s)
                try:
                    fix = gauss_newton(fun, anchors.mean(axis=0), p.max_iter, p.tol_m)
                except EstimationError as exc:
                    self.log("ramezani_failures", frame=frame, reason=str(exc))
                    return None
                self._state = (np.r_[fix.x, np.zeros(3)], P0)
                self._frame0 = self._last_frame = frame
                return None
            self._last_frame = self._frame0
        x, P = self._state
        Phi, Q = paper_transition(p.frame_s, p.q_xy_mps, p.q_z_mps)
        for _ in range(frame - self._last_frame):  # frames without pings: predict only
            x, P = Phi @ x, Phi @ P @ Phi.T + Q
        step = frame - self._frame0
        use_depth = p.rho > 0 and step % p.rho == 0
        z = tofs
        r = [p.sigma_t_s**2] * len(tofs)
        if use_depth:
            z = np.r_[tofs, self.depth()]
            r.append(p.sigma_z_m**2)

        def eval_at(s: np.ndarray) -> np.ndarray:
            if p.continue_above_surface:
                return s[:3]
            # a prediction above the surface has no ray: linearize at the surface instead
            return np.array([s[0], s[1], max(float(s[2]), 0.0)])

        def h(s: np.ndarray) -> np.ndarray:
            t = time_fn(anchors, eval_at(s)[None, :])
            return np.r_[t, s[2]] if use_depth else t

        def H_jac(s: np.ndarray) -> np.ndarray:
            H = np.zeros((len(r), 6))
            H[: len(tofs), :3] = grad_fn(anchors, eval_at(s)[None, :])
            if use_depth:
                H[-1, 2] = 1.0
            return H

        try:
            upd = ekf_update(x, P, z, h, H_jac, np.diag(r))
        except EstimationError as exc:
            self.log("ramezani_failures", frame=frame, reason=str(exc))
            return None
        self._state = (upd.x, upd.P)
        self._last_frame = frame
        return upd.x, upd.P, step, use_depth

    # -- after the run ----------------------------------------------------------------------------

    @classmethod
    def metrics(cls, tables: Mapping[str, pd.DataFrame]) -> dict[str, float]:
        """Per (mode, model): fixes, RMSE (m) and sqrt(mean CRB) (m, eqs 30-33 with eq 37 when
        a depth reading was used); tracking: RMSE and sqrt(mean PCRB) (eqs 41-42) over steps
        K1..K, the bound along the logged true positions with the anchors actually heard."""
        est = tables.get("estimates")
        out: dict[str, float] = {}
        if est is None or len(est) == 0 or "model" not in est.columns:
            return out
        est = est[est["protocol"].astype(str) == cls.name]
        for (mode, model), g in est.groupby(["mode", "model"], sort=True):
            key = f"{mode}_{model}"
            if mode == "localization":
                e2, bound = _localization_terms(g, tables)
            else:
                e2, bound = _tracking_terms(g, tables)
            out[f"{key}.estimates"] = int(e2.size)
            out[f"{key}.rmse_m"] = float(np.sqrt(np.mean(e2))) if e2.size else math.nan
            name = "sqrt_mean_crb_m" if mode == "localization" else "sqrt_mean_pcrb_m"
            out[f"{key}.{name}"] = float(np.sqrt(np.mean(bound))) if bound.size else math.nan
            out[f"{key}.rmse_over_bound"] = out[f"{key}.rmse_m"] / out[f"{key}.{name}"]
        return out


def _flag(v: Any) -> bool:
    """A boolean column value, also after a CSV round trip ("True" / "False" strings)."""
    return str(v).strip().lower() in ("true", "1", "1.0")


def _truth(g: pd.DataFrame) -> np.ndarray:
    return g[["true_x", "true_y", "true_z"]].to_numpy(float)


def _sq_err(g: pd.DataFrame) -> np.ndarray:
    return np.sum((g[["x", "y", "z"]].to_numpy(float) - _truth(g)) ** 2, axis=1)


def _anchor_truth(tables: Mapping[str, pd.DataFrame], nodes: list[int], t: float) -> np.ndarray:
    """True anchor positions (n, 3) at true time t, from the positions table."""
    return positions_at(tables["positions"], np.asarray(nodes), np.full(len(nodes), t))


def _localization_terms(g: pd.DataFrame, tables: Mapping[str, pd.DataFrame]) -> tuple[np.ndarray, np.ndarray]:
    bound = np.empty(len(g))
    for i, row in enumerate(g.itertuples(index=False)):  # one CRB per fix: a few hundred rows
        A = _anchor_truth(tables, [int(s) for s in str(row.anchor_nodes).split()], float(row.time))
        sz = float(row.sigma_z) if _flag(row.depth_used) else None
        bound[i] = float(fix_crb(A, [row.true_x, row.true_y, row.true_z], row.b, row.a, row.sigma_t, sz))
    return _sq_err(g), bound


def _tracking_terms(g: pd.DataFrame, tables: Mapping[str, pd.DataFrame]) -> tuple[np.ndarray, np.ndarray]:
    e2_all, b_all = [], []
    for _, h in g.groupby("node", sort=True):
        h = h.sort_values("step", kind="stable")
        r0 = h.iloc[0]
        steps = h["step"].to_numpy(int)
        K = int(steps.max())
        nodes = sorted({int(s) for v in h["anchor_nodes"] for s in str(v).split()})
        A = _anchor_truth(tables, nodes, float(h["time"].iloc[0]))
        X = np.zeros((K, 3))
        mask = np.zeros((K, len(nodes)), bool)  # steps without a row: no information
        depth = np.zeros(K, bool)
        X[steps - 1] = _truth(h)
        for k, v, d in zip(steps, h["anchor_nodes"], h["depth_used"]):
            mask[k - 1, [nodes.index(int(s)) for s in str(v).split()]] = True
            depth[k - 1] = _flag(d)
        X[~mask.any(axis=1)] = X[mask.any(axis=1)][0]  # any in-water point; masked out anyway
        Phi, Q = paper_transition(float(r0.frame_s), float(r0.q_xy), float(r0.q_z))
        P0 = np.diag([float(r0.p0_pos_std) ** 2] * 3 + [float(r0.p0_vel_std) ** 2] * 3)
        pc = pcrb_along(
            X,
            A,
            float(r0.b),
            float(r0.a),
            float(r0.sigma_t),
            P0,
            Phi,
            Q,
            sigma_z=float(r0.sigma_z),
            depth_steps=depth,
            mask=mask,
        )
        keep = steps >= int(r0.k1)
        e2_all.append(_sq_err(h)[keep])
        b_all.append(pc[steps[keep] - 1])
    return np.concatenate(e2_all), np.concatenate(b_all)
