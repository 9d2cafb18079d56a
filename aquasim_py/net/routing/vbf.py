"""``vbf``: vector-based forwarding (P. Xie, J.-H. Cui and L. Lao, "VBF: Vector-Based Forwarding
Protocol for Underwater Sensor Networks", IFIP Networking 2006, LNCS 3976, pp. 1216-1221;
journal version with HH-VBF: P. Xie, Z. Zhou, N. Nicolaou, A. See, J.-H. Cui and Z. Shi,
"Efficient Vector-Based Forwarding for Underwater Sensor Networks", EURASIP Journal on Wireless
Communications and Networking 2010, 195910).

Each packet carries the positions of its source S, its target T and the node F that sent this
copy, and the radius W of the *routing pipe*: the cylinder of radius W around the vector from
S to T. A node that hears a copy and lies within W of that axis is a candidate forwarder;
any other drops it. A candidate weighs how well placed it is by its *desirableness factor*

    alpha = p / W + (R - d cos(theta)) / R,

p its distance to the pipe's axis, d its distance to F, theta the angle between F->T and
F->node, R the transmission range (alpha is smaller for a node nearer the axis and further
along it), and holds the packet for

    T_adaptation = sqrt(alpha) T_delay + (R - d) / v0

(the second term evens out the propagation delay from F). Self-adaptation: if, while it holds
the packet, it hears copies from n other forwarders, it computes its desirableness factor
relative to each of them (d and theta from that forwarder); when the time is up it forwards
only if the smallest of the n + 1 factors is below alpha_c / 2^n, alpha_c the initial
threshold; otherwise it discards its copy. Its own copy carries its position as F.

Positions here are the nodes' position fixes (``sensors.position_fix``, with
``position_noise_std_m``; the paper's nodes measure the forwarder's relative position by angle
of arrival and signal strength, Aqua-Sim NG reads every node's true position); a sink announces
its fix at set-up, and a packet for any sink aims at the one nearest the source's fix.

Readings (documented switches): ``radius_m`` (W; default R), ``delay_max_s`` (T_delay) and
``alpha_c`` are the deployment's: their defaults, 1 s and 1.5, are Aqua-Sim NG's (``DELAY``,
``m_priority``). A node decides on its candidacy at the first copy it hears; later copies only
enter the self-adaptation (as in Aqua-Sim NG). The holding time is the paper's; Aqua-Sim NG's
(``sqrt(alpha) DELAY + 2 (d - R) / v0``) differs in the sign and factor of its second term.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from pydantic import Field

from .base import Datagram, Header, RangeParams, Router, RouterParams, RouterPort

__all__ = ["Vbf", "VbfHeader", "VbfParams", "desirableness", "pipe_distance"]

Point = tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class VbfHeader(Header):
    """VBF's header: the common fields, the positions (m) of the source, the target and the
    node sending this copy, and the pipe's radius W (m)."""

    source: Point = (math.nan, math.nan, math.nan)
    target: Point = (math.nan, math.nan, math.nan)
    forwarder: Point = (math.nan, math.nan, math.nan)
    radius: float = math.nan


class VbfParams(RangeParams):
    radius_m: float | None = Field(None, gt=0.0, description="W, the routing pipe's radius (m); default R")
    delay_max_s: float = Field(1.0, gt=0.0, le=3600.0, description="T_delay of the holding time (local s)")
    alpha_c: float = Field(1.5, gt=0.0, description="the initial desirableness threshold alpha_c")


def pipe_distance(node: Point, start: Point, target: Point) -> float:
    """p: the distance (m) from ``node`` to the axis through ``start`` and ``target`` (to
    ``start`` itself when they coincide)."""
    wx, wy, wz = target[0] - start[0], target[1] - start[1], target[2] - start[2]
    vx, vy, vz = node[0] - start[0], node[1] - start[1], node[2] - start[2]
    length = math.sqrt(wx * wx + wy * wy + wz * wz)
    if length == 0.0:
        return math.sqrt(vx * vx + vy * vy + vz * vz)
    cx, cy, cz = vy * wz - vz * wy, vz * wx - vx * wz, vx * wy - vy * wx
    return math.sqrt(cx * cx + cy * cy + cz * cz) / length


def desirableness(
    node: Point, forwarder: Point, target: Point, p: float, width: float, range_m: float
) -> tuple[float, float]:
    """(alpha, d): the desirableness factor p / W + (R - d cos(theta)) / R of ``node``
    relative to ``forwarder``, and d, its distance to it (m)."""
    dx, dy, dz = node[0] - forwarder[0], node[1] - forwarder[1], node[2] - forwarder[2]
    tx, ty, tz = target[0] - forwarder[0], target[1] - forwarder[1], target[2] - forwarder[2]
    d = math.sqrt(dx * dx + dy * dy + dz * dz)
    lt = math.sqrt(tx * tx + ty * ty + tz * tz)
    d_cos = (dx * tx + dy * ty + dz * tz) / lt if lt > 0.0 else 0.0  # d cos(theta)
    return p / width + (range_m - d_cos) / range_m, d


@dataclass(slots=True)
class _Held:
    """A copy this node holds: the first copy, and the forwarders it heard (the first's sender
    and every later one)."""

    datagram: Datagram
    prev: int
    forwarders: list[Point]


class Vbf(Router):
    """Vector-based forwarding (module docstring)."""

    name = "vbf"
    Params = VbfParams
    params: VbfParams
    needs_position = True
    header_fields_bits = 3 * 3 * 16 + 16  # three positions, the radius

    def __init__(self, port: RouterPort, params: RouterParams) -> None:
        super().__init__(port, params)
        self.R = self.range_m(self.params.range_m) if not self.is_sink else math.nan
        self.held: dict[tuple[int, int], _Held] = {}

    def sink_position(self) -> Point | None:
        return self.port.position()

    def pipe_start(self, header: VbfHeader, forwarder: Point) -> Point:
        """Where the pipe's axis starts: the source (VBF)."""
        return header.source

    # -- the source ------------------------------------------------------------------------------

    def originate(self, header: Header) -> Header:
        here = self.port.position()
        return VbfHeader(
            *header.common(),
            source=here,
            target=self._target(header.dst, here),
            forwarder=here,
            radius=self.params.radius_m if self.params.radius_m is not None else self.R,
        )

    def _target(self, dst: int, here: Point) -> Point:
        """The target's position: the addressed sink's fix, or the sink nearest ``here``."""
        sinks = {i: s.position for i, s in self._sinks.items() if s.position is not None}
        if dst in sinks:
            return sinks[dst]
        if dst in self._sinks or not sinks:
            raise ValueError(f"{self.name}: sink {dst if dst in self._sinks else ''} has no position fix to aim at")
        return min(sinks.values(), key=lambda q: math.dist(q, here))

    def relay(self, header: Header) -> Header:
        assert isinstance(header, VbfHeader)
        return replace(header, forwarder=self.port.position())

    # -- a forwarder -----------------------------------------------------------------------------

    def on_copy(self, datagram: Datagram, sender: int) -> None:
        h = datagram.header
        assert isinstance(h, VbfHeader)
        key = h.key
        held = self.held.get(key)
        if held is not None:  # another forwarder's copy, heard while holding
            held.forwarders.append(h.forwarder)
            return
        if key in self.history:
            return
        self.history.add(key)
        here = self.port.position()
        p = pipe_distance(here, self.pipe_start(h, h.forwarder), h.target)
        if p > h.radius:  # outside the routing pipe
            return
        alpha, d = desirableness(here, h.forwarder, h.target, p, h.radius, self.R)
        self.held[key] = _Held(datagram, sender, [h.forwarder])
        hold = math.sqrt(alpha) * self.params.delay_max_s + (self.R - d) / self.params.sound_speed_mps
        self.later(hold, lambda: self._decide(key))

    def _decide(self, key: tuple[int, int]) -> None:
        """Self-adaptation at the end of the holding time: forward, or discard as redundant."""
        held = self.held.pop(key)
        h = held.datagram.header
        assert isinstance(h, VbfHeader)
        here = self.port.position()
        best = math.inf
        for f in held.forwarders:
            p = pipe_distance(here, self.pipe_start(h, f), h.target)
            best = min(best, desirableness(here, f, h.target, p, h.radius, self.R)[0])
        n = len(held.forwarders) - 1
        if best < self.params.alpha_c / 2.0**n:
            self.forward(held.datagram, held.prev, best)
        else:
            self.suppressed(held.datagram, held.prev, best)
