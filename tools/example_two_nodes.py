"""Two nodes exchanging packets: the smallest complete aquasim-py run.

A buoy (true time) pings an ordinary node whose clock runs 50 ppm fast and 0.2 s ahead; the
node answers with its receive and send stamps. From each exchange the buoy computes the
one-way delay and the node's clock offset (two-way time transfer), and both are compared
with the truth the kernel wrote to the traces.

    python tools/example_two_nodes.py [OUT_DIR]     # default: ./two_nodes_traces
"""

from __future__ import annotations

import sys
from pathlib import Path

from aquasim_py.channel import Constant, Isogradient, travel_time
from aquasim_py.channel.config import ChannelConfig
from aquasim_py.clock import Clock
from aquasim_py.kernel import Simulation
from aquasim_py.node import Node, Role


def profile():
    """Isogradient c(z) = 1480 + 0.1 z where the ray tracer supports it (else 1500 m/s)."""
    iso = Isogradient(1480.0, 0.1)
    try:
        travel_time(iso, [0.0, 0.0, 10.0], [100.0, 0.0, 50.0])
        return iso
    except NotImplementedError:
        return Constant(1500.0)


class PingPong(Node):
    """The buoy pings every 10 s; the other node answers with (T2, T3) of its own clock."""

    name = "pingpong"

    def run(self):
        if self.role is Role.BUOY:
            while True:
                t1 = yield self.broadcast("ping", None, 64)
                rec = yield self.recv(timeout=8.0, kinds="pong")
                if rec is not None:
                    t2, t3 = rec.packet.payload
                    t4 = rec.rx_local
                    delay = ((t4 - t1) - (t3 - t2)) / 2  # one-way delay (s), symmetric path
                    offset = ((t2 - t1) - (t4 - t3)) / 2  # node clock minus buoy clock (s)
                    self.log("exchange", peer=rec.packet.src, t1=t1, delay_s=delay, offset_s=offset)
                yield self.sleep(10.0 - (self.local_time() - t1))
        else:
            while True:
                rec = yield self.recv(kinds="ping")
                yield self.sleep(0.5)  # turnaround; the modem is idle, so the send starts now
                t3 = self.local_time()
                yield self.send(rec.packet.src, "pong", (rec.rx_local, t3), 128)


def main(argv: list[str]) -> int:
    out = Path(argv[0]) if argv else Path("two_nodes_traces")
    ssp = profile()
    sim = Simulation(seed=7, ssp=ssp, channel=ChannelConfig(collision="destructive"))
    buoy_pos, node_pos = [0.0, 0.0, 5.0], [1200.0, 500.0, 80.0]
    sim.add_group(PingPong, 1, role=Role.BUOY, positions=[buoy_pos])
    sim.add_group(PingPong, 1, role=Role.ORDINARY, positions=[node_pos], clocks=[Clock(skew=50e-6, offset=0.2)])
    sim.run(60.0)
    frames = sim.trace.frames()
    ex = frames["exchange"]
    true_delay = float(travel_time(ssp, buoy_pos, node_pos))
    print(f"profile: {ssp}")
    print(f"true one-way delay {true_delay * 1e3:.6f} ms")
    print(
        "(the node's 50 ppm fast clock reads its 0.564 s turnaround, 64-bit reception + 0.5 s wait, "
        "28 us long, so the delay comes out 14 us short)"
    )
    for _, r in ex.iterrows():
        # node clock minus true time in the middle of the exchange (the buoy's clock is true time)
        t_mid = r.t1 + true_delay + 0.282
        true_offset = 50e-6 * t_mid + 0.2
        print(
            f"t = {r.time:6.2f} s: delay {r.delay_s * 1e3:.6f} ms (error {(r.delay_s - true_delay) * 1e6:+.2f} us), "
            f"offset {r.offset_s:.6f} s (error {(r.offset_s - true_offset) * 1e6:+.2f} us)"
        )
    p = frames["packets"]
    print("packets:", p["event"].value_counts().to_dict())
    sim.trace.write(out)
    print(f"traces written to {out}/ ({', '.join(sorted(f.name for f in out.iterdir()))})")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
