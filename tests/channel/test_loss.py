"""Losses, noise, SNR and ToF noise against hand-computed values and basic physics.

The literal reference numbers below were computed separately with Python's ``decimal`` module
at 30 significant digits from the published formulas (Thorp; Coates/Stojanovic noise), not
with the package:
  Thorp(1 kHz)  = 0.0690040904657400634 dB/km
  Thorp(10 kHz) = 1.18702993870815653 dB/km
  Thorp(25 kHz) = 6.10480510125597985 dB/km
  noise at 10 kHz, s = 0.5, w = 0: turbulence -13, shipping 5.92194401877491287,
      wind 29.3186664280487858, thermal 5, total 29.3547035742348511 dB re 1 uPa^2/Hz
  noise at 1 kHz, s = 1, w = 4 m/s: shipping 49.2297665176896677, wind 59.1548785728704790,
      total 59.5759071803823615
"""

from __future__ import annotations

import numpy as np
import pytest

from aquasim_py.channel import loss


def test_thorp_hand_values() -> None:
    got = loss.thorp_absorption_db_per_km([1.0, 10.0, 25.0])
    np.testing.assert_allclose(got, [0.0690040904657400634, 1.18702993870815653, 6.10480510125597985], rtol=1e-14)


def test_thorp_monotone_increasing() -> None:
    f = np.geomspace(0.01, 1000.0, 2000)
    assert np.all(np.diff(loss.thorp_absorption_db_per_km(f)) > 0.0)


def test_noise_hand_values() -> None:
    assert loss.noise_turbulence_db(10.0) == pytest.approx(-13.0, abs=1e-13)
    assert loss.noise_shipping_db(10.0, 0.5) == pytest.approx(5.92194401877491287, abs=1e-12)
    assert loss.noise_wind_db(10.0, 0.0) == pytest.approx(29.3186664280487858, abs=1e-12)
    assert loss.noise_thermal_db(10.0) == pytest.approx(5.0, abs=1e-13)
    assert loss.noise_psd_db(10.0, 0.5, 0.0) == pytest.approx(29.3547035742348511, abs=1e-12)
    assert loss.noise_shipping_db(1.0, 1.0) == pytest.approx(49.2297665176896677, abs=1e-12)
    assert loss.noise_wind_db(1.0, 4.0) == pytest.approx(59.1548785728704790, abs=1e-12)
    assert loss.noise_psd_db(1.0, 1.0, 4.0) == pytest.approx(59.5759071803823615, abs=1e-12)


def test_noise_monotone_in_activity_and_wind_and_above_components() -> None:
    f = np.geomspace(0.05, 200.0, 300)
    assert np.all(np.diff([loss.noise_psd_db(f, s) for s in np.linspace(0, 1, 6)], axis=0) > 0.0)
    assert np.all(np.diff([loss.noise_psd_db(f, 0.5, w) for w in (0.0, 1.0, 5.0, 15.0)], axis=0) > 0.0)
    total = loss.noise_psd_db(f, 0.3, 2.0)
    for part in (
        loss.noise_turbulence_db(f),
        loss.noise_shipping_db(f, 0.3),
        loss.noise_wind_db(f, 2.0),
        loss.noise_thermal_db(f),
    ):
        assert np.all(total >= part)
    # the thermal floor dominates far above 100 kHz, turbulence far below 10 Hz
    assert loss.noise_psd_db(1e4, 0.5, 0.0) == pytest.approx(loss.noise_thermal_db(1e4), abs=0.01)
    assert loss.noise_psd_db(1e-3, 0.5, 0.0) == pytest.approx(loss.noise_turbulence_db(1e-3), abs=0.1)


def test_path_loss_eq35_and_spreading() -> None:
    # 10 * 1.5 * log10(1000) + 0.999 km * Thorp(10 kHz)
    assert loss.path_loss_db(1000.0, 10.0, k=1.5) == pytest.approx(45.0 + 0.999 * 1.18702993870815653, rel=1e-14)
    assert loss.spreading_loss_db(100.0, k=2.0) == pytest.approx(40.0, rel=1e-15)
    assert loss.spreading_loss_db(100.0, k=1.0) == pytest.approx(20.0, rel=1e-15)
    # reference length: no loss; given absorption overrides Thorp
    assert loss.path_loss_db(1000.0, 10.0, k=2.0, l0_m=1000.0) == 0.0
    assert loss.path_loss_db(3000.0, 10.0, k=2.0, l0_m=1000.0, absorption_db_per_km=1.0) == pytest.approx(
        20.0 * np.log10(3.0) + 2.0, rel=1e-14
    )
    # monotone in distance, frequency and k
    l = np.geomspace(1.0, 1e5, 400)
    assert np.all(np.diff(loss.path_loss_db(l, 20.0)) > 0.0)
    assert np.all(np.diff(loss.path_loss_db(5000.0, np.geomspace(0.1, 100, 100))) > 0.0)
    assert loss.path_loss_db(5000.0, 10.0, k=1.0) < loss.path_loss_db(5000.0, 10.0, k=2.0)


@pytest.mark.parametrize("k", [0.99, 2.01, -1.0, float("nan")])
def test_spreading_exponent_bounds(k: float) -> None:
    with pytest.raises(ValueError):
        loss.spreading_loss_db(100.0, k=k)
    with pytest.raises(ValueError):
        loss.path_loss_db(100.0, 10.0, k=k)
    with pytest.raises(ValueError):
        loss.tof_noise_variance_s2(100.0, 0.1, 10.0, k=k)


def test_invalid_inputs() -> None:
    with pytest.raises(ValueError):
        loss.noise_shipping_db(10.0, 1.5)
    with pytest.raises(ValueError):
        loss.noise_wind_db(10.0, -1.0)
    with pytest.raises(ValueError):
        loss.thorp_absorption_db_per_km([10.0, 0.0])
    with pytest.raises(ValueError):
        loss.snr_db(180.0, 1000.0, 10.0, 0.0)
    with pytest.raises(ValueError):
        loss.tof_noise_variance_s2(100.0, 0.1)  # neither frequency nor absorption


def test_snr_budget() -> None:
    # 180 - (45 + 0.999 * Thorp(10)) - 29.3547035742348511 - 10 log10(1000)
    expected = 180.0 - (45.0 + 0.999 * 1.18702993870815653) - 29.3547035742348511 - 30.0
    assert loss.snr_db(180.0, 1000.0, 10.0, 1000.0) == pytest.approx(expected, abs=1e-11)
    snr = loss.snr_db(170.0, np.geomspace(10, 2e4, 50), 12.0, 4000.0)
    assert np.all(np.diff(snr) < 0.0)
    # 10 dB more source level, 10 dB more SNR; 10x bandwidth, 10 dB less
    assert loss.snr_db(190.0, 800.0, 12.0, 4000.0) - loss.snr_db(180.0, 800.0, 12.0, 4000.0) == pytest.approx(10.0)
    assert loss.snr_db(180.0, 800.0, 12.0, 400.0) - loss.snr_db(180.0, 800.0, 12.0, 4000.0) == pytest.approx(10.0)


def test_tof_noise_eq34_paper_setting() -> None:
    """Paper's Fig. 5 setting: K_E = -10 dB, beta = 2, L(f) = 1 dB/km, l_r = 1000 m."""
    var = loss.tof_noise_variance_s2(2000.0, 0.1, k=2.0, l0_m=1000.0, absorption_db_per_km=1.0)
    # 0.1 * (2000/1000)^2 * 10^(1 dB/km * 1 km / 10)
    assert var == pytest.approx(0.1 * 4.0 * 10.0**0.1, rel=1e-14)
    assert loss.tof_noise_variance_s2(1000.0, 0.1, k=2.0, l0_m=1000.0, absorption_db_per_km=1.0) == pytest.approx(0.1)
    # same number as the dB path loss
    assert 10 * np.log10(var / 0.1) == pytest.approx(
        loss.path_loss_db(2000.0, None, k=2.0, l0_m=1000.0, absorption_db_per_km=1.0), rel=1e-13
    )


def test_tof_noise_derivative_eq36_and_finite_differences() -> None:
    l = np.array([50.0, 900.0, 2500.0, 7000.0])
    for kw in ({"f_khz": 15.0, "k": 1.5}, {"absorption_db_per_km": 1.0, "k": 2.0, "l0_m": 1000.0}):
        d = loss.tof_noise_variance_derivative_s2_per_m(l, 0.1, **kw)
        # eq 36 literally: K_E l^(b-1) / l0^b L^(l - l0) (b + l ln L), L = 10^(alpha[dB/m]/10)
        alpha = kw.get("absorption_db_per_km") or float(loss.thorp_absorption_db_per_km(15.0))
        L = 10.0 ** (alpha * 1e-3 / 10.0)
        b, l0 = kw["k"], kw.get("l0_m", 1.0)
        eq36 = 0.1 * l ** (b - 1) / l0**b * L ** (l - l0) * (b + l * np.log(L))
        np.testing.assert_allclose(d, eq36, rtol=1e-12)
        h = 1e-3
        fd = (loss.tof_noise_variance_s2(l + h, 0.1, **kw) - loss.tof_noise_variance_s2(l - h, 0.1, **kw)) / (2 * h)
        np.testing.assert_allclose(d, fd, rtol=1e-7)
