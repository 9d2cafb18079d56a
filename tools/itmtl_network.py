"""Network-wide ITMTL (Figs 15-17 analogues): coverage, sync error and NMSE against node
density and anchor share, with the connectivity-graph upper bound on coverage.

    python tools/itmtl_network.py [--nodes 20] [--seeds 3] [--duration 300]
                                  [--densities 3 5 7 10] [--shares 0.1 0.2 0.3] [--out DIR]

Each run places ``nodes`` nodes uniformly at random in a square whose side makes the mean
number of neighbours within the 1200 m range equal to the density (2-D estimate
``N pi R^2 / side^2``), ``share`` of them anchors (on true time, at 5 m depth) and the rest
ordinary nodes drifting in the scenario's meandering current; everything else (profile,
clocks, channel, protocol parameters) is scenarios/itmtl.toml. Prints a markdown table of
the means over seeds; with ``--out`` also writes network.md and network.png.
"""

from __future__ import annotations

import argparse
import math
import tomllib
from pathlib import Path

import numpy as np

from aquasim_py import scenario
from aquasim_py.protocols.itmtl.metrics import protocol_metrics

SCEN = Path(__file__).resolve().parents[1] / "scenarios" / "itmtl.toml"
KEYS = ("coverage_final", "coverage", "coverage_upper_bound", "sync_final_mean_s", "loc_nmse", "promoted_share")


def run(n: int, density: float, share: float, seed: int, duration: float) -> dict[str, float]:
    raw = tomllib.loads(SCEN.read_text())
    raw.pop("variants", None)  # ITMTL only
    R = raw["channel"]["max_range_m"]
    side = math.sqrt(n * math.pi * R * R / density)
    rng = np.random.default_rng([seed, int(density * 100), int(share * 100)])
    n_anchor = max(1, int(round(share * n)))
    depth = raw["environment"]["volume"]["hi"][2]
    raw["simulation"].update(seed=seed, duration_s=duration)
    raw["environment"]["volume"] = {"lo": [0.0, 0.0, 0.0], "hi": [side, side, depth]}
    anchors = np.column_stack([rng.uniform(0, side, (n_anchor, 2)), np.full(n_anchor, 5.0)])
    ordinary = np.column_stack([rng.uniform(0, side, (n - n_anchor, 2)), rng.uniform(20.0, depth - 20.0, n - n_anchor)])
    ref, ordi = raw["nodes"]
    ref["placement"] = {"kind": "explicit", "positions": anchors.tolist()}
    ref.pop("params", None)
    ordi["placement"] = {"kind": "explicit", "positions": ordinary.tolist()}
    sim = scenario.build(scenario.load_dict(raw, SCEN))
    sim.run(duration)
    return protocol_metrics(sim.trace.frames(), "itmtl")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--nodes", type=int, default=20)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--duration", type=float, default=300.0)
    ap.add_argument("--densities", type=float, nargs="*", default=[3.0, 5.0, 7.0, 10.0])
    ap.add_argument("--shares", type=float, nargs="*", default=[0.1, 0.2, 0.3])
    ap.add_argument("--out", type=Path, default=None)
    a = ap.parse_args()
    rows = []
    for share in a.shares:
        for d in a.densities:
            ms = [run(a.nodes, d, share, s, a.duration) for s in range(1, a.seeds + 1)]
            rows.append((share, d, {k: float(np.nanmean([m.get(k, np.nan) for m in ms])) for k in KEYS}))
    lines = [
        f"{a.nodes} nodes, {a.seeds} seeds, {a.duration:g} s per point: means over seeds",
        "",
        "| anchors | density | coverage (end) | coverage (ever) | graph bound | sync covered (us) | NMSE | promoted |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for share, d, m in rows:
        lines.append(
            f"| {share:.0%} | {d:g} | {m['coverage_final']:.2f} | {m['coverage']:.2f} | "
            f"{m['coverage_upper_bound']:.2f} | {m['sync_final_mean_s'] * 1e6:.1f} | {m['loc_nmse']:.3g} | "
            f"{m['promoted_share']:.2f} |"
        )
    text = "\n".join(lines)
    print(text)
    if a.out is not None:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        a.out.mkdir(parents=True, exist_ok=True)
        (a.out / "network.md").write_text(text + "\n")
        fig, ax = plt.subplots(1, 3, figsize=(13, 4))
        for share in a.shares:
            sel = [(d, m) for s, d, m in rows if s == share]
            ds = [d for d, _ in sel]
            ax[0].plot(ds, [m["coverage"] for _, m in sel], "o-", label=f"{share:.0%} anchors")
            ax[0].plot(ds, [m["coverage_upper_bound"] for _, m in sel], "k:", alpha=0.4)
            ax[1].plot(ds, [m["sync_final_mean_s"] * 1e6 for _, m in sel], "o-", label=f"{share:.0%}")
            ax[2].plot(ds, [m["loc_nmse"] for _, m in sel], "o-", label=f"{share:.0%}")
        ax[0].set_ylabel("coverage (dotted: graph bound)")
        ax[1].set_ylabel("sync error of covered nodes (us)")
        ax[2].set_ylabel("NMSE")
        for x in ax:
            x.set_xlabel("node density (mean neighbours)")
        ax[0].legend()
        fig.tight_layout()
        fig.savefig(a.out / "network.png", dpi=120)
        plt.close(fig)


if __name__ == "__main__":
    main()
