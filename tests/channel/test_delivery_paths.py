"""The compiled delivery (channel/_delivery.c) against the Python reference
(``AcousticChannel.compiled_delivery = False``): random transmissions, every packets row and
every reception each node got must be the same, field for field and in the same order.

The networks are test_verdicts' (a line in a 1024 m/s medium, 1/16 s grid, so equal arrivals,
equal ends and signals that only touch are common), with the SNR falling with distance (capture
decisions go both ways), half-duplex cuts, unicasts and broadcasts, MAC jitter on or off, clocks
exact (stamped in C), skewed or drifting (stamped through Python), and nodes that take their
receptions at once, in batches or not at all.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scripted import Plan, Script
from test_verdicts import BITRATE, C, networks

from aquasim_py import events
from aquasim_py.channel import Constant, acoustic
from aquasim_py.channel.acoustic import AcousticChannel, ChannelConfig
from aquasim_py.clock import Clock
from aquasim_py.kernel import Simulation

pytestmark = pytest.mark.skipif(
    acoustic._delivery is None or events._events is None, reason="the compiled extensions are not built"
)


class Receiver(Script):
    """Transmits on its plan and logs every reception it takes: node ids 0 mod 3 wait in recv,
    1 mod 3 take their inbox every 0.3 s, 2 mod 3 never listen."""

    name = "delivery_paths_receiver"

    def run(self) -> Any:
        if self.id % 3 == 0:
            self.env.process(self._wait())
        elif self.id % 3 == 1:
            self.env.process(self._batches())
        yield from super().run()

    def _keep(self, r: Any) -> None:
        p = r.packet
        self.log("got", uid=p.uid, src=p.src, rx_local=r.rx_local, snr=r.snr_db, pressure=r.pressure)

    def _wait(self) -> Any:
        while True:
            r = yield self.recv()
            self._keep(r)

    def _batches(self) -> Any:
        while True:
            yield self.sleep(0.3)
            for r in self.take_pending():
                self._keep(r)


def _run(
    xs: list[int],
    plan: Plan,
    cfg: ChannelConfig,
    clocks: str,
    compiled: bool,
    own_heap: bool = True,
    compiled_queue: bool = False,
) -> tuple[dict[str, pd.DataFrame], bool]:
    cls = type("Planned", (Receiver,), {"plan": plan, "name": "planned_receiver"})
    old = AcousticChannel.compiled_delivery, AcousticChannel.compiled_heap, events.compiled
    AcousticChannel.compiled_delivery, AcousticChannel.compiled_heap, events.compiled = (
        compiled,
        own_heap,
        compiled_queue,
    )
    try:
        sim = Simulation(3, ssp=Constant(C), channel=cfg)

        def clock(i: int, rng: np.random.Generator) -> Clock:
            if clocks == "exact":
                return Clock()
            if clocks == "skewed":
                return Clock(skew=1e-4 * (i + 1), offset=0.01 * i)
            return Clock(skew=1e-4, drift_std=1e-5, drift_interval=0.5, rng=rng)

        sim.add_group(cls, len(xs), positions=[[64.0 * x, 0.0, 10.0] for x in xs], clocks=clock)
        sim.run(20.0)
        used = sim.channel._core is not None
        assert isinstance(sim.env, events.Environment) == compiled_queue
    finally:
        AcousticChannel.compiled_delivery, AcousticChannel.compiled_heap, events.compiled = old
    return sim.trace.frames(), used


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    net=networks(),
    collision=st.sampled_from(["destructive", "capture", "none"]),
    jitter=st.sampled_from([0.0, 1e-3]),
    clocks=st.sampled_from(["exact", "skewed", "drifting"]),
    capture_db=st.sampled_from([0.0, 3.0, 10.0]),
    path=st.sampled_from(["compiled queue", "simpy, own heap", "simpy, simpy heap", "python on compiled queue"]),
    drain=st.booleans(),
)
def test_compiled_delivery_equals_the_python_reference(net, collision, jitter, clocks, capture_db, path, drain) -> None:
    """The reference: the Python delivery on SimPy's Environment. Against it: the compiled
    delivery on the kernel's compiled queue, or on SimPy's with the channel's entries on its
    own heap or on SimPy's; and the Python delivery on the compiled queue. Each deciding
    consecutive deliveries in one loop or one per step."""
    xs, plan = net
    cfg = ChannelConfig(
        max_range_m=1e6,
        bitrate_bps=BITRATE,
        snr_threshold_db=-1e9,
        collision=collision,
        capture_threshold_db=capture_db,
        jitter_std_s=jitter,
    )
    ref, used_ref = _run(xs, plan, cfg, clocks, compiled=False)
    AcousticChannel.drain_deliveries = drain
    try:
        got, used = _run(
            xs,
            plan,
            cfg,
            clocks,
            compiled=not path.startswith("python"),
            own_heap=path == "simpy, own heap",
            compiled_queue="compiled queue" in path,
        )
    finally:
        AcousticChannel.drain_deliveries = True
    assert used != path.startswith("python") and not used_ref  # each run took the path it was meant to
    assert ref.keys() == got.keys()
    for name in ref:
        pd.testing.assert_frame_equal(got[name], ref[name], check_exact=True)


def test_pressure_readings_equal() -> None:
    """Sound emissions (pressure_kind): the hydrophone reading is drawn through the Python hook
    from the receiver's own stream, in the same order on both paths."""
    plan: Plan = {i: [(0.1 * k + 0.05 * i, None, 64) for k in range(30)] for i in range(4)}
    cfg = ChannelConfig(
        max_range_m=1e6, bitrate_bps=BITRATE, snr_threshold_db=-1e9, collision="none", pressure_kind="data"
    )
    out = []
    for compiled in (False, True):
        frames, used = _run([0, 3, 5, 9], plan, cfg, "exact", compiled, compiled_queue=compiled)
        assert used == compiled
        out.append(frames)
    got = out[1]["got"]
    assert got["pressure"].notna().all() and len(got) > 20
    for name in out[0]:
        pd.testing.assert_frame_equal(out[1][name], out[0][name], check_exact=True)
