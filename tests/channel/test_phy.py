"""The PHY's maths (aquasim_py.channel.phy, loss.noise_band_db) against independent references:
bit error rates against a Monte Carlo of each modulation (symbols through AWGN and a
demodulator, tests/channel/modem_mc.py), the SINR pieces against a brute-force sweep, packet
errors against the product over pieces, the band noise against scipy's adaptive quadrature."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st
from modem_mc import ber_fsk_nc, ber_psk
from scipy.integrate import quad

from aquasim_py.channel import loss
from aquasim_py.channel.phy import (
    ErrorModel,
    PerTable,
    ber_bfsk_nc,
    ber_bpsk,
    ber_mfsk_nc,
    ber_qpsk,
    packet_error,
    sinr_pieces,
)

#: Eb/N0 (dB) of the check: 0 to 15 dB in 1 dB steps
EBN0_DB = list(range(16))
#: trials per point
N_MC = 20_000
#: the band each estimate must fall in: Z standard errors. 64 points (4 modulations x 16);
#: a two-sided 4-sigma band misses with probability 6.3e-5 each, 0.4 % for the family
Z = 4.0


def _mc(name: str, db: float, rng: np.random.Generator) -> tuple[float, float]:
    if name == "bpsk":
        return ber_psk(db, N_MC, rng)
    if name == "qpsk":
        return ber_psk(db, N_MC, rng, qpsk=True)
    if name == "bfsk":
        return ber_fsk_nc(db, 2, N_MC, rng)
    return ber_fsk_nc(db, 4, N_MC, rng)


CLOSED = {
    "bpsk": ber_bpsk,
    "qpsk": ber_qpsk,
    "bfsk": ber_bfsk_nc,
    "4fsk": lambda g: ber_mfsk_nc(g, 4),
}


@pytest.mark.parametrize("name", list(CLOSED))
def test_closed_form_ber_within_the_monte_carlo_interval(name: str) -> None:
    """Each closed form lies within Z standard errors of the Monte Carlo estimate at every Eb/N0
    from 0 to 15 dB (BER from 0.3 down to 1e-15: importance sampling, see modem_mc)."""
    rng = np.random.default_rng(20240 + len(name))
    for db in EBN0_DB:
        est, se = _mc(name, db, rng)
        ref = CLOSED[name](10.0 ** (db / 10.0))
        assert se > 0.0 and se < 0.25 * est, (name, db, est, se)  # an interval that says something
        assert abs(est - ref) <= Z * se, (name, db, est, ref, se)


def test_the_check_rejects_a_wrong_formula() -> None:
    """The same check has the power to fail: coherent BFSK's BER, Q(sqrt(Eb/N0)), is not the
    non-coherent demodulator's, and is rejected from 4 dB up."""
    rng = np.random.default_rng(7)
    for db in (4, 8, 12):
        est, se = ber_fsk_nc(db, 2, N_MC, rng)
        coherent = 0.5 * math.erfc(math.sqrt(10.0 ** (db / 10.0) / 2.0))
        assert abs(est - coherent) > Z * se


def test_mfsk_of_order_two_is_bfsk() -> None:
    for g in (0.1, 1.0, 10.0, 40.0):
        assert ber_mfsk_nc(g, 2) == pytest.approx(ber_bfsk_nc(g), rel=1e-14)


def test_error_model_scales_sinr_to_eb_n0_and_adds_the_coding_gain() -> None:
    m = ErrorModel("bpsk", bandwidth_hz=4000.0, bitrate_bps=1000.0, coding_gain_db=3.0)
    assert m.bit_error(2.0) == pytest.approx(ber_bpsk(2.0 * 4.0 * 10.0**0.3), rel=1e-14)
    with pytest.raises(ValueError, match="power of 2"):
        ErrorModel("mfsk", order=6)


def test_per_table_gives_its_per_back_and_scales_with_length() -> None:
    t = PerTable(((0.0, 1.0), (5.0, 0.5), (10.0, 0.0)), bits=200)
    m = ErrorModel("table", table=t)
    assert packet_error(m, ((10.0 ** (2.5 / 10.0), 200.0),)) == pytest.approx(0.75, rel=1e-12)
    # twice the bits at the same SINR: 1 - (1 - PER)^2
    assert packet_error(m, ((10.0**0.5, 400.0),)) == pytest.approx(1.0 - 0.5**2, rel=1e-12)
    assert packet_error(m, ((1e3, 400.0),)) == 0.0 and packet_error(m, ((0.1, 1.0),)) == 1.0
    with pytest.raises(ValueError, match="increase"):
        PerTable(((1.0, 0.5), (1.0, 0.2)), bits=8)


def test_packet_error_is_the_product_over_pieces() -> None:
    m = ErrorModel("bfsk", bandwidth_hz=5000.0, bitrate_bps=1000.0)
    pieces = [(0.5, 100.0), (3.0, 50.0), (1.2, 106.0)]
    want = 1.0 - math.prod((1.0 - m.bit_error(s)) ** b for s, b in pieces)
    assert packet_error(m, pieces) == pytest.approx(want, rel=1e-12)
    # a tiny PER keeps its digits (no 1 - (1 - x) cancellation)
    tiny = packet_error(m, ((30.0, 8.0),))
    assert tiny == pytest.approx(8.0 * m.bit_error(30.0), rel=1e-6) and tiny > 0.0


@given(
    st.lists(
        st.tuples(st.floats(-2.0, 3.0), st.floats(0.01, 3.0), st.floats(0.01, 100.0)),
        max_size=6,
    ),
    st.floats(0.05, 5.0),
)
@example([(0.0, 1.0, 1.0)] * 3 + [(0.0, 0.010000000000000002, 1.0), (0.0, 0.01, 1.0)], 1.0)
def test_sinr_pieces_match_a_brute_force(others: list[tuple[float, float, float]], noise: float) -> None:
    """The pieces tile [0, 1) and each one's SINR is the power over the noise plus every
    interferer present at its middle."""
    spans = [(a, a + d, p) for a, d, p in others]
    pieces = sinr_pieces(0.0, 1.0, 7.0, spans, noise)
    assert sum(d for _, d in pieces) == pytest.approx(1.0, abs=1e-12)
    t = 0.0
    for sinr, d in pieces:
        mid = t + d / 2.0
        # a sliver between two ends a few ulps apart (0.01 and 0.010000000000000002) has no
        # middle that the running sum t can point at; it holds no bit of the packet
        if d > 1e-9:
            level = noise + sum(p for a, b, p in spans if a <= mid < b)
            assert sinr == pytest.approx(7.0 / level, rel=1e-9)
        t += d


@pytest.mark.parametrize("band", [(9.99, 10.01), (7.5, 12.5), (18.0, 34.0), (7.0, 17.0), (0.05, 100.0)])
@pytest.mark.parametrize("shipping, wind", [(0.0, 0.0), (0.5, 0.0), (1.0, 12.0)])
def test_band_noise_matches_adaptive_quadrature(band: tuple[float, float], shipping: float, wind: float) -> None:
    lo, hi = band
    ref, err = quad(
        lambda f: 10.0 ** (float(loss.noise_psd_db(f / 1e3, shipping, wind)) / 10.0),
        lo * 1e3,
        hi * 1e3,
        epsrel=1e-12,
        limit=400,
    )
    assert err < 1e-9 * ref
    assert loss.noise_band_db(lo, hi, shipping, wind) == pytest.approx(10.0 * math.log10(ref), abs=1e-9)


def test_band_noise_of_a_narrow_band_is_the_carrier_approximation() -> None:
    f, b = 10.0, 0.002
    flat = float(loss.noise_psd_db(f)) + 10.0 * math.log10(b * 1e3)
    assert loss.noise_band_db(f - b / 2, f + b / 2) == pytest.approx(flat, abs=1e-6)
