"""Acoustic losses, ambient noise, SNR and the distance-dependent ToF noise.

Units are in every name: frequencies ``f_khz`` in kHz, lengths ``*_m`` in metres, levels in dB
(source level in dB re 1 uPa at 1 m, noise PSD in dB re 1 uPa^2/Hz), absorption in dB/km.
All functions are vectorized numpy and broadcast their arguments.

Formulas: Thorp's absorption and the Coates ambient-noise model in the form collected by
Stojanovic ("On the relationship between capacity and distance in an underwater acoustic
communication channel", 2007, eqs 3-8), and the path loss / ToF noise of Ramezani et al.
(IEEE TSP 2013) eqs 34-36.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "noise_band_db",
    "noise_psd_db",
    "noise_shipping_db",
    "noise_thermal_db",
    "noise_turbulence_db",
    "noise_wind_db",
    "path_loss_db",
    "snr_db",
    "spreading_loss_db",
    "thorp_absorption_db_per_km",
    "tof_noise_variance_derivative_s2_per_m",
    "tof_noise_variance_s2",
]

FloatArray = NDArray[np.float64]


def _freq(f_khz: ArrayLike) -> FloatArray:
    f = np.asarray(f_khz, dtype=float)
    if np.any(~(f > 0.0)):
        raise ValueError("frequency must be positive (kHz)")
    return f


def _spreading_k(k: float) -> float:
    k = float(k)
    if not 1.0 <= k <= 2.0:
        raise ValueError(f"spreading exponent k must be in [1, 2] (1 cylindrical, 2 spherical), got {k!r}")
    return k


def thorp_absorption_db_per_km(f_khz: ArrayLike) -> FloatArray:
    """Thorp absorption coefficient (dB/km) at frequency ``f_khz`` (kHz).

    10 log a(f) = 0.11 f^2/(1 + f^2) + 44 f^2/(4100 + f^2) + 2.75e-4 f^2 + 0.003
    (the last term is the low-frequency extension used for f below a few hundred Hz).
    """
    f2 = _freq(f_khz) ** 2
    return 0.11 * f2 / (1.0 + f2) + 44.0 * f2 / (4100.0 + f2) + 2.75e-4 * f2 + 0.003


def spreading_loss_db(length_m: ArrayLike, k: float = 1.5, l0_m: float = 1.0) -> FloatArray:
    """Geometric spreading loss 10 k log10(l / l0) (dB); k in [1, 2] (1.5: practical spreading)."""
    k = _spreading_k(k)
    with np.errstate(divide="ignore"):
        return 10.0 * k * np.log10(np.asarray(length_m, dtype=float) / l0_m)


def path_loss_db(
    length_m: ArrayLike,
    f_khz: ArrayLike,
    k: float = 1.5,
    l0_m: float = 1.0,
    absorption_db_per_km: ArrayLike | None = None,
) -> FloatArray:
    """Path loss A(l, f) in dB (Ramezani eq 35 in dB): 10 k log10(l/l0) + (l - l0) alpha(f).

    ``length_m`` is the travelled (ray) length, l0_m the reference length; alpha is Thorp's
    coefficient at ``f_khz`` unless ``absorption_db_per_km`` is given (the paper's Fig. 5 uses
    1 dB/km). As in eq 35 the absorption acts over l - l0, so A(l0, f) = 0 dB.

    Lengths below l0 are taken as l0 (A = 0 dB): the source level is defined at l0, inside it
    the far-field law does not hold, and co-located nodes (l = 0) would otherwise get an
    infinite SNR (docs/metrics.md).
    """
    alpha = (
        thorp_absorption_db_per_km(f_khz)
        if absorption_db_per_km is None
        else np.asarray(absorption_db_per_km, dtype=float)
    )
    length = np.maximum(np.asarray(length_m, dtype=float), l0_m)
    return spreading_loss_db(length, k, l0_m) + (length - l0_m) * 1e-3 * alpha


def noise_turbulence_db(f_khz: ArrayLike) -> FloatArray:
    """Turbulence noise PSD (dB re 1 uPa^2/Hz): 17 - 30 log10 f."""
    return 17.0 - 30.0 * np.log10(_freq(f_khz))


def noise_shipping_db(f_khz: ArrayLike, shipping: float = 0.5) -> FloatArray:
    """Shipping noise PSD (dB re 1 uPa^2/Hz), activity ``shipping`` in [0, 1]:
    40 + 20 (s - 0.5) + 26 log10 f - 60 log10(f + 0.03)."""
    s = float(shipping)
    if not 0.0 <= s <= 1.0:
        raise ValueError(f"shipping activity must be in [0, 1], got {shipping!r}")
    f = _freq(f_khz)
    return 40.0 + 20.0 * (s - 0.5) + 26.0 * np.log10(f) - 60.0 * np.log10(f + 0.03)


def noise_wind_db(f_khz: ArrayLike, wind_mps: float = 0.0) -> FloatArray:
    """Wind-driven surface noise PSD (dB re 1 uPa^2/Hz), wind speed in m/s:
    50 + 7.5 sqrt(w) + 20 log10 f - 40 log10(f + 0.4)."""
    w = float(wind_mps)
    if not w >= 0.0:
        raise ValueError(f"wind speed must be >= 0 m/s, got {wind_mps!r}")
    f = _freq(f_khz)
    return 50.0 + 7.5 * np.sqrt(w) + 20.0 * np.log10(f) - 40.0 * np.log10(f + 0.4)


def noise_thermal_db(f_khz: ArrayLike) -> FloatArray:
    """Thermal noise PSD (dB re 1 uPa^2/Hz): -15 + 20 log10 f."""
    return -15.0 + 20.0 * np.log10(_freq(f_khz))


def noise_psd_db(f_khz: ArrayLike, shipping: float = 0.5, wind_mps: float = 0.0) -> FloatArray:
    """Total ambient noise PSD (dB re 1 uPa^2/Hz): power sum of the four components."""
    parts = (
        noise_turbulence_db(f_khz),
        noise_shipping_db(f_khz, shipping),
        noise_wind_db(f_khz, wind_mps),
        noise_thermal_db(f_khz),
    )
    return 10.0 * np.log10(sum(10.0 ** (p / 10.0) for p in parts))


#: Gauss-Legendre nodes and weights on [-1, 1] for the band integral (in log frequency, where
#: every component is a smooth function: 64 nodes integrate it to ~1e-14 relative, tests)
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(64)


def noise_band_db(f_lo_khz: float, f_hi_khz: float, shipping: float = 0.5, wind_mps: float = 0.0) -> float:
    """Ambient noise power in the band [f_lo, f_hi] (dB re 1 uPa^2): 10 log10 of the integral of
    the PSD :func:`noise_psd_db` over the band, in Hz.

    The integral is taken in u = ln f (df = f du), where the four components are smooth, by
    64-point Gauss-Legendre quadrature. For a narrow band it tends to N(f_c) + 10 log10 B, the
    flat-at-the-carrier approximation :func:`snr_db` makes; over a wide band the PSD's slope
    (about -17 dB/decade above a few kHz) makes the two differ (docs/network.md)."""
    lo, hi = float(f_lo_khz), float(f_hi_khz)
    if not 0.0 < lo < hi:
        raise ValueError(f"the band must satisfy 0 < f_lo < f_hi (kHz), got [{lo!r}, {hi!r}]")
    a, b = np.log(lo), np.log(hi)
    u = 0.5 * (b - a) * _GL_NODES + 0.5 * (b + a)
    f_khz = np.exp(u)
    psd = 10.0 ** (noise_psd_db(f_khz, shipping, wind_mps) / 10.0)  # uPa^2 / Hz
    power = 0.5 * (b - a) * float(np.sum(_GL_WEIGHTS * psd * f_khz * 1e3))  # uPa^2 (df in Hz)
    return 10.0 * float(np.log10(power))


def snr_db(
    source_level_db: ArrayLike,
    length_m: ArrayLike,
    f_khz: ArrayLike,
    bandwidth_hz: ArrayLike,
    k: float = 1.5,
    shipping: float = 0.5,
    wind_mps: float = 0.0,
    l0_m: float = 1.0,
) -> FloatArray:
    """Narrow-band SNR (dB) at the receiver: SL - A(l, f) - N(f) - 10 log10(B).

    ``source_level_db`` in dB re 1 uPa at 1 m (so the path loss is referenced to l0 = 1 m),
    ``length_m`` the ray length, ``f_khz`` the carrier, ``bandwidth_hz`` the receiver bandwidth
    (noise PSD taken flat over B at the carrier).
    """
    bw = np.asarray(bandwidth_hz, dtype=float)
    if np.any(~(bw > 0.0)):
        raise ValueError("bandwidth must be positive (Hz)")
    return (
        np.asarray(source_level_db, dtype=float)
        - path_loss_db(length_m, f_khz, k, l0_m)
        - noise_psd_db(f_khz, shipping, wind_mps)
        - 10.0 * np.log10(bw)
    )


def _absorption_per_m_ln(f_khz: ArrayLike | None, absorption_db_per_km: ArrayLike | None) -> FloatArray:
    """ln L(f) per metre, L(f) the linear absorption factor of eq 35."""
    if absorption_db_per_km is None:
        if f_khz is None:
            raise ValueError("give f_khz (Thorp) or absorption_db_per_km")
        alpha = thorp_absorption_db_per_km(f_khz)
    else:
        alpha = np.asarray(absorption_db_per_km, dtype=float)
    return alpha * 1e-3 * np.log(10.0) / 10.0


def tof_noise_variance_s2(
    length_m: ArrayLike,
    k_e_s2: ArrayLike,
    f_khz: ArrayLike | None = None,
    k: float = 2.0,
    l0_m: float = 1.0,
    absorption_db_per_km: ArrayLike | None = None,
) -> FloatArray:
    """Distance-dependent ToF noise variance (s^2), Ramezani eq 34: sigma^2 = K_E A(l, f),
    with the linear path loss A = (l/l0)^k L(f)^(l - l0) of eq 35.

    ``k_e_s2`` is K_E in s^2 (the paper's K_E = -10 dB means 0.1); L(f) from Thorp at ``f_khz``
    unless ``absorption_db_per_km`` is given.
    """
    k = _spreading_k(k)
    ln_l = _absorption_per_m_ln(f_khz, absorption_db_per_km)
    length = np.asarray(length_m, dtype=float)
    return np.asarray(k_e_s2, dtype=float) * (length / l0_m) ** k * np.exp((length - l0_m) * ln_l)


def tof_noise_variance_derivative_s2_per_m(
    length_m: ArrayLike,
    k_e_s2: ArrayLike,
    f_khz: ArrayLike | None = None,
    k: float = 2.0,
    l0_m: float = 1.0,
    absorption_db_per_km: ArrayLike | None = None,
) -> FloatArray:
    """d sigma^2 / d l (s^2/m), Ramezani eq 36 without the chain factor d l / d x_i:
    K_E l^(k-1) / l0^k L(f)^(l - l0) (k + l ln L(f)) = sigma^2 (k / l + ln L(f))."""
    ln_l = _absorption_per_m_ln(f_khz, absorption_db_per_km)
    length = np.asarray(length_m, dtype=float)
    var = tof_noise_variance_s2(length, k_e_s2, f_khz, k, l0_m, absorption_db_per_km)
    return var * (k / length + ln_l)
