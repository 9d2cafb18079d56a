"""tools/bench_kernel.py's receiver modes: what the nodes do with their receptions changes their
cost, never the channel's decisions, and the ``drop`` ablation leaves the kernel as it was."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))

import bench_kernel as bk

from aquasim_py.nodecore import NodeCore

N, UNTIL = 40, 6.0


def _run(receiver: str, speed: float = 0.0):
    pos, rng_m = bk.layout(N, 6.0, 3)
    sim = bk.build_kernel(pos, rng_m, receiver, 3, speed)
    sim.run(UNTIL)
    return sim, sim.trace.frames()["packets"]


@pytest.mark.parametrize("speed", [0.0, 1.0])
def test_receivers_do_not_change_the_channel(speed):
    frames = {mode: _run(mode, speed)[1] for mode in bk.RECEIVERS}
    ref = frames["recv"]
    assert (ref["event"] == "rx").sum() > 50  # a network that delivers
    for mode, f in frames.items():
        assert f.equals(ref), mode


def test_what_each_receiver_leaves_in_its_inbox():
    left, delivered = {}, {}
    for mode in bk.RECEIVERS:
        sim, frame = _run(mode)
        left[mode] = sum(node.pending() for node in sim.nodes)
        delivered[mode] = int((frame["event"] == "rx").sum())
    assert left["none"] == delivered["none"] > 0  # nobody takes anything: every delivery waits
    assert left["drop"] == 0  # discarded at delivery
    assert left["recv"] == 0  # each taken as it comes
    assert 0 < left["take"] < delivered["take"]  # taken once a period: only the last period's wait


def test_drop_restores_the_kernels_deliver():
    before = NodeCore.deliver
    _run("drop")
    assert NodeCore.deliver is before
    with pytest.raises(ValueError, match="receiver must be one of"):
        bk.build_kernel(*bk.layout(N, 6.0, 3), "sometimes", 3)
    assert NodeCore.deliver is before
