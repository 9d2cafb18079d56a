"""VBF and HH-VBF: the pipe and the desirableness factor against independent calculations, the
holding time as printed, the self-adaptation's threshold, and the property that no node
forwards from outside its pipe."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from routenet import FakePort, rows, run

from aquasim_py.net.routing.base import Datagram
from aquasim_py.net.routing.vbf import Vbf, VbfHeader, VbfParams, desirableness, pipe_distance

R = 100.0


@settings(max_examples=200)
@given(st.lists(st.floats(-500, 500), min_size=9, max_size=9))
def test_pipe_distance_and_desirableness_match_the_projection_on_the_axis(xs):
    node, start, target = np.array(xs[:3]), np.array(xs[3:6]), np.array(xs[6:])
    axis = target - start
    if np.linalg.norm(axis) < 1e-3:
        return
    u = axis / np.linalg.norm(axis)
    foot = start + np.dot(node - start, u) * u  # the node's projection on the axis
    p = pipe_distance(tuple(node), tuple(start), tuple(target))
    assert p == pytest.approx(np.linalg.norm(node - foot), rel=1e-9, abs=1e-6)
    # relative to a forwarder F = start: d cos(theta) is the advance along F -> T
    alpha, d = desirableness(tuple(node), tuple(start), tuple(target), p, 50.0, R)
    assert d == pytest.approx(np.linalg.norm(node - start), rel=1e-12, abs=1e-9)
    assert alpha == pytest.approx(p / 50.0 + (R - np.dot(node - start, u)) / R, rel=1e-9, abs=1e-9)


def test_the_holding_time_is_sqrt_alpha_t_delay_plus_r_minus_d_over_v0():
    # source at 200 m depth, sink straight above; a node 60 m up and 20 m off the axis
    sensors = [[0.0, 0.0, 200.0], [20.0, 0.0, 140.0]]
    t = run(sensors, [[0.0, 0.0, 0.0]], {0: [1.0]}, "vbf", {"radius_m": 50.0}, until=30.0)
    fwd = rows(t, "forward").set_index("node")
    d = math.hypot(20.0, 60.0)
    alpha = 20.0 / 50.0 + (R - 60.0) / R
    rx_end = 1.0 + d / 1500.0 + (200 + 56 + 160) / 10_000.0
    assert fwd.loc[1, "value"] == pytest.approx(alpha, rel=1e-12)
    assert fwd.loc[1, "time"] == pytest.approx(rx_end + math.sqrt(alpha) * 1.0 + (R - d) / 1500.0, abs=1e-9)


def _copy(seq: int, forwarder, sender: int = 3) -> Datagram:
    h = VbfHeader(
        7, seq, -2, 1, sender, source=(0.0, 0.0, 300.0), target=(0.0, 0.0, 0.0), forwarder=forwarder, radius=50.0
    )
    return Datagram(h, "data", None, 100)


@pytest.mark.parametrize(
    ("others", "forwards"),
    [
        ([], True),  # alpha = 0.2 + 0.5 = 0.7 < 1.5
        ([(0.0, 0.0, 250.0)], True),  # min(0.7, 0.2 + 1) = 0.7 < 0.75
        ([(0.0, 0.0, 250.0), (0.0, 0.0, 240.0)], False),  # 0.7 > 1.5 / 4
    ],
)
def test_self_adaptation_halves_the_threshold_for_each_forwarder_heard(others, forwards):
    port = FakePort(position=(10.0, 0.0, 250.0))
    vbf = Vbf(port, VbfParams(radius_m=50.0))
    vbf.on_copy(_copy(0, (0.0, 0.0, 300.0)), 3)  # d = 51 m, p = 10 m
    for k, f in enumerate(others):
        vbf.on_copy(_copy(0, f, sender=4 + k), 4 + k)
    port.env.run(10.0)
    expected = 10.0 / 50.0 + (R - 50.0) / R
    if forwards:
        (row,) = port.events("forward")
        assert row[7] == pytest.approx(expected)
        assert port.offered[0][1].header.forwarder == (10.0, 0.0, 250.0)
    else:
        assert port.offered == [] and port.events("suppress")


def test_a_node_outside_the_pipe_never_holds_the_packet():
    port = FakePort(position=(60.0, 0.0, 250.0))
    vbf = Vbf(port, VbfParams(radius_m=50.0))
    vbf.on_copy(_copy(0, (0.0, 0.0, 300.0)), 3)
    port.env.run(10.0)
    assert port.offered == [] and port.rows == [] and not vbf.held


@settings(max_examples=20)
@given(
    seed=st.integers(0, 10_000),
    width=st.sampled_from([20.0, 50.0, 100.0]),
    routing=st.sampled_from(["vbf", "hh_vbf"]),
    n=st.integers(10, 30),
)
def test_no_node_forwards_from_outside_its_pipe(seed, width, routing, n):
    rng = np.random.default_rng(seed)
    sensors = rng.uniform([0.0, 0.0, 20.0], [250.0, 250.0, 250.0], (n, 3))
    sinks = np.array([[60.0, 60.0, 0.0], [190.0, 190.0, 0.0]])
    sources = [int(i) for i in rng.choice(n, 2, replace=False)]
    plan = {sources[0]: [1.0], sources[1]: [30.0]}
    t = run(sensors, sinks, plan, routing, {"radius_m": width}, until=60.0, collision="destructive")
    fwd = rows(t, "forward")
    relays = fwd[fwd["prev"] >= 0]
    pos = np.vstack([sensors, sinks])
    for _, r in relays.iterrows():
        src = pos[int(r["origin"])]
        target = sinks[np.argmin(np.linalg.norm(sinks - src, axis=1))]
        start = src if routing == "vbf" else pos[int(r["prev"])]
        assert pipe_distance(tuple(pos[int(r["node"])]), tuple(start), tuple(target)) <= width + 1e-9
    assert fwd.groupby(["node", "origin", "seq"]).size().max() == 1
