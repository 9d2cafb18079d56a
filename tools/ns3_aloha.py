"""Pure ALOHA in aquasim-py and in ns-3's UAN module, on one workload, in one process.

ns-3 (3.44, the ``ns3`` wheel from PyPI: ``pip install 'aquasim-py[ns3]'``) runs in-process
through its Python bindings; its part of the workload is C++ compiled by cppyy at start-up, so
that ns-3's time is ns-3's, not Python callbacks'. The workload, the same in both:

- ``--nodes`` sources (30) evenly on a 1-km ring around one sink, static;
- ideal propagation: no loss (ns-3 ``UanPropModelIdeal``; here ``loss_model = "none"``),
  straight rays at 1500 m/s, every node in range of every other (range 2001 m here);
- 1-s frames: 1000 bits at 1000 bit/s (in ns-3 a 125-byte packet, the ALOHA header included);
- Poisson offers per source, G = nodes x rate x 1 s; a source busy transmitting refuses a new
  offer (ns-3 ``UanMacAloha::Enqueue`` returns false while its PHY transmits; here
  ``mac = "aloha"`` with ``queue_length = 1``);
- half-duplex modems; a reception overlapped by another frame is lost (all received powers
  are equal under ideal propagation, so ns-3's SINR of an overlapped frame is about 0 dB, under
  its default 8-dB PER threshold: no capture; here ``collision = "destructive"``).

For each G and seed both simulators run ``--duration`` seconds; the script reports S (frames
delivered to the sink per frame time) per G with Student-t 95 % intervals over the seeds, and
the CPU time of each simulator's run (``time.process_time`` around our ``Simulation.run``;
``std::clock`` around ``Simulator::Run``), as frames and receptions per CPU second. A
reception is a frame's arrival at one receiver (every transmission reaches the 30 others),
counted the same way for both.

    python tools/ns3_aloha.py --seeds 5 --duration 5000 --out out/ns3_aloha
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import pandas as pd
from scipy import stats

ROOT = Path(__file__).resolve().parents[1]
LOADS = (0.1, 0.25, 0.5, 1.0, 2.0)

NS3_CODE = r"""
#include "ns3/core-module.h"
#include "ns3/mobility-module.h"
#include "ns3/network-module.h"
#include "ns3/uan-module.h"
#include <ctime>
#include <vector>

namespace aquasim_ns3 {
using namespace ns3;

struct Counts {
    double offers = 0, accepted = 0, received = 0, cpu_s = 0;
};

static Counts g_counts;

static void Offer(Ptr<NetDevice> dev, Address sink, uint32_t bytes, Ptr<ExponentialRandomVariable> gap) {
    g_counts.offers += 1;
    if (dev->Send(Create<Packet>(bytes), sink, 0)) {
        g_counts.accepted += 1;
    }
    Simulator::Schedule(Seconds(gap->GetValue()), &Offer, dev, sink, bytes, gap);
}

static bool SinkRx(Ptr<NetDevice>, Ptr<const Packet>, uint16_t, const Address&) {
    g_counts.received += 1;
    return true;
}

Counts RunAloha(uint32_t nodes, double rate_pps, double duration_s, uint32_t seed, uint32_t run) {
    RngSeedManager::SetSeed(seed);
    RngSeedManager::SetRun(run);
    g_counts = Counts();
    NodeContainer all;
    all.Create(nodes + 1);  // node 0: the sink
    MobilityHelper mobility;
    Ptr<ListPositionAllocator> pos = CreateObject<ListPositionAllocator>();
    pos->Add(Vector(1200.0, 1200.0, 50.0));
    for (uint32_t i = 0; i < nodes; ++i) {
        double phi = 2.0 * M_PI * i / nodes;
        pos->Add(Vector(1200.0 + 1000.0 * std::cos(phi), 1200.0 + 1000.0 * std::sin(phi), 50.0));
    }
    mobility.SetPositionAllocator(pos);
    mobility.SetMobilityModel("ns3::ConstantPositionMobilityModel");
    mobility.Install(all);

    UanTxMode mode = UanTxModeFactory::CreateMode(UanTxMode::FSK, 1000, 1000, 10000, 2000, 2, "FSK-1kbps");
    UanModesList modes;
    modes.AppendMode(mode);
    UanHelper uan;
    uan.SetPhy("ns3::UanPhyGen", "SupportedModes", UanModesListValue(modes));
    uan.SetMac("ns3::UanMacAloha");
    Ptr<UanChannel> channel = CreateObject<UanChannel>();
    channel->SetPropagationModel(CreateObject<UanPropModelIdeal>());
    channel->SetNoiseModel(CreateObject<UanNoiseModelDefault>());
    NetDeviceContainer devs = uan.Install(all, channel);

    UanHeaderCommon header;
    uint32_t bytes = 125 - header.GetSerializedSize();  // 1000 bits on the air, header included
    devs.Get(0)->SetReceiveCallback(MakeCallback(&SinkRx));
    Address sink = devs.Get(0)->GetAddress();
    for (uint32_t i = 1; i <= nodes; ++i) {
        Ptr<ExponentialRandomVariable> gap = CreateObject<ExponentialRandomVariable>();
        gap->SetAttribute("Mean", DoubleValue(1.0 / rate_pps));
        Simulator::Schedule(Seconds(gap->GetValue()), &Offer, devs.Get(i), sink, bytes, gap);
    }
    Simulator::Stop(Seconds(duration_s));
    std::clock_t t0 = std::clock();
    Simulator::Run();
    g_counts.cpu_s = double(std::clock() - t0) / CLOCKS_PER_SEC;
    Simulator::Destroy();
    return g_counts;
}
}  // namespace aquasim_ns3
"""


def run_ns3(nodes: int, g: float, duration: float, seed: int) -> dict[str, float]:
    from ns import ns

    if not hasattr(ns.cppyy.gbl, "aquasim_ns3"):
        ns.cppyy.cppdef(NS3_CODE)
    c = ns.cppyy.gbl.aquasim_ns3.RunAloha(nodes, g / nodes, duration, 1, seed + 1)
    return {"offers": c.offers, "transmissions": c.accepted, "received": c.received, "cpu_s": c.cpu_s}


def run_ours(nodes: int, g: float, duration: float, seed: int) -> dict[str, float]:
    from aquasim_py import scenario

    sc = scenario.load(
        ROOT / "scenarios" / "mac_aloha.toml",
        overrides=[
            f"simulation.duration_s={duration}",
            "channel.max_range_m=2001.0",
            f"nodes.1.count={nodes}",
            f"nodes.1.params.rate_pps={g / nodes}",
            "nodes.1.mac_params={queue_length=1}",
            "trace.position_interval_s=1e9",
        ],
        seed=seed,
    )
    sc = scenario.resolve(sc, variant="pure")
    # ns-3's run counts no energy: neither does this one (the scenario's modem powers off)
    sc.channel.tx_power_w = sc.channel.rx_power_w = sc.channel.idle_power_w = sc.channel.sleep_power_w = None
    sim = scenario.build(sc)
    t0 = time.process_time()
    sim.run(duration)
    cpu = time.process_time() - t0
    pk = sim.trace.frames()["packets"]
    data = pk[pk["kind"] == "data"]
    return {
        "offers": float((data["event"] == "offer").sum()),
        "transmissions": float((data["event"] == "tx").sum()),
        "received": float(((data["event"] == "rx") & (data["node"] == 0)).sum()),
        "cpu_s": cpu,
    }


def _ci(x: pd.Series) -> tuple[float, float]:
    x = x.to_numpy(float)
    half = stats.t.ppf(0.975, x.size - 1) * x.std(ddof=1) / math.sqrt(x.size) if x.size > 1 else math.nan
    return float(x.mean()), float(half)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--nodes", type=int, default=30)
    ap.add_argument("--loads", type=float, nargs="+", default=list(LOADS))
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--duration", type=float, default=5000.0, help="simulated seconds per run")
    ap.add_argument("--out", type=Path, help="write runs.csv and summary.csv here")
    args = ap.parse_args(argv)
    rows = []
    for g in args.loads:
        for seed in range(args.seeds):
            for name, fn in (("ns-3", run_ns3), ("aquasim-py", run_ours)):
                r = fn(args.nodes, g, args.duration, seed)
                rows.append({"simulator": name, "G_nominal": g, "seed": seed, **r})
                print(f"{name:>10} G={g:<5} seed={seed} S={r['received'] / args.duration:.4f} cpu={r['cpu_s']:.2f} s")
    runs = pd.DataFrame(rows)
    runs["G"] = runs["offers"] / args.duration  # 1-s frames: offers per frame time
    runs["S"] = runs["received"] / args.duration
    out = []
    for (sim, _g), grp in runs.groupby(["simulator", "G_nominal"], sort=False):
        gm, gh = _ci(grp["G"])
        sm, sh = _ci(grp["S"])
        cpu = grp["cpu_s"].sum()
        tx = grp["transmissions"].sum()
        out.append(
            {
                "simulator": sim,
                "G": gm,
                "G_ci": gh,
                "S": sm,
                "S_ci": sh,
                "theory": gm * math.exp(-2.0 * gm),
                "cpu_s": cpu,
                "frames_per_cpu_s": tx / cpu,
                "receptions_per_cpu_s": tx * args.nodes / cpu,
            }
        )
    summary = pd.DataFrame(out)
    total = summary.groupby("simulator", sort=False)[["cpu_s"]].sum()
    total["receptions_per_cpu_s"] = (
        runs.groupby("simulator", sort=False)["transmissions"].sum() * args.nodes / total["cpu_s"]
    )
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(summary.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
        print(total.to_string(float_format=lambda v: f"{v:.4g}"))
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        runs.to_csv(args.out / "runs.csv", index=False)
        summary.to_csv(args.out / "summary.csv", index=False)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
