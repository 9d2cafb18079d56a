"""Validated :class:`Scenario` -> ready-to-run :class:`~aquasim_py.kernel.Simulation`.

Per-node random draws (placement, clocks, mobility) come from the simulation's named random
streams, so one group's draws never shift another's. Also the physics objects a scenario
names (sound-speed profile, channel configuration, mobility classes), which validation uses
to check values only the physics constructors can judge.
"""

from __future__ import annotations

import csv
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from aquasim_py import registry
from aquasim_py.errors import ScenarioDeprecationWarning
from aquasim_py.scenario import ocean
from aquasim_py.scenario.errors import ScenarioError
from aquasim_py.scenario.schema import (
    ConstantSSP,
    CtdSSP,
    ExplicitPlacement,
    IsogradientSSP,
    LayeredSSP,
    MunkSSP,
    NodeGroupSpec,
    RingPlacement,
    UniformPlacement,
)

if TYPE_CHECKING:
    from aquasim_py.scenario.model import Scenario

__all__ = [
    "DEPRECATED_MOBILITY",
    "MOBILITY_CLASSES",
    "ScenarioDeprecationWarning",
    "build",
    "channel_config",
    "make_ssp",
    "mobility_class",
    "placement_positions",
    "warn_deprecated_mobility",
]

#: scenario mobility model name -> class name in aquasim_py.mobility
MOBILITY_CLASSES = {
    "static": "Static",
    "constant_velocity": "ConstantVelocity",
    "coordinated_turn": "CoordinatedTurn",
    "random_walk": "RandomWalk",
    "kinematic": "Kinematic",
    "meandering_jet": "MeanderingJet",
    "meandering_current": "Kinematic",  # deprecated alias, see DEPRECATED_MOBILITY
    "waypoints": "Waypoints",
    "noisy_constant_velocity": "NoisyConstantVelocity",
}

#: deprecated scenario mobility names -> the warning a load emits (once per name)
DEPRECATED_MOBILITY = {
    "meandering_current": (
        "mobility model 'meandering_current' is deprecated: it still means the STVF/SLMP kinematic "
        "model, now named 'kinematic'; the Bower/Caruso meandering current is 'meandering_jet'"
    ),
}


def warn_deprecated_mobility(model: str, file: Path | None) -> None:
    msg = DEPRECATED_MOBILITY.get(model)
    if msg is not None:
        # one message per file (not per group): the default filter shows it once
        where = f"{file}: " if file is not None else ""
        warnings.warn(f"{where}{msg}", ScenarioDeprecationWarning, stacklevel=3)


def mobility_class(model: str) -> type:
    from aquasim_py import mobility

    return getattr(mobility, MOBILITY_CLASSES[model])


def _ctd_columns(spec: CtdSSP, file: Path | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    key = "environment.sound_speed.file"
    if spec.file is None:
        return (
            np.asarray(spec.depth_m, float),
            np.asarray(spec.temperature_c, float),
            np.asarray(spec.salinity_psu, float),
        )
    p = Path(spec.file)
    if not p.is_absolute() and file is not None:
        p = file.parent / p
    try:
        with open(p, newline="") as fh:
            rows = list(csv.DictReader(fh))
    except FileNotFoundError:
        raise ScenarioError(file, key, f"CTD file not found: {p}") from None
    except OSError as e:
        raise ScenarioError(file, key, f"cannot read CTD file {p}: {e.strerror}") from None
    names = {
        "depth": ("depth_m", "depth"),
        "temperature": ("temperature_c", "temperature"),
        "salinity": ("salinity_psu", "salinity"),
    }
    header = rows[0].keys() if rows else []
    cols = []
    for options in names.values():
        col = next((c for c in options if c in header), None)
        if col is None:
            raise ScenarioError(
                file, key, f"CTD file {p} has no {options[0]} column (columns: depth_m, temperature_c, salinity_psu)"
            )
        try:
            cols.append(np.array([float(r[col]) for r in rows]))
        except (TypeError, ValueError):
            raise ScenarioError(file, key, f"CTD file {p}: column {col} has a non-numeric value") from None
    return cols[0], cols[1], cols[2]


def make_ssp(sc: Scenario) -> Any:
    """The scenario's sound-speed profile object (aquasim_py.channel.ssp)."""
    from aquasim_py.channel import ssp

    spec = sc.environment.sound_speed
    bottom = sc.environment.bottom_m
    if not ocean.depth_profile(sc):
        return ocean.centre_profile(sc)  # what the scenario checks look at
    try:
        if isinstance(spec, ConstantSSP):
            return ssp.Constant(spec.speed_mps, bottom=bottom)
        if isinstance(spec, IsogradientSSP):
            return ssp.Isogradient(spec.surface_speed_mps, spec.gradient_per_s, bottom=bottom)
        if isinstance(spec, LayeredSSP):
            return ssp.Layered(np.asarray(spec.depths_m), np.asarray(spec.speeds_mps), bottom=bottom)
        if isinstance(spec, MunkSSP):
            return ssp.Munk(
                spec.axis_depth_m,
                spec.axis_speed_mps,
                spec.epsilon,
                spec.scale_m,
                bottom=bottom,
                n_layers=spec.n_layers,
            )
        if isinstance(spec, CtdSSP):
            if sc._ctd is None:
                sc._ctd = _ctd_columns(spec, sc.path)
            return ssp.from_ctd(*sc._ctd, bottom=bottom)
    except ValueError as e:
        raise ScenarioError(sc.path, "environment.sound_speed", str(e)) from None
    raise AssertionError(f"unhandled profile {spec!r}")


def placement_positions(
    g: NodeGroupSpec, volume_lo: Sequence[float], volume_hi: Sequence[float], rng: np.random.Generator
) -> np.ndarray:
    """Initial positions (count, 3) of a group (m).

    uniform: i.i.d. uniform in the placement box (default the volume), drawn from ``rng``;
    grid: ``shape`` points per axis from lo to hi inclusive (one point: the middle), the last
    axis varying fastest; explicit: as given; ring: evenly on a horizontal circle.
    """
    p = g.placement
    if isinstance(p, ExplicitPlacement):
        return np.asarray(p.positions, dtype=float).reshape(-1, 3)
    if isinstance(p, RingPlacement):
        assert g.count is not None
        phi = 2.0 * np.pi * np.arange(g.count) / g.count
        ring = np.stack([np.cos(phi), np.sin(phi), np.zeros(g.count)], axis=1)
        return np.asarray(p.center, dtype=float) + p.radius_m * ring
    lo = np.asarray(p.lo if p.lo is not None else volume_lo, dtype=float)
    hi = np.asarray(p.hi if p.hi is not None else volume_hi, dtype=float)
    if isinstance(p, UniformPlacement):
        assert g.count is not None
        return rng.uniform(lo, hi, size=(g.count, 3))
    axes = [np.linspace(lo[k], hi[k], n) if n > 1 else np.array([(lo[k] + hi[k]) / 2.0]) for k, n in enumerate(p.shape)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


def _clock_factory(spec: Any) -> Any:
    """``(node_id, rng) -> Clock`` drawing this node's skew and offset from its own stream."""
    from aquasim_py.clock import Clock

    def make(node_id: int, rng: np.random.Generator) -> Clock:
        skew = (spec.skew_ppm + spec.skew_std_ppm * rng.standard_normal()) * 1e-6
        offset = spec.offset_s + spec.offset_std_s * rng.standard_normal()
        needs_rng = spec.drift_std_ppm > 0.0 or spec.jitter_std_s > 0.0
        return Clock(
            skew=float(skew),
            offset=float(offset),
            drift_std=spec.drift_std_ppm * 1e-6,
            drift_interval=spec.drift_interval_s,
            jitter_std=spec.jitter_std_s,
            rng=rng if needs_rng else None,
        )

    return make


def channel_config(sc: Scenario) -> Any:
    """The kernel's ChannelConfig for the scenario's [channel] table."""
    from aquasim_py.channel.config import ChannelConfig

    c = sc.channel
    return ChannelConfig(
        max_range_m=c.max_range_m,
        bitrate_bps=c.bitrate_bps,
        source_level_db=c.source_level_db,
        frequency_khz=c.frequency_khz,
        bandwidth_khz=c.bandwidth_khz,
        spreading=c.spreading,
        shipping=c.noise.shipping,
        wind_mps=c.noise.wind_mps,
        snr_threshold_db=c.snr_threshold_db,
        collision=c.collision,
        capture_threshold_db=c.capture_threshold_db,
        jitter_std_s=c.jitter_std_s,
        reflections=c.reflections,
        pressure_kind=c.pressure_kind,
        pressure_source_level=c.pressure_source_level,
        pressure_exponent=c.pressure_exponent,
        pressure_noise_std=c.pressure_noise_std,
        obstacles=None if c.obstacles is None else _obstacles(c.obstacles),
        sound_speed_std_mps=c.sound_speed_std_mps,
        sound_speed_corr_s=c.sound_speed_corr_s,
        snr_estimate_std_db=c.snr_estimate_std_db,
        max_bounces=c.max_bounces,
        detection_threshold_db=c.detection_threshold_db,
        direct_only=c.direct_only,
        follow_radius_m=c.follow_radius_m,
        reception=c.reception,
        modulation=c.modulation,
        modulation_order=c.modulation_order,
        coding_gain_db=c.coding_gain_db,
        per_table=None if c.per_table is None else tuple((p[0], p[1]) for p in c.per_table),
        per_table_bits=c.per_table_bits,
        lock=c.lock,
        per_combining=c.per_combining,
        interference_floor_db=c.interference_floor_db,
        noise_band=c.noise_band,
        overhead_s=c.overhead_s,
        modem=c.modem,
        tx_power_w=c.tx_power_w,
        rx_power_w=c.rx_power_w,
        idle_power_w=c.idle_power_w,
        sleep_power_w=c.sleep_power_w,
    )


def _obstacles(o: Any) -> Any:
    """The channel's ObstacleConfig for a [channel.obstacles] table."""
    from aquasim_py.channel.obstacles import ObstacleConfig

    return ObstacleConfig(
        links=tuple((a, b) for a, b in o.links),
        probability=o.probability,
        nodes=None if o.nodes is None else tuple(o.nodes),
        extra_loss_db=o.extra_loss_db,
        excess_delay_s=o.excess_delay_s,
        excess_delay_ratio=o.excess_delay_ratio,
        excess_delay_sigma_ratio=o.excess_delay_sigma_ratio,
    )


def _environment(sc: Scenario, ssp: Any) -> Any:
    """The scenario's Environment (its depth profile ``ssp`` where the sound speed is one)."""
    return ocean.make_environment(sc, ssp if ocean.depth_profile(sc) else None)


def build(sc: Scenario) -> Any:
    """A ready-to-run :class:`~aquasim_py.kernel.Simulation` for a validated scenario.

    Random draws per group come from the simulation's streams keyed by the group's name:
    ("group", name, "placement") for uniform positions, ("group", name, "mobility") for the
    mobility model, ("node", id, "clock") for each node's clock. Errors that only the physics
    constructors detect (e.g. a mobility parameter out of range) become ScenarioError.
    """
    from aquasim_py.channel.config import no_snr
    from aquasim_py.kernel import Simulation
    from aquasim_py.mobility import Box
    from aquasim_py.node import Sensors
    from aquasim_py.trace import TraceConfig

    file = sc.path
    vol = sc.environment.volume
    box = Box(vol.lo, vol.hi)
    try:
        cfg = channel_config(sc)
    except ValueError as e:
        raise ScenarioError(file, "channel", str(e)) from None
    ssp = make_ssp(sc)
    sim = Simulation(
        sc.simulation.seed,
        ssp,
        box,
        cfg,
        TraceConfig(position_interval=sc.trace.position_interval_s),
        loss_model=no_snr if sc.channel.loss_model == "none" else None,
        # a bathymetry, a section or a grid: the channel traces the environment (every arrival)
        environment=_environment(sc, ssp) if ocean.range_dependent(sc) else None,
    )
    for i, g in enumerate(sc.nodes):
        assert g.name is not None and g.count is not None
        cls = registry.get(g.protocol, base=sc.base_dir)
        pos = placement_positions(g, vol.lo, vol.hi, sim.rng("group", g.name, "placement"))
        try:
            mob_cls = mobility_class(g.mobility.model)
        except (ImportError, AttributeError) as e:
            raise ScenarioError(file, f"nodes[{i}].mobility.model", f"mobility model unavailable ({e})") from None
        try:
            # the same stream add_group would hand a mobility factory
            mobility = mob_cls(pos, box, sim.rng("group", g.name, "mobility"), **g.mobility.params())
        except (ValueError, TypeError) as e:
            raise ScenarioError(file, f"nodes[{i}].mobility", str(e)) from None
        s = g.sensors
        sim.add_group(
            cls,
            g.count,
            role=g.role,
            mobility=mobility,
            clocks=_clock_factory(g.clock),
            params=g.params,
            name=g.name,
            mac=g.mac,
            mac_params=g.mac_params,
            routing=g.routing,
            routing_params=g.routing_params,
            sensors=Sensors(
                depth_std=s.depth_noise_std_m,
                velocity_std=s.velocity_noise_std_mps,
                velocity=s.velocity_sensor,
                position_std=s.position_noise_std_m,
                position=s.position_fix,
            ),
            battery_j=None if g.battery is None else g.battery.capacity_j,
        )
    return sim
