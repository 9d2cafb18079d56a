"""The acoustic modem's and channel's parameters, and the SNR (loss) models.

Plain numpy: no SimPy, no kernel. :class:`ChannelConfig` is what the ``[channel]`` table of a
scenario becomes; a :data:`LossModel` maps the eigenrays of one transmission to an SNR per
receiver.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from .obstacles import ObstacleConfig
from .phy import ErrorModel, PerTable
from .rays import Eigenray

__all__ = ["ChannelConfig", "LossModel", "default_loss_model", "no_snr", "physical_snr"]


@dataclass(frozen=True)
class ChannelConfig:
    """Acoustic modem and channel parameters.

    max_range_m: straight-line range (m) at send time beyond which a node hears nothing.
    bitrate_bps: modem bit rate; a packet of b bits lasts b / bitrate_bps seconds.
    source_level_db: source level (dB re 1 uPa at 1 m), for the loss model.
    frequency_khz, bandwidth_khz: carrier and band, for the loss model.
    spreading: spreading exponent k (1 cylindrical, 1.5 practical, 2 spherical).
    shipping, wind_mps: ambient noise parameters (shipping activity 0..1, wind speed m/s).
    snr_threshold_db: receptions below this SNR are dropped ("snr").
    collision: "none" (signals never interfere), "destructive" (any overlap destroys both),
        "capture" (a signal survives if its SNR beats the summed power of the signals overlapping
        it by capture_threshold_db; without an SNR model nothing can be captured, so "capture"
        then acts as "destructive").
    jitter_std_s: std of Gaussian MAC timestamp jitter (s), on top of the clock's own.
    reflections: passed to ``eigenray`` ("none", "fallback", "all").
    pressure_kind: packets of this kind are sound emissions: each reception carries the received
        pressure (``channel.pressure``, eq 6 of MSWPF) plus N(0, pressure_noise_std^2) drawn from
        the receiver's ("node", id, "pressure") stream; None = off.
    pressure_source_level, pressure_exponent: S and k of h = S / D^k.
    obstacles: obstructed links' extra loss and excess delay (``channel.obstacles``; the random
        part of the delay is drawn per packet from each link's own stream); None = none.
    sound_speed_std_mps, sound_speed_corr_s: sound-speed uncertainty (channel/uncertainty.py):
        std (m/s) of the path-mean speed around the profile, and its per-link correlation time
        (s; 0 = independent per packet). std 0 leaves the channel exactly as without it.
    max_bounces, detection_threshold_db: a range-dependent environment only
        (:mod:`.arrival_links`): the arrivals of a link are its eigenrays with at most
        ``max_bounces`` surface + bottom bounces, and the modem stamps the first whose SNR
        reaches ``detection_threshold_db`` (None: ``snr_threshold_db``, so the arrival it
        synchronizes on is one it can decode from). direct_only: an analysis switch, not a
        modem: a reception whose stamped arrival is not a direct or refracted one is lost
        ("indirect"), to measure what blocked and weak direct paths cost a protocol.
        follow_radius_m: the arrival cache's following radius (m; :mod:`.arrival_links`): a
        link's eigenrays are followed while each end stays within it of where the link was last
        searched, then searched again; 0 searches at every request. Larger is faster on drifting
        nodes and lacks more often a path that appeared since the search (docs/channel.md).
    snr_estimate_std_db: std (dB) of the Gaussian error of the receiver's SNR estimate, the
        ``Reception.snr_db`` a node gets (0 = the exact SNR); drawn by the kernel from the
        receiver's own ("node", id, "snr_estimate") stream. The ``packets`` trace and the drop
        decisions use the true SNR. Without noise a node could invert the loss model for its
        exact range.

    The physical layer (docs/network.md; :mod:`.phy`, :mod:`.sinr`):

    reception: how a reception is decided. "threshold": the SNR threshold and the ``collision``
        rule above (the default). "sinr": from the SINR over the packet in pieces (every
        overlapping signal plus the noise), the modulation's bit errors and a packet-error draw
        from the receiver's own ("node", id, "per") stream; ``collision`` and
        ``capture_threshold_db`` do not apply.
    modulation, modulation_order, coding_gain_db: the bit error model of "sinr" (:mod:`.phy`:
        "bpsk", "qpsk", "bfsk" non-coherent, "mfsk" non-coherent of order M, or "table").
    per_table, per_table_bits: "table": ((sinr_db, per), ...) measured on packets of
        per_table_bits bits.
    lock: the acquisition rule of "sinr". A signal is acquired when its SINR at its first bit
        reaches snr_threshold_db while the receiver is not transmitting; "first": a receiver
        that has acquired a packet acquires no other until its last bit (ns-3's UanPhyGen);
        "relock": a later signal acquired meanwhile takes the receiver over (the first is
        lost); "none": every signal is demodulated on its own, as by a receiver per arrival.
    per_combining: "pieces": PER = 1 - prod_k (1 - BER_k)^bits_k over the SINR pieces;
        "worst": every bit at the lowest piece's SINR (ns-3's UanPhyGen).
    interference_floor_db: under "sinr", signals whose SNR is at or above this (dB) but below
        snr_threshold_db are still recorded at the receiver, where they interfere (weaker ones
        are neglected: each adds less than 10^(floor/10) of the noise power).
    noise_band: "carrier": the noise PSD at the carrier, flat over the band (N(f_c) + 10 log10
        B); "integrated": the PSD integrated over [f_c - B/2, f_c + B/2] (loss.noise_band_db).
        None: "integrated" under "sinr", "carrier" under "threshold".
    overhead_s: preamble and header time added to each packet's airtime (s).
    modem: the preset these figures came from (:mod:`.modem_presets`), for the record.
    tx_power_w, rx_power_w, idle_power_w, sleep_power_w: the modem's power (W) by state; all
        four given: the kernel counts each node's energy (aquasim_py.energy); None: not counted.
    """

    max_range_m: float = 5000.0
    bitrate_bps: float = 1000.0
    source_level_db: float = 170.0
    frequency_khz: float = 10.0
    bandwidth_khz: float = 5.0
    spreading: float = 1.5
    shipping: float = 0.5
    wind_mps: float = 0.0
    snr_threshold_db: float = 10.0
    collision: Literal["none", "destructive", "capture"] = "destructive"
    capture_threshold_db: float = 6.0
    jitter_std_s: float = 0.0
    reflections: Literal["none", "fallback", "all"] = "fallback"
    pressure_kind: str | None = None
    pressure_source_level: float = 5e4
    pressure_exponent: float = 1.0
    pressure_noise_std: float = 5.0
    obstacles: ObstacleConfig | None = None
    sound_speed_std_mps: float = 0.0
    sound_speed_corr_s: float = 0.0
    snr_estimate_std_db: float = 1.0
    max_bounces: int = 2
    detection_threshold_db: float | None = None
    direct_only: bool = False
    follow_radius_m: float = 1.0
    reception: Literal["threshold", "sinr"] = "threshold"
    modulation: str = "bfsk"
    modulation_order: int = 2
    coding_gain_db: float = 0.0
    per_table: tuple[tuple[float, float], ...] | None = None
    per_table_bits: int = 256
    lock: Literal["first", "relock", "none"] = "first"
    per_combining: Literal["pieces", "worst"] = "pieces"
    interference_floor_db: float = -20.0
    noise_band: Literal["carrier", "integrated"] | None = None
    overhead_s: float = 0.0
    modem: str | None = None
    tx_power_w: float | None = None
    rx_power_w: float | None = None
    idle_power_w: float | None = None
    sleep_power_w: float | None = None

    def __post_init__(self) -> None:
        for name in ("max_range_m", "bitrate_bps", "frequency_khz", "bandwidth_khz"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"ChannelConfig.{name} must be positive and finite, got {v!r}")
        if self.collision not in ("none", "destructive", "capture"):
            raise ValueError(f"ChannelConfig.collision must be none/destructive/capture, got {self.collision!r}")
        if self.reflections not in ("none", "fallback", "all"):
            raise ValueError(f"ChannelConfig.reflections must be none/fallback/all, got {self.reflections!r}")
        if not self.jitter_std_s >= 0.0:
            raise ValueError(f"ChannelConfig.jitter_std_s must be >= 0, got {self.jitter_std_s!r}")
        if not (self.sound_speed_std_mps >= 0.0 and self.sound_speed_corr_s >= 0.0):
            raise ValueError("ChannelConfig.sound_speed_std_mps and sound_speed_corr_s must be >= 0")
        if not (math.isfinite(self.snr_estimate_std_db) and self.snr_estimate_std_db >= 0.0):
            raise ValueError(f"ChannelConfig.snr_estimate_std_db must be >= 0, got {self.snr_estimate_std_db!r}")
        if not (isinstance(self.max_bounces, int) and 0 <= self.max_bounces <= 20):
            raise ValueError(f"ChannelConfig.max_bounces must be an integer in 0..20, got {self.max_bounces!r}")
        if not (math.isfinite(self.follow_radius_m) and self.follow_radius_m >= 0.0):
            raise ValueError(f"ChannelConfig.follow_radius_m must be >= 0 and finite, got {self.follow_radius_m!r}")
        if self.detection_threshold_db is not None and not math.isfinite(self.detection_threshold_db):
            raise ValueError(
                f"ChannelConfig.detection_threshold_db must be finite, got {self.detection_threshold_db!r}"
            )
        if self.reception not in ("threshold", "sinr"):
            raise ValueError(f"ChannelConfig.reception must be threshold/sinr, got {self.reception!r}")
        if self.lock not in ("first", "relock", "none"):
            raise ValueError(f"ChannelConfig.lock must be first/relock/none, got {self.lock!r}")
        if self.per_combining not in ("pieces", "worst"):
            raise ValueError(f"ChannelConfig.per_combining must be pieces/worst, got {self.per_combining!r}")
        if self.noise_band not in (None, "carrier", "integrated"):
            raise ValueError(f"ChannelConfig.noise_band must be carrier/integrated, got {self.noise_band!r}")
        if not (math.isfinite(self.overhead_s) and self.overhead_s >= 0.0):
            raise ValueError(f"ChannelConfig.overhead_s must be >= 0, got {self.overhead_s!r}")
        if not math.isfinite(self.interference_floor_db):
            raise ValueError(f"ChannelConfig.interference_floor_db must be finite, got {self.interference_floor_db!r}")
        if self.noise_integrated and not self.bandwidth_khz < 2.0 * self.frequency_khz:
            raise ValueError(
                f"ChannelConfig: the band ({self.bandwidth_khz} kHz wide around {self.frequency_khz} kHz) must lie "
                "above 0 Hz to integrate the noise over it"
            )
        powers = (self.tx_power_w, self.rx_power_w, self.idle_power_w, self.sleep_power_w)
        if any(p is not None for p in powers):
            if any(p is None for p in powers):
                raise ValueError("ChannelConfig: give all four modem powers (tx, rx, idle, sleep) or none")
            if not all(p is not None and math.isfinite(p) and p >= 0.0 for p in powers):
                raise ValueError(f"ChannelConfig: modem powers must be >= 0 W, got {powers!r}")
        self.error_model()  # checks the modulation and its table

    @property
    def noise_integrated(self) -> bool:
        """Whether the ambient noise is the PSD integrated over the band (``noise_band``)."""
        if self.noise_band is None:
            return self.reception == "sinr"
        return self.noise_band == "integrated"

    def error_model(self) -> ErrorModel:
        """The bit error model of the "sinr" reception (:class:`.phy.ErrorModel`)."""
        table = None
        if self.modulation == "table" and self.per_table is not None:
            table = PerTable(tuple((float(x), float(y)) for x, y in self.per_table), self.per_table_bits)
        return ErrorModel(
            self.modulation,
            self.modulation_order,
            self.bandwidth_khz * 1e3,
            self.bitrate_bps,
            self.coding_gain_db,
            table,
        )

    @property
    def powers(self) -> tuple[float, float, float, float] | None:
        """(tx, rx, idle, sleep) power of the modem (W), or None when energy is not counted."""
        p = (self.tx_power_w, self.rx_power_w, self.idle_power_w, self.sleep_power_w)
        return None if p[0] is None else p  # type: ignore[return-value]

    def airtime(self, bits: Any) -> Any:
        """How long a packet of ``bits`` bits lasts on the air (s), the preamble / header time
        ``overhead_s`` included; elementwise on an array."""
        return bits / self.bitrate_bps + self.overhead_s


#: An SNR model: (eigenrays to the receivers, config) -> SNR in dB per receiver (NaN = unknown,
#: never dropped).
LossModel = Callable[[Eigenray, ChannelConfig], NDArray[np.float64]]


def no_snr(ray: Eigenray, config: ChannelConfig) -> NDArray[np.float64]:
    """The null loss model: SNR unknown (NaN), so nothing is dropped on SNR."""
    return np.full(np.shape(ray.time), np.nan)


def physical_snr(ray: Eigenray, config: ChannelConfig) -> NDArray[np.float64]:
    """SNR (dB) along each eigenray: SL - A(l, f) - N(f) - 10 log10 B (``channel.loss.snr_db``),
    with l the ray's arc length and the config's source level, carrier, band, spreading
    exponent and ambient-noise parameters.

    The same terms in the same order as ``loss.snr_db`` (so the same bits), with the two that
    depend only on the config (ambient noise N(f) and 10 log10 B) computed once per config:
    the noise sum is the costliest part and this runs once per transmission."""
    return _snr_of_length(np.asarray(ray.length, dtype=float), config)


def _snr_of_length(length: NDArray[np.float64], config: ChannelConfig) -> NDArray[np.float64]:
    """:func:`physical_snr` (dB) of rays of arc lengths ``length`` (m)."""
    noise, band, alpha, k10 = _snr_constants(config)
    # loss.path_loss_db(l, f, k, l0 = 1, alpha) term by term (the same operations, so the same
    # bits): 10 k log10(max(l, l0) / l0) + (max(l, l0) - l0) 1e-3 alpha, with l / 1.0 = l and
    # no divide-by-zero guard needed since max(l, 1) >= 1 (NaN stays NaN)
    length = np.maximum(length, 1.0)
    loss_db = k10 * np.log10(length) + (length - 1.0) * 1e-3 * alpha
    return config.source_level_db - loss_db - noise - band


@lru_cache(maxsize=64)
def _snr_constants(
    config: ChannelConfig,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float]:
    """(N(f) in dB re 1 uPa^2/Hz, 10 log10 B in dB-Hz, Thorp's alpha(f) in dB/km, 10 k) of a
    channel config (the noise integrated over the band: its power in dB re 1 uPa^2, and 0) (alpha is what ``loss.path_loss_db`` computes itself when not given, 10 k
    the factor ``loss.spreading_loss_db`` applies: the same bits)."""
    from . import loss

    alpha = loss.thorp_absorption_db_per_km(config.frequency_khz)
    k10 = 10.0 * loss._spreading_k(config.spreading)
    if config.noise_integrated:
        # the noise power in the band [f_c - B/2, f_c + B/2], the band's 10 log10 B folded into it
        f, half = config.frequency_khz, config.bandwidth_khz / 2.0
        power = loss.noise_band_db(f - half, f + half, config.shipping, config.wind_mps)
        return np.asarray(power), np.asarray(0.0), alpha, k10
    noise = loss.noise_psd_db(config.frequency_khz, config.shipping, config.wind_mps)
    return noise, 10.0 * np.log10(np.asarray(config.bandwidth_khz * 1e3, dtype=float)), alpha, k10


def default_loss_model() -> LossModel:
    """The channel's default: :func:`physical_snr` (use :func:`no_snr` to disable SNR drops)."""
    return physical_snr
