"""Checks of a scenario across sections, with exact key paths: group names and counts, the
sound-speed profile, positions inside the volume, protocol parameters against the protocol's
``Params`` model, mobility parameters against the mobility class.

Also the bounds of docs/scenarios.md "Limits and plausibility": resource-sized values (node
counts, profile layers, trace samples, sweep sizes) against :data:`LIMITS` before anything is
allocated; physically impossible values (a non-positive sound speed in the water column, a clock
skew <= -1, a node configured at or above the slowest sound speed) as errors; implausible but
legal values (:data:`PLAUSIBLE`) as one :class:`ScenarioWarning` each; and cross-field checks of
protocol parameters against the network (node ids that must exist, counts that must fit), by
the protocol's own ``Params.check_scenario(params, network)`` hook when it has one, else by the
shipped checks of :data:`PROTOCOL_CHECKS`."""

from __future__ import annotations

import difflib
import inspect
import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import BaseModel, ValidationError

from aquasim_py import registry
from aquasim_py.errors import ScenarioWarning
from aquasim_py.scenario.build import make_ssp, mobility_class, placement_positions, warn_deprecated_mobility
from aquasim_py.scenario.errors import ScenarioError, format_key_path, raise_validation, show
from aquasim_py.scenario.schema import (
    ExplicitPlacement,
    GridPlacement,
    NodeGroupSpec,
    RingPlacement,
    UniformPlacement,
)

if TYPE_CHECKING:
    from aquasim_py.scenario.model import Scenario

__all__ = [
    "LIMITS",
    "PLAUSIBLE",
    "PROTOCOL_CHECKS",
    "NetworkSummary",
    "ScenarioWarning",
    "check",
    "check_sweep_size",
]

#: resource bounds (docs/scenarios.md "Limits and plausibility"): each keeps one run's memory
#: (or a sweep's run count) to what a workstation holds; exceeding one is an error naming it.
LIMITS: dict[str, float] = {
    "nodes": 100_000,  # nodes of a run, all groups together
    "layers": 10_000,  # sound-speed profile layers (Munk n_layers, layered / CTD points)
    "samples": 5e7,  # rows of the positions table (nodes x samples), and clock drift steps
    "sweep_runs": 100_000,  # grid points x runs of one sweep
}
#: bytes per row of the positions table (time, node, x, y, z, vx, vy, vz as 8-byte numbers)
_ROW_BYTES = 64

#: key -> (lo, hi, why): values outside [lo, hi] run, with one warning line
PLAUSIBLE: dict[str, tuple[float, float, str]] = {
    "sound_speed_mps": (1400.0, 1600.0, "sea water is 1400-1600 m/s"),
    "gradient_per_s": (-1.0, 1.0, "ocean gradients are below 1 (m/s)/m"),
    "skew_ppm": (-1000.0, 1000.0, "modem clocks drift by tens of ppm"),
    "node_speed_mps": (0.0, 20.0, "vehicles and currents stay below 20 m/s"),
    "modem_power_w": (0.0, 500.0, "acoustic modems draw at most a few hundred W"),
    "follow_radius_m": (0.0, 10.0, "arrival sets measured up to 10 m; docs/channel.md"),
}


def _plausible(file: Path | None, key: str, value: float, what: str) -> None:
    lo, hi, why = PLAUSIBLE[what]
    if not lo <= value <= hi:
        where = f"{file}: " if file is not None else ""
        warnings.warn(
            f"{where}{key}: value {value:g} is outside the plausible range [{lo:g}, {hi:g}] ({why})",
            ScenarioWarning,
            stacklevel=2,
        )


def _limit(file: Path | None, key: str, what: str, amount: float, unit: str, extra: str = "") -> None:
    cap = LIMITS[what]
    if amount > cap:
        raise ScenarioError(file, key, f"{amount:.3g} {unit}{extra} (limit: {cap:.3g} {unit}, docs/scenarios.md)")


@dataclass
class NetworkSummary:
    """What cross-field checks know of the network: node ids (0..n-1 in group order) by group
    and by role."""

    n_nodes: int
    groups: list[list[int]] = field(default_factory=list)
    roles: dict[str, list[int]] = field(default_factory=dict)
    group: int = 0  # the group whose parameters are being checked
    group_role: str = ""

    def ids(self, *roles: str) -> list[int]:
        return sorted(i for r in roles for i in self.roles.get(r, []))


def check(sc: Scenario, file: Path | None) -> None:
    """Checks across sections (fills in group names, implied counts, validated protocol params)."""
    # group names and counts
    seen: dict[str, int] = {}
    for i, g in enumerate(sc.nodes):
        if g.name is None:
            g.name = f"group{i}"
        if g.name in seen:
            raise ScenarioError(file, f"nodes[{i}].name", f"{g.name!r} is already the name of nodes[{seen[g.name]}]")
        seen[g.name] = i
        _check_count(g, i, file)
    _check_resources(sc, file)
    # the sound-speed profile (its constructor knows the physics constraints)
    ssp = make_ssp(sc)
    c_min = _check_sound_speed(sc, ssp, file)
    vol = sc.environment.volume
    lo, hi = np.asarray(vol.lo), np.asarray(vol.hi)
    for i, g in enumerate(sc.nodes):
        p = g.placement
        if isinstance(p, ExplicitPlacement):
            for j, q in enumerate(p.positions):
                _inside(q, lo, hi, file, f"nodes[{i}].placement.positions[{j}]")
        elif isinstance(p, RingPlacement):
            ring = placement_positions(g, vol.lo, vol.hi, np.random.default_rng(0))  # (no random draw)
            for j, q in enumerate(ring):
                _inside(q, lo, hi, file, f"nodes[{i}].placement (node {j} of the ring)")
        elif isinstance(p, (UniformPlacement, GridPlacement)):
            for side in ("lo", "hi"):
                q = getattr(p, side)
                if q is not None:
                    _inside(q, lo, hi, file, f"nodes[{i}].placement.{side}")
            plo = np.asarray(p.lo if p.lo is not None else vol.lo)
            phi = np.asarray(p.hi if p.hi is not None else vol.hi)
            if np.any(plo > phi):
                raise ScenarioError(
                    file, f"nodes[{i}].placement", f"lo {plo.tolist()} is above hi {phi.tolist()} on some axis"
                )
        _check_protocol(g, i, file)
        _check_mac(g, i, file)
        _check_routing(g, i, file)
        _check_mobility(g, i, file, c_min)
        _check_clock(g, i, file)
    _check_routed_network(sc, file)
    _check_channel(sc, file)
    _check_network(sc, file)


#: the modem's power by state: all four, or none (energy not counted)
POWER_KEYS = ("tx_power_w", "rx_power_w", "idle_power_w", "sleep_power_w")


def _check_channel(sc: Scenario, file: Path | None) -> None:
    """The physical layer's and energy's keys across ``[channel]`` and the node groups."""
    from aquasim_py.channel.phy import PerTable

    c = sc.channel
    given = [k for k in POWER_KEYS if getattr(c, k) is not None]
    if given and len(given) < len(POWER_KEYS):
        missing = next(k for k in POWER_KEYS if k not in given)
        raise ScenarioError(
            file,
            f"channel.{missing}",
            f"missing: give all four of {', '.join(POWER_KEYS)} (or a modem preset), or none",
        )
    for k in given:
        _plausible(file, f"channel.{k}", float(getattr(c, k)), "modem_power_w")
    _plausible(file, "channel.follow_radius_m", c.follow_radius_m, "follow_radius_m")
    for i, g in enumerate(sc.nodes):
        if g.battery is not None and not given:
            raise ScenarioError(
                file,
                f"nodes[{i}].battery",
                'a battery needs the modem\'s power: set [channel] modem = "NAME" (aquasim-py modems) or its '
                + ", ".join(POWER_KEYS),
            )
    if c.reception == "sinr" and c.loss_model == "none":
        raise ScenarioError(file, "channel.reception", "'sinr' needs the SNR loss model (loss_model = 'default')")
    if c.modulation == "table":
        if c.per_table is None:
            raise ScenarioError(
                file, "channel.per_table", "modulation = 'table' needs per_table = [[sinr_db, per], ...]"
            )
        try:
            PerTable(tuple((p[0], p[1]) for p in c.per_table), c.per_table_bits)
        except ValueError as e:
            raise ScenarioError(file, "channel.per_table", str(e)) from None
    if c.modulation == "mfsk" and c.modulation_order & (c.modulation_order - 1):
        raise ScenarioError(file, "channel.modulation_order", f"M-ary FSK needs a power of 2, got {c.modulation_order}")
    integrated = c.noise_band == "integrated" or (c.noise_band is None and c.reception == "sinr")
    if integrated and not c.bandwidth_khz < 2.0 * c.frequency_khz:
        raise ScenarioError(
            file,
            "channel.bandwidth_khz",
            f"{c.bandwidth_khz:g} kHz around {c.frequency_khz:g} kHz reaches below 0 Hz: the noise cannot be "
            "integrated over it",
        )


def _check_count(g: NodeGroupSpec, i: int, file: Path | None) -> None:
    p = g.placement
    implied = None
    if isinstance(p, ExplicitPlacement):
        implied = len(p.positions)
    elif isinstance(p, GridPlacement):
        implied = math.prod(p.shape)  # Python ints: no int64 overflow for a huge shape
        _limit(file, f"nodes[{i}].placement.shape", "nodes", implied, "nodes")
    if implied is None:
        if g.count is None:
            raise ScenarioError(file, f"nodes[{i}].count", f"required key missing (a {p.kind} placement needs a count)")
    elif g.count is None:
        g.count = implied
    elif g.count != implied:
        raise ScenarioError(
            file, f"nodes[{i}].count", f"{g.count} differs from the {p.kind} placement's {implied} positions"
        )


def _inside(q: Sequence[float], lo: np.ndarray, hi: np.ndarray, file: Path | None, key: str) -> None:
    pt = np.asarray(q, dtype=float)
    if np.any(pt < lo) or np.any(pt > hi):
        raise ScenarioError(
            file, key, f"position {pt.tolist()} is outside the volume lo={lo.tolist()} hi={hi.tolist()}"
        )


def _check_finite(v: Any, loc: list[str | int], file: Path | None) -> None:
    """NaN / inf anywhere in free-form parameters (protocol, mobility) is a mistake."""
    if isinstance(v, float) and not math.isfinite(v):
        raise ScenarioError(file, format_key_path(loc), f"must be a finite number (got {show(v)})")
    if isinstance(v, list):
        for j, x in enumerate(v):
            _check_finite(x, loc + [j], file)
    elif isinstance(v, dict):
        for k, x in v.items():
            _check_finite(x, loc + [k], file)


def _has_str(v: Any) -> bool:
    if isinstance(v, str):
        return True
    if isinstance(v, list):
        return any(_has_str(x) for x in v)
    return False


def _check_protocol(g: NodeGroupSpec, i: int, file: Path | None) -> None:
    try:
        cls = registry.get(g.protocol, base=file.parent if file is not None else None)
    except registry.UnknownProtocolError as e:
        raise ScenarioError(file, f"nodes[{i}].protocol", e.message) from None
    Params: type[BaseModel] = cls.Params  # type: ignore[attr-defined]  # every registered Node has one
    # the resolved scenario carries every parameter, defaults included
    g.params = _checked_params(g.params, Params, i, "params", f"protocol {g.protocol!r}", file)


def _check_mac(g: NodeGroupSpec, i: int, file: Path | None) -> None:
    """The group's MAC by name, and its parameters against its ``Params``."""
    from aquasim_py.net import mac

    name = g.mac if g.mac is not None else "direct"
    try:
        cls = mac.get(name)
    except mac.UnknownMacError as e:
        raise ScenarioError(file, f"nodes[{i}].mac", str(e)) from None
    params = _checked_params(g.mac_params, cls.Params, i, "mac_params", f"MAC {name!r}", file)
    if g.mac is not None:  # (unset: direct, which takes none; the group resolves as before)
        g.mac_params = params


def _check_routing(g: NodeGroupSpec, i: int, file: Path | None) -> None:
    """The group's routing protocol by name, its parameters, and the sensors it needs."""
    if g.routing is None:
        if g.routing_params:
            raise ScenarioError(file, f"nodes[{i}].routing_params", "given without routing (name the protocol)")
        return
    from aquasim_py.net import routing

    try:
        cls = routing.get(g.routing)
    except routing.UnknownRouterError as e:
        raise ScenarioError(file, f"nodes[{i}].routing", str(e)) from None
    g.routing_params = _checked_params(
        g.routing_params, cls.Params, i, "routing_params", f"routing {g.routing!r}", file
    )
    has_fix = g.sensors.position_fix if g.sensors.position_fix is not None else g.role in ("buoy", "anchor")
    if cls.needs_position and not has_fix:
        raise ScenarioError(
            file,
            f"nodes[{i}].sensors.position_fix",
            f"routing {g.routing!r} needs the nodes' position fixes (set position_fix = true; "
            "position_noise_std_m sets their error)",
        )


def _check_routed_network(sc: Scenario, file: Path | None) -> None:
    """Routing is one protocol for the whole network, and it has a sink that routes."""
    routed = [(i, g) for i, g in enumerate(sc.nodes) if g.routing is not None]
    if not routed:
        return
    first, g0 = routed[0]
    for i, g in routed[1:]:
        if g.routing != g0.routing:
            raise ScenarioError(
                file,
                f"nodes[{i}].routing",
                f"{g.routing!r}, but nodes[{first}] routes with {g0.routing!r} (one protocol)",
            )
    for i, g in enumerate(sc.nodes):
        if g.role == "sink" and g.routing is None:
            raise ScenarioError(
                file, f"nodes[{i}].routing", f"missing: the sinks must run the network's routing ({g0.routing!r})"
            )
    if not any(g.role == "sink" for _, g in routed):
        raise ScenarioError(file, f"nodes[{first}].routing", "routes to sinks, but no group of role sink")


def _checked_params(
    raw: dict[str, Any], Params: type[BaseModel], i: int, key: str, owner: str, file: Path | None
) -> dict[str, Any]:
    """``nodes[i].<key>`` validated by ``Params`` (unknown names with a hint, NaN, types: one
    line naming the key), as a dict with every parameter, defaults included."""
    _check_finite(raw, ["nodes", i, key], file)
    fields = set(Params.model_fields)
    for k in raw:
        if k not in fields:
            near = difflib.get_close_matches(k, sorted(fields), n=1)
            hint = (
                f" (did you mean {near[0]!r}?)"
                if near
                else (f" (allowed: {', '.join(sorted(fields))})" if fields else " (it takes none)")
            )
            raise ScenarioError(file, f"nodes[{i}].{key}.{k}", f"unknown parameter of {owner}{hint}")
    try:
        # strict: a quoted number is not a number (no silent conversion, as for the file itself)
        validated = Params.model_validate(raw, strict=True)
    except ValidationError as e:
        raise_validation(e, raw, file, prefix=("nodes", i, key), model=Params)
    return validated.model_dump(mode="json")


def _check_mobility(g: NodeGroupSpec, i: int, file: Path | None, c_min: float = math.inf) -> None:
    warn_deprecated_mobility(g.mobility.model, file)
    try:
        cls = mobility_class(g.mobility.model)
    except ImportError:
        return  # mobility module not importable: build() will report it
    params = g.mobility.params()
    _check_finite(params, ["nodes", i, "mobility"], file)
    _check_node_speed(g.mobility.model, params, i, file, c_min)
    sig = inspect.signature(cls)  # the constructor's parameters, without self
    accepted = [
        n
        for n, p in sig.parameters.items()
        if n not in ("self", "initial_positions", "box", "rng") and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
    ]
    if any(p.kind == p.VAR_KEYWORD for p in sig.parameters.values()):
        return
    for k, v in params.items():
        ann = str(sig.parameters[k].annotation) if k in sig.parameters else ""
        if _has_str(v) and "str" not in ann and "Literal" not in ann:
            got = f"got string {v!r}" if isinstance(v, str) else "got a string inside"
            raise ScenarioError(file, f"nodes[{i}].mobility.{k}", f"expected a number ({got}; no conversion)")
    for k in params:
        if k not in accepted:
            near = difflib.get_close_matches(k, accepted, n=1)
            hint = (
                f" (did you mean {near[0]!r}?)"
                if near
                else (f" (allowed: {', '.join(accepted)})" if accepted else " (it takes none)")
            )
            raise ScenarioError(
                file, f"nodes[{i}].mobility.{k}", f"unknown parameter of mobility model {g.mobility.model!r}{hint}"
            )


# --------------------------------------------------------------------------- resources
def _check_resources(sc: Scenario, file: Path | None) -> None:
    """Resource-sized values against :data:`LIMITS`, before anything is allocated."""
    total = 0
    for i, g in enumerate(sc.nodes):
        assert g.count is not None
        total += g.count
        key = f"nodes[{i}].placement.shape" if isinstance(g.placement, GridPlacement) else f"nodes[{i}].count"
        _limit(file, key, "nodes", total, "nodes", "" if i == 0 else " in all groups")
    spec = sc.environment.sound_speed
    for name in ("n_layers", "depths_m", "depth_m"):
        v = getattr(spec, name, None)
        if v is not None:
            _limit(file, f"environment.sound_speed.{name}", "layers", v if isinstance(v, int) else len(v), "layers")
    duration = sc.simulation.duration_s
    dt = sc.trace.position_interval_s
    if dt is not None:
        rows = total * (math.floor(duration / dt) + 1)
        extra = f" ({total} nodes every {dt:g} s for {duration:g} s, ~{rows * _ROW_BYTES / 1e9:.3g} GB)"
        _limit(file, "trace.position_interval_s", "samples", rows, "position rows", extra)
    steps = 0.0
    for i, g in enumerate(sc.nodes):
        c = g.clock
        if c.drift_std_ppm > 0.0:
            assert g.count is not None
            steps += g.count * (duration / c.drift_interval_s + 1.0)
            _limit(file, f"nodes[{i}].clock.drift_interval_s", "samples", steps, "clock drift steps")


def check_sweep_size(file: Path | None, runs: int, sizes: Mapping[str, int]) -> None:
    """A sweep's grid points x runs against ``LIMITS["sweep_runs"]``."""
    n = runs * math.prod(sizes.values())
    _limit(file, "sweep", "sweep_runs", n, "runs", f" ({runs} runs x {math.prod(sizes.values())} grid points)")


# --------------------------------------------------------------------------- physics
def _water_column(sc: Scenario) -> float:
    """Deepest point a node or a ray can reach (m): the volume's bottom, or the sea floor."""
    bottom = sc.environment.bottom_m
    return max(sc.environment.volume.hi[2], bottom if bottom is not None else 0.0)


def _check_sound_speed(sc: Scenario, ssp: Any, file: Path | None) -> float:
    """Error if the speed is <= 0 anywhere in the water column; warn outside the plausible
    range. Returns the slowest speed (m/s)."""
    zmax = _water_column(sc)
    pts = [np.linspace(0.0, zmax, 1001)]
    try:  # piecewise-linear profiles take their extremes at their knots
        knots = np.asarray(ssp.to_layered().depths, dtype=float)
        pts.append(knots[(knots >= 0.0) & (knots <= zmax)])
    except (NotImplementedError, ValueError, AttributeError):
        pass
    z = np.concatenate(pts)
    c = np.asarray(ssp.speed(z), dtype=float)
    k = int(np.argmin(c))
    key = "environment.sound_speed"
    if not c[k] > 0.0:
        raise ScenarioError(
            file, key, f"sound speed {c[k]:g} m/s at depth {z[k]:g} m (must be > 0 in the water column 0-{zmax:g} m)"
        )
    spec = sc.environment.sound_speed
    if spec.model == "constant":
        _plausible(file, f"{key}.speed_mps", float(c[k]), "sound_speed_mps")
    else:
        if spec.model == "isogradient":
            _plausible(file, f"{key}.gradient_per_s", spec.gradient_per_s, "gradient_per_s")
        _plausible(file, f"{key} (slowest in the water column)", float(c[k]), "sound_speed_mps")
        _plausible(file, f"{key} (fastest in the water column)", float(c.max()), "sound_speed_mps")
    return float(c[k])


def _max_speed(model: str, params: Mapping[str, Any]) -> tuple[str, float] | None:
    """(parameter, largest configured node speed in m/s) of a mobility model, where the
    parameters state it; None for flow fields (kinematic, meandering_jet) and defaults."""
    try:
        if model == "constant_velocity" and "velocity" in params:
            v = np.asarray(params["velocity"], dtype=float).reshape(-1, 3)
            return "velocity", float(np.max(np.linalg.norm(v, axis=1)))
        if model == "coordinated_turn" and ("speed" in params or "vz" in params):
            s = float(np.max(np.abs(np.asarray(params.get("speed", 1.0), dtype=float))))
            vz = float(np.max(np.abs(np.asarray(params.get("vz", 0.0), dtype=float))))
            return ("speed" if "speed" in params else "vz"), math.hypot(s, vz)
        if model == "random_walk" and "speed_max" in params:
            return "speed_max", float(params["speed_max"])
        if model == "waypoints" and "speed" in params:
            return "speed", float(np.max(np.abs(np.asarray(params["speed"], dtype=float))))
    except (TypeError, ValueError):
        return None  # malformed: the mobility constructor reports it at build time
    return None


def _check_node_speed(model: str, params: Mapping[str, Any], i: int, file: Path | None, c_min: float) -> None:
    found = _max_speed(model, params)
    if found is None:
        return
    name, v = found
    key = f"nodes[{i}].mobility.{name}"
    if v >= c_min:
        raise ScenarioError(
            file,
            key,
            f"a node speed of {v:g} m/s is not below the slowest sound speed {c_min:g} m/s "
            "(a node would outrun its own signals)",
        )
    _plausible(file, key, v, "node_speed_mps")


def _check_clock(g: NodeGroupSpec, i: int, file: Path | None) -> None:
    c = g.clock
    # local = (1 + skew) t + offset: a skew <= -1 stops or reverses local time; 6 std keeps
    # the per-node draws N(skew_ppm, skew_std_ppm) above it with certainty in practice
    low = c.skew_ppm - 6.0 * c.skew_std_ppm
    if low <= -1e6:
        key = f"nodes[{i}].clock.skew_ppm"
        what = f"{c.skew_ppm:g}" if c.skew_std_ppm == 0.0 else f"{c.skew_ppm:g} - 6 x skew_std_ppm = {low:g}"
        raise ScenarioError(file, key, f"must be > -1e6 ppm (a skew <= -1 stops or reverses the clock; got {what})")
    _plausible(file, f"nodes[{i}].clock.skew_ppm", c.skew_ppm, "skew_ppm")


# --------------------------------------------------------------------------- network
#: count parameters (any protocol) that need that many other nodes to ever act
_COUNT_FIELDS = ("n_ref", "first_fix_refs", "min_refs", "self_min_refs")

CrossCheck = Callable[[BaseModel, NetworkSummary], list[tuple[str, str]]]


def _generic_checks(params: BaseModel, net: NetworkSummary) -> list[tuple[str, str]]:
    """Node-id lists (fields ``*_ids``) name existing nodes once each; reference counts
    (:data:`_COUNT_FIELDS`) fit in the other nodes of the network."""
    out: list[tuple[str, str]] = []
    for name in type(params).model_fields:
        v = getattr(params, name)
        if name.endswith("_ids") and isinstance(v, list):
            first: dict[int, int] = {}
            for j, x in enumerate(v):
                if not 0 <= x < net.n_nodes:
                    out.append((f"{name}[{j}]", f"node id {x} is not a node (ids 0..{net.n_nodes - 1})"))
                elif x in first:
                    out.append((f"{name}[{j}]", f"node id {x} appears twice (also {name}[{first[x]}])"))
                else:
                    first[x] = j
        if name in _COUNT_FIELDS and isinstance(v, int) and v > net.n_nodes - 1:
            out.append(
                (name, f"{v} is more than the {net.n_nodes - 1} other nodes of the network (it could never act)")
            )
    return out


def _ramezani_checks(params: Any, net: NetworkSummary) -> list[tuple[str, str]]:
    """Ramezani: ``min_anchors`` <= the TDMA slots; every anchor / buoy of the group has a slot."""
    out: list[tuple[str, str]] = []
    n = len(params.anchor_positions)
    ids = params.anchor_ids if params.anchor_ids is not None else list(range(n))
    key = "anchor_ids" if params.anchor_ids is not None else "anchor_positions"
    if params.anchor_ids is None:
        bad = [x for x in ids if x >= net.n_nodes]
        if bad:
            out.append((key, f"the default anchor_ids 0..{n - 1} name node {bad[0]}, which is not a node"))
    if params.min_anchors > n:
        out.append(("min_anchors", f"{params.min_anchors} is more than the {n} anchors of anchor_positions"))
    if net.group_role in ("anchor", "buoy"):
        missing = [x for x in net.groups[net.group] if x not in ids]
        if missing:
            out.append((key, f"anchor node {missing[0]} of this group has no slot (anchor_ids {ids})"))
    return out


#: checks of shipped protocols whose Params do not define ``check_scenario`` themselves
PROTOCOL_CHECKS: dict[str, CrossCheck] = {"ramezani": _ramezani_checks}


def _check_network(sc: Scenario, file: Path | None) -> None:
    from dataclasses import replace

    net = NetworkSummary(n_nodes=0)
    for g in sc.nodes:
        assert g.count is not None
        ids = list(range(net.n_nodes, net.n_nodes + g.count))
        net.groups.append(ids)
        net.roles.setdefault(g.role, []).extend(ids)
        net.n_nodes += g.count
    for i, g in enumerate(sc.nodes):
        cls = registry.get(g.protocol, base=file.parent if file is not None else None)
        Params: type[BaseModel] = cls.Params  # type: ignore[attr-defined]
        params = Params.model_validate(g.params)
        here = replace(net, group=i, group_role=g.role)
        problems = _generic_checks(params, here)
        hook = getattr(Params, "check_scenario", None)
        if callable(hook):
            problems += hook(params, here)
        elif g.protocol in PROTOCOL_CHECKS:
            problems += PROTOCOL_CHECKS[g.protocol](params, here)
        if problems:
            key, problem = problems[0]
            raise ScenarioError(file, f"nodes[{i}].params.{key}", problem)
