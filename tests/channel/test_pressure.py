"""Received-pressure model (eq 6 of MSWPF) and the channel hook that puts it on receptions."""

from __future__ import annotations

import math
from collections.abc import Generator
from typing import Any

import numpy as np
import pytest

from aquasim_py.channel import Constant
from aquasim_py.channel.config import ChannelConfig
from aquasim_py.channel.pressure import (
    received_pressure,
    received_pressure_and_gradient,
    received_pressure_gradient,
)
from aquasim_py.kernel import Simulation
from aquasim_py.node import Node


def test_pressure_closed_form_and_gradient() -> None:
    src, rx = np.array([30.0, 40.0, 50.0]), np.array([0.0, 0.0, 100.0])
    D2 = 30.0**2 + 40.0**2 + 50.0**2
    assert received_pressure(src, rx, 5e4, 1.0) == pytest.approx(5e4 / math.sqrt(D2), rel=1e-15)
    assert received_pressure(src, rx, 5e6, 2.0) == pytest.approx(5e6 / D2, rel=1e-15)
    for k in (1.0, 1.5, 2.0):  # 1: the sqrt branch; others: the power
        g = received_pressure_gradient(src, rx, 5e4, k)
        eps = 1e-4  # central differences: error ~ eps^2 h''' ~ 1e-10 relative here
        fd = [
            (received_pressure(src + eps * e, rx, 5e4, k) - received_pressure(src - eps * e, rx, 5e4, k)) / (2 * eps)
            for e in np.eye(3)
        ]
        np.testing.assert_allclose(g, fd, rtol=1e-7)
    for k in (1.0, 1.5, 2.0):  # the fused form's h: the same to rounding (a few ulp)
        h, _ = received_pressure_and_gradient(src, rx, 5e4, k)
        assert h == pytest.approx(received_pressure(src, rx, 5e4, k), rel=1e-14)


class _Emitter(Node):
    name = "test_emitter"

    def run(self) -> Generator[Any, Any, Any]:
        if self.id == 0:
            yield self.broadcast("boom", None, 16)
            yield self.broadcast("data", None, 16)
        else:
            self.got = []
            while True:
                rec = yield self.recv()
                self.got.append(rec)


@pytest.mark.parametrize("std", [0.0, 5.0])
def test_receptions_of_the_emission_kind_carry_the_received_pressure(std: float) -> None:
    cfg = ChannelConfig(pressure_kind="boom", pressure_source_level=5e4, pressure_exponent=1.0, pressure_noise_std=std)
    sim = Simulation(7, Constant(1500.0), channel=cfg)
    pos = [[0.0, 0.0, 50.0], [120.0, 0.0, 100.0], [0.0, 90.0, 100.0]]
    nodes = sim.add_group(_Emitter, 3, positions=pos)
    sim.run(5.0)
    for n in nodes[1:]:
        boom, data = n.got
        h = 5e4 / np.linalg.norm(np.subtract(pos[n.id], pos[0]))
        # the noise is the first draw of the receiver's own ("node", id, "pressure") stream
        expect = h + (sim.rng("node", n.id, "pressure").normal(0.0, std) if std > 0 else 0.0)
        assert boom.pressure == pytest.approx(expect, rel=1e-12)
        assert math.isnan(data.pressure)
