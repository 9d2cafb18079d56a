"""Shared Req/Res machinery of ITMTL and its baselines (not a protocol by itself).

The exchange of the paper, one SimPy process per role (both wait on the node's modem, each
for its own packet kind: ``recv(kinds=...)``):

- :meth:`ReqResNode.responder`, on every node, answers while the node is a reference (buoys,
  anchors, promoted ordinary nodes): a ``sync_req`` received at local ``T`` is answered
  (:meth:`ReqResNode.reply`, a process per answer) in the reply slot the requester assigned
  to it with a ``sync_res`` to its sender carrying ``t2`` (receive stamp, reference time), the
  reference's clock model (so that the frame's MAC transmit stamp gives ``t3`` in reference
  time), position, velocity, confidence and whether it is a buoy / anchor;
- :meth:`ReqResNode.requester`, on ordinary nodes: every ``round_period_s`` (local, plus a
  per-round uniform jitter) :meth:`~ReqResNode.request` broadcasts ``sync_req``,
  :meth:`~ReqResNode.collect` takes the answers until the last slot can have arrived, the
  references that did not answer are asked once more (one retry), and
  :meth:`~ReqResNode.close_round` hands the round to :meth:`ReqResNode.process_round`;
- TSHL's one-way beacons are the ``sync_res`` stamps themselves (``t3`` sent, ``T4`` received).

The reply MAC (``mac = "slots"``, added: the paper gives no MAC). The Req lists the
references the node heard in its last rounds, closest first (by their last round trip), and
gives each a slot index ``k``; a listed reference answers ``turnaround_s + k * slot`` after
it received the Req, with ``slot = Res duration + max_prop_delay_s + slot_guard_s``. Sorted
by round trip, consecutive answers arrive at least ``slot - 2 * (change of a delay since the
last round)`` apart, so they cannot overlap at the requester. Unlisted references (not heard
yet) pick one of ``contention_slots`` random slots after the listed ones; a Req marked closed
(the node already knows enough buoys / anchors: the hierarchy) gets no unlisted answers.
``mac = "random"`` is the former scheme (hold ``hold_min_s + U(0, hold_spread_s)``, fixed
``collect_window_s``, no retry), kept to measure what the slots change.

Buoys and anchors keep true time and know their position (GPS / surveyed deployment); a
promoted node answers with its synchronized time and its estimated position.
Every node of a run must use one of these protocols (the packet kinds are shared, so
references of any of them answer any of them).
"""

from __future__ import annotations

from collections.abc import Generator, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal

import numpy as np
import pandas as pd
from pydantic import BaseModel, ConfigDict, Field

from aquasim_py.channel.ssp import Constant, Isogradient, Layered, SoundSpeedProfile
from aquasim_py.node import Node, Role, SensorUnavailable
from aquasim_py.packet import Reception

from . import metrics as itmtl_metrics

REQ = "sync_req"
RES = "sync_res"
REFERENCE_ROLES = (Role.BUOY, Role.ANCHOR)


class ReqResParams(BaseModel):
    """Parameters shared by ITMTL and the baselines (times in local seconds)."""

    model_config = ConfigDict(extra="forbid")

    round_period_s: float = Field(30.0, gt=0, description="time between an ordinary node's Req broadcasts (s)")
    first_round_s: float = Field(10.0, ge=0, description="first Req at a uniform random time in [0, this) (s)")
    round_jitter_s: float = Field(
        10.0, ge=0, description="each round starts round_period_s + U(-this/2, this/2) after the last (s)"
    )
    mac: Literal["slots", "random"] = Field("slots", description="reply MAC: assigned slots + retry, or random holds")
    bitrate_bps: float = Field(5000.0, gt=0, description="the modem's bit rate, for frame durations (bit/s)")
    max_prop_delay_s: float = Field(0.85, gt=0, description="longest one-way delay within modem range (s)")
    slot_guard_s: float = Field(0.05, ge=0, description="guard time added to each reply slot (s)")
    turnaround_s: float = Field(0.15, ge=0, description="a reference's delay before its first slot (s)")
    contention_slots: int = Field(4, ge=0, description="random slots for references the Req does not list")
    retry: bool = Field(True, description="ask once more the listed references that did not answer")
    forget_rounds: int = Field(2, ge=1, description="a reference silent this many rounds in a row is not listed")
    collect_window_s: float = Field(5.0, gt=0, description="mac = random: how long answers are collected (s)")
    hold_min_s: float = Field(0.15, ge=0, description="mac = random: minimum delay before answering (s)")
    hold_spread_s: float = Field(2.0, ge=0, description="mac = random: plus a uniform random delay up to this (s)")
    req_bits: int = Field(96, ge=1, description="Req frame size (bits)")
    res_bits: int = Field(224, ge=1, description="Res frame size (bits)")
    min_refs: int = Field(3, ge=1, description="answers needed to localize (3 at known depth)")
    mean_speed_mps: float = Field(1500.0, gt=0, description="sound speed of straight-line models (m/s)")
    ssp_depths_m: list[float] = Field(default_factory=list, description="depths of the node's sound-speed profile (m)")
    ssp_speeds_mps: list[float] = Field(default_factory=list, description="speeds at those depths (m/s)")
    velocity_sensor_std_mps: float = Field(
        0.02, ge=0, description="assumed std of a velocity sensor reading, per axis (m/s)"
    )
    stamp_std_s: float = Field(2e-5, gt=0, description="assumed MAC timestamp precision (s)")


@dataclass
class Answer:
    """One reference's answer to this node's Req."""

    ref: int
    T1: float  #: local Req send stamp
    t2: float  #: reference's receive stamp (reference time)
    t3: float  #: reference's send stamp
    T4: float  #: local receive stamp
    pos: np.ndarray  #: reference position at t2 (m)
    vel: np.ndarray  #: reference velocity (m/s)
    conf: float  #: reference confidence (1 for buoys / anchors)
    pos_std: float = 0.0  #: announced position std (m)
    vel_std: float = 0.0  #: announced velocity std per axis (m/s)
    time_std: float = 0.0  #: announced reference-time std (s)
    anchor: bool = True  #: a buoy / anchor (true time, known position), not a promoted node


@dataclass
class Round:
    index: int
    T1: float
    answers: list[Answer] = field(default_factory=list)
    asked: list[int] = field(default_factory=list)  #: references given a slot (first Req)
    open: bool = True  #: the first Req had open slots (not closed by the hierarchy)
    T1s: list[float] = field(default_factory=list)  #: local send stamps of the Req and its retry
    retried: bool = False


class ReqResNode(Node):
    """Base of ITMTL, TSHL, MU-Sync and Mobi-Sync nodes (see module docstring)."""

    name: ClassVar[str] = "_reqres"
    trace_tables = (
        "nodes",
        "clocks",
        "estimates",
        "packets",
        "reqres_rounds",
        "reqres_replies",
        "positions",
    )  # what metrics / derived_tables / report / paper_comparison / the bounds read
    Params = ReqResParams

    # -- state ----------------------------------------------------------------------------------

    def setup(self) -> None:
        self.is_reference = self.role in REFERENCE_ROLES
        self.is_anchor = self.is_reference
        self.confidence = 1.0 if self.is_reference else 0.0
        self.round_index = 0
        self.alpha = 1.0  # this node's estimate of its clock: local = alpha t + beta
        self.beta = 0.0
        self.synced = self.is_reference
        # references heard: id -> (last round, last round trip S in local s, buoy / anchor)
        self._known: dict[int, tuple[int, float, bool]] = {}

    # -- what a reference tells others ------------------------------------------------------------

    def own_position(self) -> np.ndarray:
        """Position a buoy / anchor knows: its GPS / survey fix (``Node.known_position()``)."""
        return np.asarray(self.known_position(), dtype=float).reshape(3)

    def profile(self) -> SoundSpeedProfile:
        """The sound-speed profile the node believes (a CTD cast): ``ssp_depths_m`` /
        ``ssp_speeds_mps`` (two points = isogradient, more = layered), else the mean speed."""
        p = self.params
        if not p.ssp_depths_m:
            return Constant(p.mean_speed_mps)
        z = np.asarray(p.ssp_depths_m, float)
        c = np.asarray(p.ssp_speeds_mps, float)
        if z.size == 2:
            g = (c[1] - c[0]) / (z[1] - z[0])
            return Isogradient(c[0] - g * z[0], g)
        return Layered(z, c)

    def own_velocity(self) -> np.ndarray:
        """Velocity sensor reading where the node has one, else zero."""
        try:
            return np.asarray(self.velocity(), dtype=float)
        except SensorUnavailable:
            return np.zeros(3)

    def ref_time(self, local: float) -> float:
        """Reference time of a local stamp: true time for anchors, synchronized otherwise."""
        return (local - self.beta) / self.alpha

    def estimated_position_at(self, t: float) -> np.ndarray:
        """This node's position estimate extrapolated to (its estimate of) true time ``t``."""
        raise NotImplementedError

    def estimated_velocity(self) -> np.ndarray:
        return np.zeros(3)

    # uncertainties a reference announces with its answer (buoys / anchors: sensor grade)
    def position_std(self) -> float:
        """Std of the announced position (m)."""
        return 0.0

    def velocity_std(self) -> float:
        """Std of the announced velocity, per axis (m/s)."""
        return self.params.velocity_sensor_std_mps

    def time_std(self, t: float) -> float:
        """Std of the announced reference time at ``t`` (s)."""
        return 0.0

    # -- main loop --------------------------------------------------------------------------------

    def slot_s(self) -> float:
        """Reply slot length (s): Res duration + longest one-way delay + guard."""
        p = self.params
        return p.res_bits / p.bitrate_bps + p.max_prop_delay_s + p.slot_guard_s

    def _slot_plan(self, rnd_index: int) -> tuple[list[int], int]:
        """References to list in the next Req (closest first) and the number of open slots.

        The hierarchy: when the node heard at least ``min_refs`` buoys / anchors in its last
        rounds it lists only those and closes the Req to everyone else."""
        p = self.params
        fresh = {j: k for j, k in self._known.items() if rnd_index - k[0] <= p.forget_rounds}
        self._known = fresh
        anchors = [j for j, k in fresh.items() if k[2]]
        if len(anchors) >= p.min_refs:
            return sorted(anchors, key=lambda j: (fresh[j][1], j)), 0
        return sorted(fresh, key=lambda j: (fresh[j][1], j)), p.contention_slots

    def _send_req(
        self, rnd_index: int, listed: list[int], n_open: int, attempt: int = 0
    ) -> Generator[Any, Any, tuple[float, float]]:
        """Broadcast a Req; returns (local send stamp, local end of its collection window)."""
        p = self.params
        if p.mac == "random":
            T1 = yield self.broadcast(REQ, {"round": rnd_index, "try": attempt}, p.req_bits)
            return float(T1), float(T1) + p.collect_window_s
        slot = self.slot_s()
        payload = {
            "round": rnd_index,
            "try": attempt,
            "slots": tuple(listed),
            "open": n_open,
            "slot_s": slot,
            "turn_s": p.turnaround_s,
        }
        # 8 bits per listed reference id
        T1 = yield self.broadcast(REQ, payload, p.req_bits + 8 * len(listed))
        last = p.turnaround_s + (len(listed) + n_open) * slot + 2.0 * p.max_prop_delay_s
        return float(T1), float(T1) + last

    # -- the exchange: one process per role -------------------------------------------------------

    def run(self) -> Generator[Any, Any, None]:
        """Every node answers Reqs while it is a reference (:meth:`responder`, its own process);
        an ordinary node also runs rounds (:meth:`requester`). Buoys and anchors never ask."""
        p = self.params
        # Every node draws its first Req time, references too (they never use it): the draws
        # that follow (slot choices, round jitter) then sit at the same places of a node's
        # stream whatever its role.
        first = self.local_time() + (float(self.rng.uniform(0.0, p.first_round_s)) if p.first_round_s > 0 else 0.0)
        self.env.process(self.responder())
        if not self.is_reference:
            yield from self.requester(first)

    # reference side

    def responder(self) -> Generator[Any, Any, None]:
        """Answer each Req heard while a reference, in the slot the requester assigned."""
        while True:
            rec = yield self.recv(kinds=REQ)
            if not self.answers_requests():
                continue
            pl = rec.packet.payload
            hold = self.reply_hold(pl)
            if hold is None:
                continue  # closed Req: the requester has enough buoys / anchors
            self.log("reqres_replies", requester=rec.packet.src, round=pl["round"], hold_s=hold)
            self.env.process(self.reply(rec.packet.src, pl, rec.rx_local, hold))

    def reply_hold(self, req: Mapping[str, Any]) -> float | None:
        """Local seconds from a Req's reception to the Res (None: this reference may not
        answer). ``mac = "slots"``: the listed slot, else a random open slot; ``"random"``:
        a random hold."""
        p = self.params
        if "slots" not in req:
            return p.hold_min_s + float(self.rng.uniform(0.0, p.hold_spread_s))
        if self.id in req["slots"]:
            k = req["slots"].index(self.id)
        elif req["open"] > 0:
            k = len(req["slots"]) + int(self.rng.integers(req["open"]))
        else:
            return None
        return float(req["turn_s"] + k * req["slot_s"])

    def reply(self, dst: int, req: Mapping[str, Any], T2_local: float, hold: float) -> Generator[Any, Any, None]:
        """Send the Res ``hold`` local seconds after the Req's receive stamp ``T2_local``: ``t2``
        (reference time), the clock model that turns the frame's MAC transmit stamp into ``t3``,
        position and velocity at ``t2``, confidence and the announced uncertainties."""
        yield self.sleep(max(0.0, T2_local + hold - self.local_time()))
        t2 = self.ref_time(T2_local)
        if self.is_anchor:
            pos = self.own_position()
            vel = self.own_velocity()
        else:
            pos = self.estimated_position_at(t2)
            vel = self.estimated_velocity()
        # t3 is the frame's own MAC transmit stamp (``Packet.tx_local``, set by the modem as
        # the first bit leaves); the frame carries the clock model that turns it into
        # reference time (identity for buoys and anchors).
        payload = {
            "round": req["round"],
            "try": req["try"],
            "t2": t2,
            "clock": (self.alpha, self.beta),
            "pos": tuple(map(float, pos)),
            "vel": tuple(map(float, vel)),
            "conf": float(self.confidence),
            "pos_std": self.position_std(),
            "vel_std": self.velocity_std(),
            "time_std": self.time_std(t2),
            "anchor": bool(self.is_anchor),
        }
        yield self.send(dst, RES, payload, self.params.res_bits)

    def answers_requests(self) -> bool:
        return self.is_reference

    # ordinary side

    def requester(self, first: float) -> Generator[Any, Any, None]:
        """Rounds from local time ``first``: wait for the round's start, broadcast the Req,
        collect the answers, ask the silent references once more, then hand the round to
        :meth:`process_round`."""
        p = self.params
        next_round = first
        while True:
            yield from self.idle_until(next_round)
            self.round_index += 1
            rnd, collect_end = yield from self.request(self.round_index)
            jitter = float(self.rng.uniform(-0.5, 0.5)) * p.round_jitter_s if p.round_jitter_s > 0 else 0.0
            next_round = rnd.T1 + p.round_period_s + jitter
            yield from self.collect(rnd, collect_end)
            retry = self.retry_plan(rnd)
            if retry is not None:
                rnd.retried = True
                T1r, collect_end = yield from self._send_req(rnd.index, *retry, attempt=1)
                rnd.T1s.append(T1r)
                yield from self.collect(rnd, collect_end)
            self.close_round(rnd)

    def idle_until(self, local: float) -> Generator[Any, Any, None]:
        """Wait until local time ``local``; answers that come outside a round are dropped."""
        while (now := self.local_time()) < local:
            if (yield self.recv(timeout=local - now, kinds=RES)) is None:
                return

    def request(self, index: int) -> Generator[Any, Any, tuple[Round, float]]:
        """Broadcast round ``index``'s Req to the references heard lately (closest first);
        returns the round and the local end of its collection window."""
        listed, n_open = self._slot_plan(index)
        T1, collect_end = yield from self._send_req(index, listed, n_open)
        return Round(index, T1, asked=listed, open=n_open > 0, T1s=[T1]), collect_end

    def collect(self, rnd: Round, until: float) -> Generator[Any, Any, None]:
        """Take the answers to ``rnd`` until local time ``until``."""
        while (now := self.local_time()) < until:
            rec = yield self.recv(timeout=until - now, kinds=RES)
            if rec is None:
                return
            self.take_answer(rnd, rec)

    def take_answer(self, rnd: Round, rec: Reception) -> None:
        """Record a Res to this round's Req (or its retry), one per reference."""
        pkt = rec.packet
        pl = pkt.payload
        if pkt.dst != self.id or pl["round"] != rnd.index or any(a.ref == pkt.src for a in rnd.answers):
            return  # another round's, or a late first answer after the retry asked again: keep one
        a_ref, b_ref = pl["clock"]
        rnd.answers.append(
            Answer(
                pkt.src,
                rnd.T1s[pl["try"]],
                pl["t2"],
                (pkt.tx_local - b_ref) / a_ref,
                rec.rx_local,
                np.asarray(pl["pos"], float),
                np.asarray(pl["vel"], float),
                float(pl["conf"]),
                float(pl["pos_std"]),
                float(pl["vel_std"]),
                float(pl["time_std"]),
                bool(pl["anchor"]),
            )
        )

    def retry_plan(self, rnd: Round) -> tuple[list[int], int] | None:
        """The one retry (``mac = "slots"``): the listed references that did not answer, plus
        open slots if the round is still short and was not closed by the hierarchy; None when
        there is nothing to ask (or the round was retried already)."""
        p = self.params
        if p.mac != "slots" or not p.retry or rnd.retried:
            return None
        got = {a.ref for a in rnd.answers}
        missing = [j for j in rnd.asked if j not in got]
        n_open = p.contention_slots if len(rnd.answers) < p.min_refs and rnd.open else 0
        return (missing, n_open) if missing or n_open else None

    def close_round(self, rnd: Round) -> None:
        """Remember who answered (and their round trips, for the next slot plan), log the
        round and hand it to :meth:`process_round`."""
        p = self.params
        for a in rnd.answers:
            self._known[a.ref] = (rnd.index, (a.T4 - a.T1) - (a.t3 - a.t2), a.anchor)
        self.log(
            "reqres_rounds",
            round=rnd.index,
            answers=len(rnd.answers),
            anchors=sum(a.anchor for a in rnd.answers),
            asked=len(rnd.asked),
            retried=rnd.retried,
            needed=p.min_refs,
        )
        self.process_round(rnd)

    # -- subclasses -------------------------------------------------------------------------------

    def process_round(self, rnd: Round) -> None:
        raise NotImplementedError

    # -- metrics ----------------------------------------------------------------------------------

    @classmethod
    def metrics(cls, tables: Mapping[str, pd.DataFrame]) -> dict[str, float]:
        return {**itmtl_metrics.protocol_metrics(tables, cls.name), **itmtl_metrics.mac_metrics(tables, cls.name)}

    #: What the ITMTL paper reports for this protocol, quantity -> claim, listed by
    #: the report of a single run (the variants runner prints them with our values: paper.py).
    paper: ClassVar[dict[str, str]] = {}

    @classmethod
    def derived_tables(cls, tables: Mapping[str, pd.DataFrame]) -> dict[str, pd.DataFrame]:
        """The per-round table the report prints, as ``<protocol>_rounds`` (one row per round)."""
        pr = itmtl_metrics.per_round(tables, cls.name)
        return {f"{cls.name}_rounds": pr.reset_index()} if len(pr) else {}

    @classmethod
    def report(cls, tables: Mapping[str, pd.DataFrame]) -> str:
        m = itmtl_metrics.mac_metrics(tables, cls.name)
        lines = [
            itmtl_metrics.round_table(tables, cls.name),
            f"{cls.name}: Res frames lost to collisions {m['res_collision_fraction']:.3f}, rounds short of "
            f"answers by the MAC {m['short_round_fraction']:.3f} (for any reason {m['short_round_fraction_all']:.3f}), "
            f"rounds retried {m['retry_fraction']:.3f}",
        ]
        if cls.paper:
            lines.append(
                f"{cls.name} in the ITMTL paper (Gao et al.; our values of these statistics: run every variant, paper.csv):"
            )
            lines += [f"  {k}: {v}" for k, v in cls.paper.items()]
        return "\n".join(lines)
