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
    snr_estimate_std_db: std (dB) of the Gaussian error of the receiver's SNR estimate, the
        ``Reception.snr_db`` a node gets (0 = the exact SNR); drawn by the kernel from the
        receiver's own ("node", id, "snr_estimate") stream. The ``packets`` trace and the drop
        decisions use the true SNR. Without noise a node could invert the loss model for its
        exact range.
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
        if self.detection_threshold_db is not None and not math.isfinite(self.detection_threshold_db):
            raise ValueError(
                f"ChannelConfig.detection_threshold_db must be finite, got {self.detection_threshold_db!r}"
            )

    def airtime(self, bits: Any) -> Any:
        """How long a packet of ``bits`` bits lasts on the air (s); elementwise on an array."""
        return bits / self.bitrate_bps


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
    channel config (alpha is what ``loss.path_loss_db`` computes itself when not given, 10 k
    the factor ``loss.spreading_loss_db`` applies: the same bits)."""
    from . import loss

    noise = loss.noise_psd_db(config.frequency_khz, config.shipping, config.wind_mps)
    alpha = loss.thorp_absorption_db_per_km(config.frequency_khz)
    k10 = 10.0 * loss._spreading_k(config.spreading)
    return noise, 10.0 * np.log10(np.asarray(config.bandwidth_khz * 1e3, dtype=float)), alpha, k10


def default_loss_model() -> LossModel:
    """The channel's default: :func:`physical_snr` (use :func:`no_snr` to disable SNR drops)."""
    return physical_snr
