"""ITMTL vs its variants and baselines over seeds (the issue's acceptance comparison).

    python tools/itmtl_compare.py [--seeds 20] [--duration 600] [--mobility meandering]
                                  [--variants ITMTL ITMTL-wsc ...] [--out out/itmtl-compare]

Runs scenarios/itmtl.toml once per seed and variant (ITMTL, ITMTL-wsc, no IMM, MU-Sync,
TSHL, Mobi-Sync) and prints a markdown table of the means over seeds of: the final sync
error of covered nodes and of all ordinary nodes (us), localization NMSE and RMSE over all
estimates, coverage at the end and its graph upper bound, promoted share; then ITMTL's gain
over ITMTL-wsc next to the paper's 56.67 % and 25.8 %. With ``--out``: results.json,
compare.md, and PNGs (bars per variant: Figs 9-10 / 13 analogues; per-round convergence of
sync and localization error, ITMTL vs ITMTL-wsc: Figs 11-12 analogues).

ITMTL runs without promotion unless ``--promotion`` (the paper's Figs 9-14 study anchors as
the only references). ``--mobility``: meandering (the scenario's current), turn (coordinated turn, 1 m/s,
0.01 rad/s: maneuvering nodes for IMM vs raw fixes), random_walk.
"""

from __future__ import annotations

import argparse
import json
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd

from aquasim_py import scenario
from aquasim_py.protocols.itmtl.metrics import per_round, protocol_metrics

SCEN = Path(__file__).resolve().parents[1] / "scenarios" / "itmtl.toml"

VARIANTS = {
    "ITMTL": ("itmtl", {}),
    "ITMTL-wsc": ("itmtl", {"compensate": False}),
    "ITMTL no IMM": ("itmtl", {"imm": False}),
    "ITMTL unweighted": ("itmtl", {"weighted": False}),
    "MU-Sync": ("mu_sync", {}),
    "TSHL": ("tshl", {}),
    "Mobi-Sync": ("mobi_sync", {}),
}
MOBILITY = {
    "meandering": None,
    "turn": {"model": "coordinated_turn", "speed": 1.0, "turn_rate": 0.01},
    "random_walk": {"model": "random_walk", "speed_min": 0.5, "speed_max": 1.5, "leg_duration": 60.0},
}
KEYS = (
    "sync_final_mean_s",
    "sync_final_mean_all_s",
    "loc_nmse",
    "loc_rmse_m",
    "loc_rmse_fixed_m",
    "coverage_final",
    "coverage_upper_bound",
    "promoted_share",
)
ITMTL_ONLY = ("ssp_depths_m", "ssp_speeds_mps")


def run(
    variant: str, seed: int, duration: float, mobility: str, promotion: bool = False
) -> tuple[dict[str, float], pd.DataFrame]:
    proto, extra = VARIANTS[variant]
    raw = tomllib.loads(SCEN.read_text())
    raw["simulation"].update(seed=seed, duration_s=duration)
    for g in raw["nodes"]:
        g["protocol"] = proto
        params = g.setdefault("params", {})
        if g["role"] == "ordinary":
            params.update(extra)
            if proto == "itmtl":
                params["promotion"] = promotion
            mob = MOBILITY[mobility]
            if mob is not None:
                g["mobility"] = dict(mob)
        if proto != "itmtl":
            for k in ITMTL_ONLY:
                params.pop(k, None)
    sim = scenario.build(scenario.load_dict(raw, SCEN))
    sim.run(duration)
    fr = sim.trace.frames()
    return protocol_metrics(fr, proto), per_round(fr, proto)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--duration", type=float, default=600.0)
    ap.add_argument("--mobility", choices=list(MOBILITY), default="meandering")
    ap.add_argument("--variants", nargs="*", default=list(VARIANTS))
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument(
        "--promotion", action="store_true", help="let ITMTL promote nodes (the paper's Figs 9-14 use anchors only)"
    )
    a = ap.parse_args()
    res: dict[str, list[dict[str, float]]] = {}
    rounds: dict[str, list[pd.DataFrame]] = {}
    for v in a.variants:
        for s in range(1, a.seeds + 1):
            m, pr = run(v, s, a.duration, a.mobility, a.promotion)
            res.setdefault(v, []).append(m)
            rounds.setdefault(v, []).append(pr.assign(seed=s))
    mean = {v: {k: float(np.nanmean([r.get(k, np.nan) for r in rs])) for k in KEYS} for v, rs in res.items()}
    lines = [
        f"{a.seeds} seeds, {a.duration:g} s, mobility {a.mobility}, promotion {'on' if a.promotion else 'off'}: "
        "means over seeds",
        "",
        "| variant | sync covered (us) | sync all (us) | NMSE | RMSE (m) | RMSE fixes (m) | coverage | bound | promoted |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for v, m in mean.items():
        lines.append(
            f"| {v} | {m['sync_final_mean_s'] * 1e6:.1f} | {m['sync_final_mean_all_s'] * 1e6:.1f} | "
            f"{m['loc_nmse']:.3g} | {m['loc_rmse_m']:.2f} | {m['loc_rmse_fixed_m']:.2f} | {m['coverage_final']:.2f} | "
            f"{m['coverage_upper_bound']:.2f} | {m['promoted_share']:.2f} |"
        )
    if "ITMTL" in mean and "ITMTL-wsc" in mean:
        w, i = mean["ITMTL-wsc"], mean["ITMTL"]
        lines.append("")
        lines.append(
            f"ITMTL-wsc vs ITMTL: sync error (covered) higher by "
            f"{100 * (w['sync_final_mean_s'] / i['sync_final_mean_s'] - 1):.1f} % (paper: up to 56.67 %); "
            f"NMSE higher by {100 * (w['loc_nmse'] / i['loc_nmse'] - 1):.1f} % (paper: about 25.8 %)"
        )
    text = "\n".join(lines)
    print(text)
    if a.out is not None:
        a.out.mkdir(parents=True, exist_ok=True)
        (a.out / "compare.md").write_text(text + "\n")
        (a.out / "results.json").write_text(json.dumps({"mean": mean, "runs": res}, indent=1))
        _plots(a.out, mean, rounds)


def _plots(out: Path, mean: dict[str, dict[str, float]], rounds: dict[str, list[pd.DataFrame]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(mean)
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    ax[0].bar(names, [mean[n]["sync_final_mean_s"] * 1e6 for n in names])
    ax[0].set_ylabel("final sync error of covered nodes (us)")
    ax[1].bar(names, [mean[n]["loc_nmse"] for n in names])
    ax[1].set_ylabel("localization NMSE")
    for x in ax:
        x.tick_params(axis="x", rotation=30)
    fig.tight_layout()
    fig.savefig(out / "variants.png", dpi=120)
    plt.close(fig)
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for n in names:
        df = pd.concat(rounds[n])
        g = df.groupby(level=0)
        if "sync_mean_s" in df:
            ax[0].plot(g["sync_mean_s"].mean() * 1e6, label=n)
        if "loc_rmse_m" in df:
            ax[1].plot(g["loc_rmse_m"].mean(), label=n)
    ax[0].set_xlabel("round")
    ax[0].set_ylabel("mean sync error of localized nodes (us)")
    ax[0].set_yscale("log")
    ax[1].set_xlabel("round")
    ax[1].set_ylabel("localization RMSE (m)")
    ax[1].legend()
    fig.tight_layout()
    fig.savefig(out / "convergence.png", dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
