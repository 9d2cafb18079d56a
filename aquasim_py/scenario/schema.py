"""The scenario file format: strict pydantic models of a TOML scenario (units in field names).

Every model forbids unknown keys, rejects NaN / inf, and is strict about types (a TOML
integer is accepted where a float is expected, nothing else is converted). Cross-section
checks that need several sections at once (positions inside the volume, protocol parameters
against the protocol's own model) are made in :mod:`aquasim_py.scenario.validate`; override
sets (``[sweep]`` grid keys, ``[variants.NAME]`` tables) are resolved and checked in
:mod:`aquasim_py.scenario.load`.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

import annotated_types as at
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_serializer, model_validator

from aquasim_py.scenario.ocean_schema import (
    OCEAN_KEYS,
    BathymetrySpec,
    GridSSP,
    NonNegFloat,
    PosFloat,
    Season,
    SectionSSP,
    SedimentSpec,
    check_geographic,
)

__all__ = [
    "PHY_KEYS",
    "ROLES",
    "BatterySpec",
    "ChannelSpec",
    "EnvironmentSpec",
    "MetricsSpec",
    "NodeGroupSpec",
    "ObstacleSpec",
    "OutputSpec",
    "Scenario",
    "SimulationSpec",
    "SweepSpec",
    "TraceSpec",
]

ROLES = ("buoy", "anchor", "ordinary", "target", "sink")

#: the ``[channel]`` keys of the physical layer, presets and energy: left out of the resolved
#: scenario unless set (Scenario.to_dict)
PHY_KEYS = (
    "modem",
    "reception",
    "modulation",
    "modulation_order",
    "coding_gain_db",
    "per_table",
    "per_table_bits",
    "lock",
    "per_combining",
    "interference_floor_db",
    "noise_band",
    "overhead_s",
    "tx_power_w",
    "rx_power_w",
    "idle_power_w",
    "sleep_power_w",
)

# annotated-types markers, not Field(...): see PosFloat in ocean_schema.py
PosInt = Annotated[int, at.Ge(1)]
Vec3 = Annotated[list[float], at.Len(3, 3)]


class Strict(BaseModel):
    """Base of every section: unknown keys are errors, no NaN / inf, no silent type conversion."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, frozen=False)


# --------------------------------------------------------------------------- [simulation]
class SimulationSpec(Strict):
    duration_s: PosFloat = Field(description="simulated time to run (s)")
    seed: Annotated[int, Field(ge=0, lt=2**63)] = Field(0, description="seed of every random stream")


# --------------------------------------------------------------------------- [environment]
class VolumeSpec(Strict):
    lo: Vec3 = Field(description="lower corner (x, y, z) in m; z is depth, positive down")
    hi: Vec3 = Field(description="upper corner (x, y, z) in m")

    @model_validator(mode="after")
    def _ordered(self) -> VolumeSpec:
        for k, (a, b) in enumerate(zip(self.lo, self.hi)):
            if not a < b:
                raise ValueError(f"lo must be below hi on every axis (axis {'xyz'[k]}: {a} >= {b})")
        if self.lo[2] < 0.0:
            raise ValueError(f"lo z (depth) must be >= 0, the sea surface (got {self.lo[2]})")
        return self


class ConstantSSP(Strict):
    model: Literal["constant"]
    speed_mps: PosFloat = 1500.0


class IsogradientSSP(Strict):
    model: Literal["isogradient"]
    surface_speed_mps: PosFloat = 1480.0
    gradient_per_s: float = Field(description="dc/dz in (m/s)/m = 1/s")


class LayeredSSP(Strict):
    model: Literal["layered"]
    depths_m: Annotated[list[float], Field(min_length=2)]
    speeds_mps: Annotated[list[PosFloat], Field(min_length=2)]

    @model_validator(mode="after")
    def _same_length(self) -> LayeredSSP:
        if len(self.depths_m) != len(self.speeds_mps):
            raise ValueError(
                f"depths_m and speeds_mps differ in length ({len(self.depths_m)} vs {len(self.speeds_mps)})"
            )
        return self


class MunkSSP(Strict):
    model: Literal["munk"]
    axis_depth_m: PosFloat = 1300.0
    axis_speed_mps: PosFloat = 1500.0
    epsilon: NonNegFloat = 0.00737
    scale_m: PosFloat = 1300.0
    n_layers: PosInt = 200


class CtdSSP(Strict):
    """A CTD cast: inline columns, or ``file`` = a CSV (columns depth_m, temperature_c,
    salinity_psu) whose path is relative to the scenario file."""

    model: Literal["ctd"]
    file: str | None = None
    depth_m: list[float] | None = None
    temperature_c: list[float] | None = None
    salinity_psu: list[float] | None = None

    @model_validator(mode="after")
    def _one_source(self) -> CtdSSP:
        cols = (self.depth_m, self.temperature_c, self.salinity_psu)
        inline = [c is not None for c in cols]
        if self.file is not None and any(inline):
            raise ValueError("give either file or the inline columns depth_m, temperature_c, salinity_psu, not both")
        if self.file is None and not all(inline):
            raise ValueError("needs file (a CSV path) or all of depth_m, temperature_c, salinity_psu")
        if all(inline) and not len(self.depth_m) == len(self.temperature_c) == len(self.salinity_psu):  # type: ignore[arg-type]
            raise ValueError("depth_m, temperature_c and salinity_psu differ in length")
        return self


SoundSpeedSpec = Annotated[
    ConstantSSP | IsogradientSSP | LayeredSSP | MunkSSP | CtdSSP | SectionSSP | GridSSP, Field(discriminator="model")
]


class EnvironmentSpec(Strict):
    volume: VolumeSpec
    sound_speed: SoundSpeedSpec = Field(default_factory=lambda: ConstantSSP(model="constant"))
    bottom_m: PosFloat | None = Field(None, description="sea-floor depth (m) for bottom reflections; none if unset")
    # range-dependent environments (aquasim_py.scenario.ocean)
    bathymetry: BathymetrySpec | None = Field(None, description="sea-floor depth over (x, y); instead of bottom_m")
    sediment: SedimentSpec | None = Field(None, description="the bottom's sediment (default sand)")
    # the ocean from standard files, placed on the globe (aquasim_py.scenario.ocean)
    origin: Annotated[list[float], Field(min_length=2, max_length=2)] | None = Field(
        None, description="[latitude, longitude] (deg) of x = y = 0; x east, y north (m)"
    )
    woa: str | Annotated[list[str], Field(min_length=1)] | None = Field(
        None, description="World Ocean Atlas temperature and salinity netCDF file(s); instead of sound_speed"
    )
    gebco: str | None = Field(None, description="GEBCO (or ETOPO) bathymetry netCDF file; instead of bathymetry")
    month: Annotated[int, Field(ge=1, le=12)] | None = Field(None, description="the WOA month (1-12)")
    season: Season | None = Field(None, description="the WOA season (winter = Jan-Mar, ... autumn = Oct-Dec)")

    @model_serializer(mode="wrap")
    def _without_unset_ocean(self, handler: Any) -> Any:
        # a scenario without them resolves exactly as before they existed
        d = handler(self)
        if isinstance(d, dict):
            for key in OCEAN_KEYS:
                if d.get(key) is None:
                    d.pop(key, None)
            if "woa" in d:  # the sound speed is the atlas's, not the (default) profile
                d.pop("sound_speed", None)
        return d

    @model_validator(mode="after")
    def _geographic(self) -> EnvironmentSpec:
        check_geographic(self)
        return self

    @model_validator(mode="after")
    def _one_floor(self) -> EnvironmentSpec:
        if self.bottom_m is not None and self.bathymetry is not None:
            raise ValueError("give bottom_m (a flat floor) or bathymetry, not both")
        return self

    @model_validator(mode="after")
    def _bottom_below_volume(self) -> EnvironmentSpec:
        if self.bottom_m is not None and self.bottom_m < self.volume.hi[2]:
            raise ValueError(
                f"bottom_m ({self.bottom_m}) is shallower than the volume's deepest point ({self.volume.hi[2]})"
            )
        return self


# --------------------------------------------------------------------------- [channel]
class NoiseSpec(Strict):
    shipping: Annotated[float, Field(ge=0.0, le=1.0)] = Field(0.5, description="shipping activity 0..1")
    wind_mps: NonNegFloat = Field(0.0, description="wind speed (m/s)")


class ObstacleSpec(Strict):
    """Obstructed links (aquasim_py.channel.obstacles): explicit id pairs and/or a per-link
    probability (each link decided from its own random stream)."""

    links: list[Annotated[list[Annotated[int, Field(ge=0)]], Field(min_length=2, max_length=2)]] = Field(
        default_factory=list, description="node-id pairs that are always obstructed"
    )
    probability: Annotated[float, Field(ge=0.0, le=1.0)] = Field(0.0, description="chance that another link is")
    nodes: list[Annotated[int, Field(ge=0)]] | None = Field(
        None, description="the probability applies only to links with an end at these ids (default all)"
    )
    extra_loss_db: NonNegFloat = Field(0.0, description="extra propagation loss of an obstructed link (dB)")
    excess_delay_s: NonNegFloat = Field(0.0, description="fixed excess delay of an obstructed link (s)")
    excess_delay_ratio: NonNegFloat = Field(0.0, description="excess delay as a fraction of the time of flight")
    excess_delay_sigma_ratio: NonNegFloat = Field(
        0.0,
        description="random excess delay |N(0, (this x time of flight)^2)| (half-normal: late only), per packet",
    )


class ChannelSpec(Strict):
    """Defaults equal those of aquasim_py.channel.acoustic.ChannelConfig (a test checks it)."""

    max_range_m: PosFloat = Field(5000.0, description="straight-line range limit at send time (m)")
    bitrate_bps: PosFloat = 1000.0
    source_level_db: float = Field(170.0, description="dB re 1 uPa at 1 m")
    frequency_khz: PosFloat = 10.0
    bandwidth_khz: PosFloat = 5.0
    spreading: Annotated[float, Field(ge=1.0, le=2.0)] = Field(1.5, description="spreading exponent k")
    noise: NoiseSpec = Field(default_factory=NoiseSpec)
    loss_model: Literal["default", "none"] = Field(
        "default", description="default: the SNR model of aquasim_py.channel.loss; none: no SNR loss"
    )
    snr_threshold_db: float = Field(10.0, description="receptions below this SNR are lost (dB)")
    collision: Literal["none", "destructive", "capture"] = "destructive"
    capture_threshold_db: NonNegFloat = 6.0
    jitter_std_s: NonNegFloat = Field(0.0, description="std of the MAC timestamp jitter (s)")
    reflections: Literal["none", "fallback", "all"] = "fallback"
    pressure_kind: str | None = Field(None, description="packet kind whose receptions carry received pressure")
    pressure_source_level: PosFloat = Field(5e4, description="S of the pressure model h = S / D^k")
    pressure_exponent: PosFloat = Field(1.0, description="k of the pressure model h = S / D^k")
    pressure_noise_std: NonNegFloat = Field(5.0, description="hydrophone noise std (pressure units)")
    obstacles: ObstacleSpec | None = Field(None, description="obstructed links; none by default")
    sound_speed_std_mps: NonNegFloat = Field(
        0.0, description="std of the path-mean sound speed around the profile (m/s); 0 = none"
    )
    sound_speed_corr_s: NonNegFloat = Field(
        0.0, description="per-link correlation time of that deviation (s); 0 = independent per packet"
    )
    snr_estimate_std_db: NonNegFloat = Field(
        1.0, description="std of the receiver's SNR estimate error (dB) in Reception.snr_db; 0 = exact"
    )
    # a range-dependent environment only (aquasim_py.channel.arrival_links); left out of the
    # resolved scenario of a range-independent one unless set (Scenario.to_dict)
    max_bounces: Annotated[int, Field(ge=0, le=20)] = Field(
        2, description="surface + bottom bounces of the arrivals a range-dependent channel lists"
    )
    detection_threshold_db: float | None = Field(
        None,
        description="SNR (dB) at which the modem detects an arrival and stamps it (the first such); "
        "default snr_threshold_db",
    )
    direct_only: bool = Field(
        False,
        description="analysis switch: receptions stamped on a reflected arrival are lost ('indirect'); not a modem",
    )
    follow_radius_m: NonNegFloat = Field(
        1.0,
        description="a range-dependent channel follows a link's eigenrays while each end stays within this (m) "
        "of where it was last searched; 0 = search at every request",
    )
    # the physical layer, modem presets and energy (docs/network.md); left out of the resolved
    # scenario unless set (Scenario.to_dict), so a file without them resolves as before
    modem: str | None = Field(
        None,
        description="a modem preset (aquasim-py modems): sets the keys it lists unless the file gives them",
    )
    reception: Literal["threshold", "sinr"] = Field(
        "threshold",
        description="threshold: SNR threshold + collision rule; sinr: SINR over the packet, modulation, PER draw",
    )
    modulation: Literal["bpsk", "qpsk", "bfsk", "mfsk", "table"] = Field(
        "bfsk", description="bit errors under reception = sinr (bfsk / mfsk non-coherent, bpsk / qpsk coherent)"
    )
    modulation_order: Annotated[int, Field(ge=2)] = Field(2, description="M of mfsk (a power of 2)")
    coding_gain_db: float = Field(0.0, description="coding gain on Eb/N0 (dB)")
    per_table: list[Annotated[list[float], Field(min_length=2, max_length=2)]] | None = Field(
        None, description="modulation = table: [[sinr_db, per], ...] in increasing SINR"
    )
    per_table_bits: PosInt = Field(256, description="packet length (bits) the PER table was measured on")
    lock: Literal["first", "relock", "none"] = Field(
        "first", description="acquisition under sinr: first (ns-3), relock (a later acquired signal takes over), none"
    )
    per_combining: Literal["pieces", "worst"] = Field(
        "pieces", description="PER over the SINR pieces (pieces) or every bit at the worst piece (worst, ns-3)"
    )
    interference_floor_db: float = Field(
        -20.0, description="under sinr, signals down to this SNR (dB) interfere though too weak to decode"
    )
    noise_band: Literal["carrier", "integrated"] | None = Field(
        None, description="noise PSD flat at the carrier or integrated over the band; default integrated under sinr"
    )
    overhead_s: NonNegFloat = Field(0.0, description="preamble / header time added to each packet (s)")
    tx_power_w: NonNegFloat | None = Field(None, description="modem power transmitting (W); all four: energy counted")
    rx_power_w: NonNegFloat | None = Field(None, description="modem power receiving (W)")
    idle_power_w: NonNegFloat | None = Field(None, description="modem power listening, idle (W)")
    sleep_power_w: NonNegFloat | None = Field(None, description="modem power asleep (W)")

    @model_validator(mode="before")
    @classmethod
    def _preset(cls, data: Any) -> Any:
        """A known ``modem`` fills the keys its preset sets that the file does not give."""
        from aquasim_py.channel.modem_presets import PRESETS

        if isinstance(data, dict) and isinstance(data.get("modem"), str) and data["modem"] in PRESETS:
            return {**PRESETS[data["modem"]].values(), **data}
        return data

    @field_validator("modem")
    @classmethod
    def _known_modem(cls, v: str | None) -> str | None:
        from aquasim_py.channel.modem_presets import PRESETS

        if v is not None and v not in PRESETS:
            raise ValueError(f"unknown modem {v!r} (known: {', '.join(PRESETS)}; list them: aquasim-py modems)")
        return v


# --------------------------------------------------------------------------- [[nodes]]
class UniformPlacement(Strict):
    kind: Literal["uniform"]
    lo: Vec3 | None = Field(None, description="sub-box lower corner (m); default the volume")
    hi: Vec3 | None = None


class GridPlacement(Strict):
    """``shape`` = points per axis, spread evenly from lo to hi inclusive (a single point sits
    in the middle of its axis); count = nx * ny * nz."""

    kind: Literal["grid"]
    shape: Annotated[list[PosInt], Field(min_length=3, max_length=3)]
    lo: Vec3 | None = None
    hi: Vec3 | None = None


class ExplicitPlacement(Strict):
    kind: Literal["explicit"]
    positions: Annotated[list[Vec3], Field(min_length=1)]


class RingPlacement(Strict):
    """``count`` nodes evenly spaced on a horizontal circle of ``radius_m`` around ``center``,
    the first on the +x side (e.g. many nodes at one distance from a receiver)."""

    kind: Literal["ring"]
    center: Vec3 = Field(description="centre of the circle (m); the nodes are at its depth")
    radius_m: PosFloat


PlacementSpec = Annotated[
    UniformPlacement | GridPlacement | ExplicitPlacement | RingPlacement, Field(discriminator="kind")
]


class MobilitySpec(BaseModel):
    """``model`` names an aquasim_py.mobility class; the other keys are its parameters, checked
    (names, finiteness) against the class constructor when the scenario is loaded."""

    model_config = ConfigDict(extra="allow", strict=True, allow_inf_nan=False)
    model: Literal[
        "static",
        "constant_velocity",
        "coordinated_turn",
        "random_walk",
        "kinematic",
        "meandering_jet",
        "meandering_current",  # deprecated alias of "kinematic"
        "waypoints",
        "noisy_constant_velocity",
    ] = "static"

    def params(self) -> dict[str, Any]:
        return dict(self.model_extra or {})


class ClockSpec(Strict):
    """Per-node clocks, local = (1 + skew) t + offset: each node draws skew ~ N(skew_ppm,
    skew_std_ppm) * 1e-6 and offset ~ N(offset_s, offset_std_s) from its own random stream."""

    skew_ppm: float = 0.0
    skew_std_ppm: NonNegFloat = 0.0
    offset_s: float = 0.0
    offset_std_s: NonNegFloat = 0.0
    drift_std_ppm: NonNegFloat = Field(0.0, description="std of each random-walk step of the skew (ppm)")
    drift_interval_s: PosFloat = 10.0
    jitter_std_s: NonNegFloat = Field(0.0, description="std of the clock read jitter (s)")


class SensorSpec(Strict):
    depth_noise_std_m: NonNegFloat = Field(0.0, description="depth gauge noise std (m)")
    velocity_noise_std_mps: NonNegFloat = Field(0.0, description="velocity sensor noise std per axis (m/s)")
    velocity_sensor: bool | None = Field(None, description="has a velocity sensor; default every role but target")
    position_noise_std_m: NonNegFloat = Field(0.0, description="position fix (GPS / survey) noise std per axis (m)")
    position_fix: bool | None = Field(None, description="knows its own position; default buoys and anchors only")


class BatterySpec(Strict):
    """A node's battery (aquasim_py.energy): the modem stops sending and receiving when the
    energy it has drawn reaches the capacity."""

    capacity_j: PosFloat = Field(description="energy available to the modem (J)")


class NodeGroupSpec(Strict):
    name: str | None = Field(None, description="group name (default group<i>); keys its random streams")
    role: Literal["buoy", "anchor", "ordinary", "target", "sink"]
    count: PosInt | None = Field(None, description="nodes in the group (default from the placement)")
    placement: PlacementSpec
    mobility: MobilitySpec = Field(default_factory=MobilitySpec)
    clock: ClockSpec = Field(default_factory=ClockSpec)
    sensors: SensorSpec = Field(default_factory=SensorSpec)
    protocol: str
    params: dict[str, Any] = Field(default_factory=dict, description="the protocol's parameters")
    battery: BatterySpec | None = Field(None, description="each node's battery; none: unlimited")
    mac: str | None = Field(
        None,
        description="the MAC of the group's nodes (aquasim_py.net.mac): direct, aloha, slotted_aloha, csma, "
        "sfama, tdma; unset: direct, and no net.* metrics unless a protocol asks for them",
    )
    mac_params: dict[str, Any] = Field(default_factory=dict, description="the MAC's parameters")
    routing: str | None = Field(
        None,
        description="the routing protocol of the group's nodes (aquasim_py.net.routing): flooding, vbf, hh_vbf, "
        "dbr, ...; unset: none (a unicast is one hop)",
    )
    routing_params: dict[str, Any] = Field(default_factory=dict, description="the routing protocol's parameters")

    @model_serializer(mode="wrap")
    def _without_unset_keys(self, handler: Any) -> Any:
        # a group without a battery, a MAC or a router resolves exactly as before they existed
        d = handler(self)
        if isinstance(d, dict):
            if d.get("battery") is None:
                d.pop("battery", None)
            for key in ("mac", "routing"):
                if d.get(key) is None:
                    d.pop(key, None)
                    if not d.get(f"{key}_params"):
                        d.pop(f"{key}_params", None)
        return d


# --------------------------------------------------------------------------- the rest
class TraceSpec(Strict):
    tables: list[str] | None = Field(None, description="tables to write; none = all")
    position_interval_s: PosFloat | None = Field(1.0, description="ground-truth position sampling (s)")
    format: Literal["csv", "parquet"] = "csv"


class OutputSpec(Strict):
    directory: str | None = Field(None, description="run output directory; default out/<scenario name>")


class SweepSpec(Strict):
    runs: PosInt = Field(1, description="Monte Carlo runs (seeds) per grid point")
    grid: dict[str, Annotated[list[Any], Field(min_length=1)]] = Field(default_factory=dict)


Role = Literal["buoy", "anchor", "ordinary", "target", "sink"]


def _unknown_by_default() -> list[Role]:
    return ["ordinary", "target"]


class MetricsSpec(Strict):
    percentiles: list[Annotated[float, Field(gt=0.0, le=100.0)]] = Field(default_factory=lambda: [50.0, 95.0])
    warmup_s: NonNegFloat = Field(0.0, description="estimates and clock rows before this time are ignored")
    unknown_roles: list[Role] = Field(
        default_factory=_unknown_by_default,
        description="roles of the evaluated nodes of the localization.* / sync.* metrics (docs/metrics.md)",
    )


class Scenario(Strict):
    description: str = ""
    simulation: SimulationSpec
    environment: EnvironmentSpec
    channel: ChannelSpec = Field(default_factory=ChannelSpec)
    nodes: Annotated[list[NodeGroupSpec], Field(min_length=1)]
    trace: TraceSpec = Field(default_factory=TraceSpec)
    output: OutputSpec = Field(default_factory=OutputSpec)
    sweep: SweepSpec | None = None
    metrics: MetricsSpec = Field(default_factory=MetricsSpec)
    variants: dict[str, dict[str, Any]] | None = Field(
        None,
        description="named override sets: variant name -> {quoted --set key path: TOML value}; "
        "checked (and each variant validated) by aquasim_py.scenario.load",
    )
