"""Clock-sync maths on hand-made exchanges with exact timestamps.

The oracle is the exact geometry: delays solve |receiver(t + tau) - sender(t)| = c tau in
closed form (a quadratic for constant velocities and a constant sound speed), independent
of the first-order motion split under test.
"""

import numpy as np
import pytest

from aquasim_py.estimation.sync import (
    Exchanges,
    fit_clock,
    half_round_trip_sync,
    itmtl_sync,
    mu_sync,
    neighbour_velocity,
    split_delays,
    tshl_skew,
    tshl_sync,
)

C = 1500.0


def _delay(a: np.ndarray, w: np.ndarray) -> float:
    """Positive root of |a + w tau| = C tau (a: receiver - sender at send time, w: receiver velocity)."""
    A = w @ w - C * C
    B = 2.0 * a @ w
    Cc = a @ a
    return float((-B - np.sqrt(B * B - 4.0 * A * Cc)) / (2.0 * A))


def _exchanges(refs, p0, v, *, alpha, beta, times, hold, ref_v=None):
    """Exact Req/Res stamps of a node moving at constant velocity v from p0 at t = 0."""
    refs = np.asarray(refs, float)
    ref_v = np.zeros_like(refs) if ref_v is None else np.asarray(ref_v, float)
    rows, truth = [], []
    for t1 in times:
        for r0, w in zip(refs, ref_v):
            tf = _delay(r0 + w * t1 - (p0 + v * t1), w)
            t2 = t1 + tf
            t3 = t2 + hold
            tb = _delay(p0 + v * t3 - (r0 + w * t3), v)
            rows.append((alpha * t1 + beta, t2, t3, alpha * (t3 + tb) + beta))
            truth.append((tf, tb, p0 + v * t1, r0 + w * t1, w))
    return np.array(rows), truth


def test_fit_clock_recovers_exact_line():
    rng = np.random.default_rng(1)
    t = np.sort(rng.uniform(0.0, 600.0, 40))
    alpha, beta = 1.0 + 37.5e-6, -0.8123456
    a, b = fit_clock(t, alpha * t + beta, rng.uniform(0.5, 2.0, t.size))
    assert abs(a - alpha) < 1e-12
    assert abs(b - beta) < 1e-9


def test_regression_recovers_skew_offset_from_exact_delays():
    """Static node and references: the round-trip split is exact, so is the regression."""
    alpha, beta = 1.0 + 40e-6, 1.25
    refs = [[0, 0, 10], [800, 0, 20], [0, 700, 5], [650, 600, 30]]
    rows, _ = _exchanges(
        refs,
        np.array([300.0, 250.0, 120.0]),
        np.zeros(3),
        alpha=alpha,
        beta=beta,
        times=np.arange(5.0, 300.0, 30.0),
        hold=0.4,
    )
    fit = itmtl_sync(Exchanges.build(*rows.T))
    assert fit.converged
    assert abs(fit.alpha - alpha) < 1e-9
    assert abs(fit.beta - beta) < 1e-9


def test_motion_split_recovers_forward_backward_radial():
    """Purely radial constant speed away from a static reference: first order is exact."""
    ref = np.array([[0.0, 0.0, 50.0]])
    v = np.array([0.8, 0.6, 0.0]) * 1.3  # radial: the node starts on the ray from the ref
    p0 = np.array([400.0, 300.0, 50.0])
    alpha, beta = 1.0 - 25e-6, 0.3
    rows, truth = _exchanges(ref, p0, v, alpha=alpha, beta=beta, times=[10.0], hold=0.7)
    k = (truth[0][2] - truth[0][3]) / np.linalg.norm(truth[0][2] - truth[0][3]) @ v / C
    ex = Exchanges.build(*rows.T, k_node=k)
    tau_f, tau_b = split_delays(ex, alpha)
    assert tau_f[0] == pytest.approx(truth[0][0], abs=1e-12)
    assert tau_b[0] == pytest.approx(truth[0][1], abs=1e-12)
    # half the round trip misses by Delta / 2 = v (hold + S) / (2 c): hundreds of microseconds
    S = truth[0][0] + truth[0][1]
    assert abs(S / 2 - truth[0][0]) == pytest.approx(1.3 * (0.7 + S) / (2 * C), rel=1e-9)


def test_motion_split_with_drifting_reference_first_order():
    """Reference drifting too: 'separate' rates (node over t1..t4, reference over t2..t3)."""
    ref = np.array([[0.0, 0.0, 20.0]])
    w = np.array([[0.3, -0.2, 0.0]])
    v = np.array([-0.9, 0.5, 0.0])
    p0 = np.array([500.0, 200.0, 60.0])
    rows, truth = _exchanges(ref, p0, v, alpha=1.0, beta=0.0, times=[0.0], hold=0.5, ref_v=w)
    tf, tb, p, r, _ = truth[0]
    u = (p - r) / np.linalg.norm(p - r)
    ex = Exchanges.build(*rows.T, k_node=u @ v / C, k_ref=-u @ w[0] / C)
    tau_f, tau_b = split_delays(ex, 1.0)
    # the first-order split ignores the range's curvature: |range''| <= |v|^2 / R per s^2
    dt = tf + 0.5 + tb
    bound = (np.sum((v - w[0]) ** 2) + v @ v) * dt**2 / (2 * np.linalg.norm(p - r)) / C
    assert abs(tau_f[0] - tf) < bound and abs(tau_b[0] - tb) < bound
    assert bound < 5e-6  # microseconds, against a ~0.8 ms Delta
    ex0 = Exchanges.build(*rows.T)
    assert abs(split_delays(ex0, 1.0)[0][0] - tf) > 1e-4


def test_note_numeric_check_motion_split_vs_half_round_trip():
    """The note's check: 10 exchanges, 4 refs, skew 40 ppm, node at 1 m/s, exact stamps.

    Closed form for the half round trip (hold 0, static refs, constant velocity): each
    exchange's points shift by -Delta/2 with Delta = 2 v_r R / c^2, and d(v_r R)/dt = |v|^2,
    so starting from the centre of a symmetric square (mean Delta = 0) the clock error grows
    as |v|^2 / c^2 per second: 133 us at t = 300 s for 1 m/s. The motion split stays < 1 us.
    """
    alpha, beta = 1.0 + 40e-6, 0.3
    L = 500.0
    refs = [[0, 0, 0], [L, 0, 0], [0, L, 0], [L, L, 0]]
    p0 = np.array([L / 2, L / 2, 100.0])
    v = np.array([1.0, 0.0, 0.0])
    rows, truth = _exchanges(refs, p0, v, alpha=alpha, beta=beta, times=np.arange(10) * 30.0, hold=0.0)
    k = np.array([(p - r) / np.linalg.norm(p - r) @ v / C for _, _, p, r, _ in truth])
    T300 = alpha * 300.0 + beta
    fit = itmtl_sync(Exchanges.build(*rows.T, k_node=k))
    half = half_round_trip_sync(Exchanges.build(*rows.T))
    err_split = fit.to_true(T300) - 300.0
    err_half = half.to_true(T300) - 300.0
    assert abs(err_split) < 1e-6
    assert err_half == pytest.approx(-300.0 * (v @ v) / C**2, rel=0.05)


def test_mu_sync_equals_half_round_trip_on_static_exchanges():
    alpha, beta = 1.0 + 15e-6, -2.0
    refs = [[0, 0, 10], [900, 0, 20], [0, 800, 5]]
    rows, _ = _exchanges(
        refs,
        np.array([200.0, 100.0, 80.0]),
        np.zeros(3),
        alpha=alpha,
        beta=beta,
        times=np.arange(0.0, 200.0, 20.0),
        hold=0.2,
    )
    fit = mu_sync(Exchanges.build(*rows.T))
    # two regressions: the first uses alpha = 1 in S, so the second is off by O(skew^2)
    assert abs(fit.alpha - alpha) < 1e-9 and abs(fit.beta - beta) < 1e-7


def test_tshl_skew_constant_delay_and_offset():
    alpha, beta = 1.0 + 30e-6, 0.75
    rng = np.random.default_rng(3)
    tau = np.array([0.2, 0.45, 0.61])  # one constant delay per sender
    g = np.repeat(np.arange(3), 8)
    ts = np.sort(rng.uniform(0, 100, g.size))
    Tr = alpha * (ts + tau[g]) + beta
    assert tshl_skew(ts, Tr, g) == pytest.approx(alpha, abs=1e-12)
    # static two-way exchange for the offset
    rows, _ = _exchanges(
        [[0, 0, 0]], np.array([300.0, 0.0, 0.0]), np.zeros(3), alpha=alpha, beta=beta, times=[120.0], hold=0.5
    )
    fit = tshl_sync(ts, Tr, g, *rows.T)
    assert fit.alpha == pytest.approx(alpha, abs=1e-12)
    assert fit.beta == pytest.approx(beta, abs=1e-9)


def test_tshl_skew_biased_by_moving_node():
    """Constant-delay assumption: a node receding at v sees a skew biased by ~v / c."""
    v = 1.0
    ts = np.arange(0.0, 100.0, 5.0)
    # node receding from a static sender at speed v: delay tau(t) = (R0 + v t) / (c - v)
    tr = ts + (300.0 + v * ts) / (C - v)
    a = tshl_skew(ts, tr)
    assert a - 1.0 == pytest.approx(v / (C - v), rel=1e-9)


def test_neighbour_velocity_weighted_mean():
    vs = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    np.testing.assert_allclose(neighbour_velocity(vs, [3.0, 1.0]), [0.75, 0.5, 0.0])
