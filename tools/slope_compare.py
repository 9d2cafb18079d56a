"""ITMTL and STVF on the shelf-break slope against the flat twin, and the part of the difference
that the bias of blocked (or too weak) direct paths explains: the tables of docs/channel.md
("The slope scenario").

Per seed, each protocol (the scenarios' ``itmtl`` and ``stvf`` variants) runs three times on the
same network: ``flat`` (scenarios/slope_flat.toml: one profile, a flat floor, the first
eigenray), ``slope`` (scenarios/slope.toml: the front, the slope, the modem's stamp at the first
detectable arrival) and ``direct only`` (slope.toml with ``channel.direct_only``: every reception
stamped on a reflected arrival lost, the analysis switch). The gap flat -> slope is what the real
site costs; the part of it that goes away when the reflected stamps are removed is the part the
blocked and weak direct paths cause (removing links also removes information, so the rest is an
upper bound on what the front and the floor's other effects cost).

Per link (the slope runs' receptions): the share stamped on each arrival class and kind
(blocked: the link has no direct or refracted arrival; weak direct: it has one, earlier than the
stamp, below the detection threshold; reflected first: a reflected arrival comes before every
direct one), and each
stamp's range bias in metres, 1495 m/s x (stamp - reference), against two references computed
here independently of the channel: the straight chord's travel time in the true field (a
quadrature of 1 / c along the chord, no rays) and what the nodes believe (the exact layered
solver in their CTD cast, ITMTL's model). Positions at the send and arrival instants are
interpolated from the 1 s ``positions`` samples.

    python tools/slope_compare.py --seeds 5 --json slope.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.integrate import trapezoid  # numpy's own is numpy >= 2 only

ROOT = Path(__file__).resolve().parents[1]
SLOPE = ROOT / "scenarios" / "slope.toml"
FLAT = ROOT / "scenarios" / "slope_flat.toml"
NOMINAL = 1495.0  # m/s, the nodes' straight-line speed
METRICS = {
    "itmtl": ("localization.rmse_m", "localization.final_rmse_m", "sync.mean_abs_error_s", "localization.coverage"),
    "stvf": ("localization.rmse_m", "localization.final_rmse_m", "localization.coverage"),
}
CONFIGS = {"flat": (FLAT, []), "slope": (SLOPE, []), "direct only": (SLOPE, ["channel.direct_only=true"])}


def run(path: Path, variant: str, seed: int, sets: list[str]) -> Any:
    from aquasim_py import run_scenario

    return run_scenario(
        path, variant=variant, seed=seed, overrides=[*sets, "trace.position_interval_s=1.0"], progress=False
    )


def link_biases(tables: Any) -> pd.DataFrame:
    """The receptions of a slope run with their range biases (m) against the chord's travel
    time in the true field and the nodes' believed (cast) travel time."""
    from aquasim_py.channel import ssp, travel_time
    from aquasim_py.channel.data import shelfbreak
    from aquasim_py.scenario import load

    p, pos = tables["packets"], tables["positions"]
    rx = p[p.event == "rx"].copy()
    t_send = p[p.event == "tx"].set_index("uid")["time"]

    def at(nodes: np.ndarray, times: np.ndarray) -> np.ndarray:
        out = np.empty((nodes.size, 3))
        for node in np.unique(nodes):
            g = pos[pos.node == node].sort_values("time")
            k = nodes == node
            out[k] = np.c_[[np.interp(times[k], g.time, g[c]) for c in "xyz"]].T
        return out

    s = at(rx.src.to_numpy(), t_send.loc[rx.uid].to_numpy())
    d = at(rx.node.to_numpy(), rx.time.to_numpy())
    env = shelfbreak()
    u = np.linspace(0.0, 1.0, 2001)
    pts = s[:, None, :] + (d - s)[:, None, :] * u[None, :, None]
    chord = trapezoid(1.0 / env.speed(pts[..., 0], pts[..., 1], pts[..., 2]), u, axis=1)
    chord *= np.linalg.norm(d - s, axis=1)
    params = load(SLOPE).nodes[1].params
    cast = ssp.Layered(params["ssp_depths_m"], params["ssp_speeds_mps"])
    rx["chord_bias_m"] = NOMINAL * (rx.tof.to_numpy() - chord)
    rx["belief_bias_m"] = NOMINAL * (rx.tof.to_numpy() - travel_time(cast, s, d, reflections="fallback"))
    # blocked: no direct or refracted arrival at all; weak direct: there is one, but an earlier
    # one than the stamp went undetected; reflected first: a reflected arrival beat every direct one
    direct = rx.path.isin(["direct", "refracted"]).to_numpy()
    later = (rx.tof > rx.direct_tof + 1e-9).to_numpy()
    rx["kind"] = np.select(
        [rx.direct_tof.isna().to_numpy(), later, ~direct],
        ["blocked", "weak direct", "reflected first"],
        default="direct",
    )
    return rx


def _half_width(x: pd.Series) -> float:
    """95 % Student-t half-width of the mean of ``x`` (NaN dropped)."""
    from scipy import stats

    x = x.dropna()
    if x.size < 2:
        return float("nan")
    return float(stats.t.ppf(0.975, x.size - 1) * x.std(ddof=1) / np.sqrt(x.size))


def summarize(df: pd.DataFrame, summary: pd.DataFrame) -> None:
    """Print the per-configuration means, the paired differences between configurations (same
    seed, same network) with their 95 % intervals over seeds, and the slope runs' receptions by
    stamp kind with their range biases."""
    print("\nper protocol and configuration, mean over seeds (95 % Student-t half-width over seeds):")
    for proto, names in METRICS.items():
        sub = df[df.protocol == proto]
        for k in (*names, "receptions", "indirect_drops"):
            cells = {}
            for c in CONFIGS:
                x = sub[sub.config == c][k]
                cells[c] = f"{x.mean():.4g} +- {_half_width(x):.2g} (n={x.notna().sum()})"
            print(proto, k, cells)
    print("\npaired differences (same seed), mean and 95 % half-width over seeds:")
    for proto, names in METRICS.items():
        wide = df[df.protocol == proto].pivot(index="seed", columns="config")
        for k in names:
            for a, b in (("slope", "flat"), ("direct only", "flat"), ("slope", "direct only")):
                dx = wide[(k, a)] - wide[(k, b)]
                print(f"{proto} {k}: {a} - {b} = {dx.mean():.4g} +- {_half_width(dx):.2g} (n={dx.notna().sum()})")
    print("\nslope runs, receptions by stamp kind and class; range bias (m, mean / std) vs chord and belief:")
    print(summary.to_string(index=False, float_format=lambda v: f"{v:.3g}"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--json", type=Path)
    ap.add_argument(
        "--summarize", type=Path, help="print the tables of an earlier run's --json file instead of running"
    )
    args = ap.parse_args()
    if args.summarize:
        doc = json.loads(args.summarize.read_text())
        summarize(pd.DataFrame(doc["runs"]), pd.DataFrame(doc["links"]))
        return
    rows = []
    links = []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        for proto, names in METRICS.items():
            for config, (path, sets) in CONFIGS.items():
                res = run(path, proto, seed, sets)
                m = res.metrics
                row = {"seed": seed, "protocol": proto, "config": config}
                row.update({k: m.get(k, np.nan) for k in names})
                p = res.tables["packets"]
                rx = p[p.event == "rx"]
                row["receptions"] = len(rx)
                row["indirect_drops"] = int((p.reason == "indirect").sum())
                rows.append(row)
                if config == "slope":
                    lb = link_biases(res.tables)
                    lb["seed"], lb["protocol"] = seed, proto
                    links.append(lb)
                print(json.dumps(row), flush=True)
    df = pd.DataFrame(rows)
    lk = pd.concat(links, ignore_index=True)
    summary = (
        lk.groupby(["protocol", "kind", "path"])
        .agg(
            n=("tof", "size"),
            chord_mean=("chord_bias_m", "mean"),
            chord_std=("chord_bias_m", "std"),
            belief_mean=("belief_bias_m", "mean"),
            belief_std=("belief_bias_m", "std"),
        )
        .reset_index()
    )
    summary["share"] = summary.n / summary.groupby("protocol").n.transform("sum")
    summarize(df, summary)
    if args.json:
        doc = {"runs": df.to_dict(orient="records"), "links": summary.to_dict(orient="records")}
        args.json.write_text(json.dumps(doc, indent=1, default=float) + "\n")


if __name__ == "__main__":
    main()
