"""ITMTL vs its variants and baselines over seeds, with 95 % confidence intervals.

    python tools/itmtl_compare.py [--seeds 20] [--duration 600] [--mobility meandering]
                                  [--variants itmtl wsc tshl mu_sync mobi_sync ...]
                                  [--no-promotion] [--workers 2] [--out out/itmtl-compare]

Runs scenarios/itmtl.toml once per seed (1..N) and variant. The variants are those of the
scenario file (``itmtl``, ``wsc``, ``tshl``, ``mu_sync``, ``mobi_sync``) plus ``no_imm`` and
``unweighted``; each is applied here as the same overrides the scenario's ``[variants]``
tables give, so the tool also runs where the variants runner is not available. Prints a
markdown table (mean and 95 % t-interval over seeds) of: final sync error of the covered
ordinary nodes and of all of them (us), localization NMSE and RMSE, coverage, promoted share,
Res collision fraction and short-round fraction; then ITMTL-wsc's gap over ITMTL in two
statistics, each with a paired bootstrap 95 % CI over seeds:

- the paper's (Figs 11-12): per round, on the (node, round) pairs both localized
  (``aquasim_protocols.itmtl.paper.wsc_gap_per_round``, the main job's definition), the
  curves averaged over seeds; the sync gap is their largest difference over the iterations
  ("the maximum difference of 56.67 %"; a maximum over noisy points, biased upward), the NMSE
  decrease its median over the iterations (NMSE "about 25.8 %" lower for ITMTL) and largest;
- the final mean: the seeds' mean final sync error (covered / all ordinary nodes) and NMSE.

With ``--out``: results.json, compare.md and PNGs (bars per variant with CIs: Figs 9-10
analogues; per-round convergence: Figs 11-12 analogues).

``--no-promotion``: ITMTL with anchors as the only references (the paper's Figs 9-14 set-up).
``--mobility``: meandering (the scenario's current), turn (coordinated turn, 1 m/s, 0.01
rad/s), random_walk.
"""

from __future__ import annotations

import argparse
import json
import tomllib
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy import stats

from aquasim_protocols.itmtl.metrics import mac_metrics, per_round, protocol_metrics
from aquasim_protocols.itmtl.paper import CLAIMS, node_rounds, wsc_gap_per_round
from aquasim_py import scenario

SCEN = Path(__file__).resolve().parents[1] / "scenarios" / "itmtl.toml"

#: variant -> (protocol, ordinary-group params); the scenario's [variants] tables say the same
VARIANTS: dict[str, tuple[str, dict[str, Any]]] = {
    "itmtl": ("itmtl", {}),
    "wsc": ("itmtl", {"compensate": False}),
    "tshl": ("tshl", {}),
    "mu_sync": ("mu_sync", {}),
    "mobi_sync": ("mobi_sync", {}),
    "no_imm": ("itmtl", {"imm": False}),
    "unweighted": ("itmtl", {"weighted": False}),
}
LABELS = {
    "itmtl": "ITMTL",
    "wsc": "ITMTL-wsc",
    "tshl": "TSHL",
    "mu_sync": "MU-Sync",
    "mobi_sync": "Mobi-Sync",
    "no_imm": "ITMTL, no IMM",
    "unweighted": "ITMTL, unweighted",
}
MOBILITY: dict[str, dict[str, Any] | None] = {
    "meandering": None,
    "turn": {"model": "coordinated_turn", "speed": 1.0, "turn_rate": 0.01},
    "random_walk": {"model": "random_walk", "speed_min": 0.5, "speed_max": 1.5, "leg_duration": 60.0},
}
KEYS = (
    "sync_final_mean_s",
    "sync_final_mean_all_s",
    "loc_nmse",
    "loc_rmse_m",
    "coverage_final",
    "promoted_share",
    "res_collision_fraction",
    "short_round_fraction",
)
#: the paper's numbers by figure (ITMTL)
PAPER = {c.figure: c.paper for c in CLAIMS}


def scenario_raw(
    variant: str, seed: int, duration: float, mobility: str = "meandering", promotion: bool = True
) -> dict[str, Any]:
    """The scenario file as a dict with the variant's overrides applied."""
    proto, extra = VARIANTS[variant]
    raw = tomllib.loads(SCEN.read_text())
    raw.pop("variants", None)
    raw["simulation"].update(seed=seed, duration_s=duration)
    for g in raw["nodes"]:
        g["protocol"] = proto
        params = g.setdefault("params", {})
        if g["role"] == "ordinary":
            params.update(extra)
            if proto == "itmtl" and not promotion:
                params["promotion"] = False
            mob = MOBILITY[mobility]
            if mob is not None:
                g["mobility"] = dict(mob)
    return raw


def run(args: tuple[str, int, float, str, bool]) -> tuple[dict[str, float], pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """One run: (metrics, per-round table, :func:`node_rounds`, the ``nodes`` table)."""
    variant, seed, duration, mobility, promotion = args
    raw = scenario_raw(variant, seed, duration, mobility, promotion)
    proto = VARIANTS[variant][0]
    sim = scenario.build(scenario.load_dict(raw, SCEN))
    sim.run(duration)
    fr = sim.trace.frames()
    m = {**protocol_metrics(fr, proto), **mac_metrics(fr, proto)}
    return m, per_round(fr, proto), node_rounds(fr, proto), fr["nodes"]


def t_ci(x: Sequence[float]) -> tuple[float, float, float]:
    """Mean and 95 % t-interval of the finite values (nan if fewer than two)."""
    a = np.asarray(x, float)
    a = a[np.isfinite(a)]
    if a.size == 0:
        return (np.nan, np.nan, np.nan)
    m = float(a.mean())
    if a.size < 2:
        return (m, np.nan, np.nan)
    h = float(stats.t.ppf(0.975, a.size - 1) * a.std(ddof=1) / np.sqrt(a.size))
    return (m, m - h, m + h)


def paired_bootstrap(fn: Any, n_seeds: int, n_boot: int = 2000, seed: int = 0) -> tuple[float, float, float]:
    """Statistic ``fn(seed indices)`` and its percentile bootstrap 95 % CI over seeds
    (the same resampled seeds for both variants: paired)."""
    rng = np.random.default_rng(seed)
    est = float(fn(np.arange(n_seeds)))
    boots = np.array([fn(rng.integers(0, n_seeds, n_seeds)) for _ in range(n_boot)], float)
    boots = boots[np.isfinite(boots)]
    if boots.size == 0:
        return (est, np.nan, np.nan)
    return (est, float(np.percentile(boots, 2.5)), float(np.percentile(boots, 97.5)))


def curve(rounds: list[pd.DataFrame], col: str, idx: np.ndarray) -> pd.Series:
    """Per-round mean over the selected seeds' per-round tables."""
    m = round_matrix(rounds, col)
    return pd.Series(np.nanmean(m.to_numpy()[:, idx], axis=1), index=m.index)


def round_matrix(rounds: list[pd.DataFrame], col: str) -> pd.DataFrame:
    """rounds x seeds table of one per-round column (nan where a seed has no value)."""
    return pd.concat([r[col] if col in r else pd.Series(dtype=float) for r in rounds], axis=1, keys=range(len(rounds)))


def gap_statistics(res: dict[str, list[dict[str, float]]], gaps: list[pd.DataFrame]) -> dict[str, Any]:
    """ITMTL-wsc vs ITMTL (%), each with a paired bootstrap CI over seeds: the paper's
    statistics on the per-round curves averaged over seeds (``gaps``: one
    :func:`wsc_gap_per_round` table per seed: same nodes and rounds for both), and the gaps
    of the seeds' mean final values."""
    n = min(len(res["itmtl"]), len(res["wsc"]), len(gaps))
    mats = {c: round_matrix(gaps[:n], c).to_numpy() for c in ("sync_itmtl_s", "sync_wsc_s", "nmse_itmtl", "nmse_wsc")}

    def curves_gap(idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per-round sync gap and NMSE decrease (%) of the seeds ``idx``' mean curves."""
        with np.errstate(all="ignore"):
            m = {c: np.nanmean(v[:, idx], axis=1) for c, v in mats.items()}
            sync = 100.0 * (m["sync_wsc_s"] - m["sync_itmtl_s"]) / m["sync_itmtl_s"]
            nmse = 100.0 * (m["nmse_wsc"] - m["nmse_itmtl"]) / m["nmse_wsc"]
        return sync[np.isfinite(sync)], nmse[np.isfinite(nmse)]

    def stat(which: int, fn: Any) -> Any:
        def f(idx: np.ndarray) -> float:
            g = curves_gap(idx)[which]
            return float(fn(g)) if g.size else np.nan

        return f

    def final_gap(key: str, relative_to: str) -> Any:
        vi = np.array([r[key] for r in res["itmtl"][:n]], float)
        vw = np.array([r[key] for r in res["wsc"][:n]], float)

        def f(idx: np.ndarray) -> float:
            i, w = np.nanmean(vi[idx]), np.nanmean(vw[idx])
            return float(100.0 * (w - i) / (i if relative_to == "itmtl" else w))

        return f

    return {
        "sync_max_per_round_pct": paired_bootstrap(stat(0, np.max), n),
        "sync_final_mean_pct": paired_bootstrap(final_gap("sync_final_mean_s", "itmtl"), n),
        "sync_final_mean_all_pct": paired_bootstrap(final_gap("sync_final_mean_all_s", "itmtl"), n),
        "nmse_median_decrease_per_round_pct": paired_bootstrap(stat(1, np.median), n),
        "nmse_max_decrease_per_round_pct": paired_bootstrap(stat(1, np.max), n),
        "nmse_mean_decrease_pct": paired_bootstrap(final_gap("loc_nmse", "wsc"), n),
    }


def _fmt(ci: tuple[float, float, float], scale: float = 1.0, fmt: str = ".1f") -> str:
    m, lo, hi = (v * scale for v in ci)
    if not np.isfinite(m):
        return "-"
    return f"{m:{fmt}} [{lo:{fmt}}, {hi:{fmt}}]" if np.isfinite(lo) else f"{m:{fmt}}"


def table(res: dict[str, list[dict[str, float]]]) -> list[str]:
    lines = [
        "| variant | sync covered (us) | sync all (us) | NMSE | RMSE (m) | coverage | promoted | Res collided | short rounds |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for v, rs in res.items():
        c = {k: t_ci([r.get(k, np.nan) for r in rs]) for k in KEYS}
        lines.append(
            f"| {LABELS.get(v, v)} | {_fmt(c['sync_final_mean_s'], 1e6)} | {_fmt(c['sync_final_mean_all_s'], 1e6)} | "
            f"{_fmt(c['loc_nmse'], 1.0, '.3g')} | {_fmt(c['loc_rmse_m'], 1.0, '.2f')} | "
            f"{_fmt(c['coverage_final'], 1.0, '.2f')} | {_fmt(c['promoted_share'], 1.0, '.2f')} | "
            f"{_fmt(c['res_collision_fraction'], 1.0, '.3f')} | {_fmt(c['short_round_fraction'], 1.0, '.3f')} |"
        )
    return lines


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--duration", type=float, default=600.0)
    ap.add_argument("--mobility", choices=list(MOBILITY), default="meandering")
    ap.add_argument("--variants", nargs="*", default=["itmtl", "wsc", "tshl", "mu_sync", "mobi_sync"])
    ap.add_argument("--no-promotion", action="store_true", help="anchors as the only references (Figs 9-14)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=None)
    a = ap.parse_args()
    jobs = [(v, s, a.duration, a.mobility, not a.no_promotion) for v in a.variants for s in range(1, a.seeds + 1)]
    with ProcessPoolExecutor(a.workers) as ex:
        outs = list(ex.map(run, jobs))
    res: dict[str, list[dict[str, float]]] = {}
    rounds: dict[str, list[pd.DataFrame]] = {}
    localized: dict[tuple[str, int], tuple[pd.DataFrame, pd.DataFrame]] = {}
    for (v, s, *_), (m, pr, nr, nodes) in zip(jobs, outs, strict=True):
        res.setdefault(v, []).append(m)
        rounds.setdefault(v, []).append(pr)
        localized[v, s] = (nr, nodes)
    lines = [
        f"{a.seeds} seeds (1..{a.seeds}), {a.duration:g} s, mobility {a.mobility}, "
        f"promotion {'off' if a.no_promotion else 'on'}: mean [95 % t-interval] over seeds",
        "",
        *table(res),
    ]
    gaps: dict[str, Any] = {}
    if "itmtl" in res and "wsc" in res:
        per_seed = [
            wsc_gap_per_round(localized["itmtl", s][0], localized["wsc", s][0], localized["itmtl", s][1])
            for s in range(1, a.seeds + 1)
        ]
        gaps = gap_statistics(res, per_seed)
        lines += [
            "",
            "ITMTL-wsc vs ITMTL (paired bootstrap 95 % CI over seeds):",
            "",
            "| statistic | measured | paper |",
            "|---|---|---|",
            f"| sync error, largest per-round gap, wsc above ITMTL (% of ITMTL's) | "
            f"{_fmt(gaps['sync_max_per_round_pct'])} | {PAPER['Fig. 11']} (max difference, Fig. 11) |",
            f"| sync error, final mean (covered nodes), wsc above ITMTL (%) | {_fmt(gaps['sync_final_mean_pct'])} | - |",
            f"| sync error, final mean (all ordinary nodes), wsc above ITMTL (%) | "
            f"{_fmt(gaps['sync_final_mean_all_pct'])} | - |",
            f"| NMSE, per-round decrease of ITMTL vs wsc, median over rounds (% of wsc's) | "
            f"{_fmt(gaps['nmse_median_decrease_per_round_pct'])} | {PAPER['Fig. 12']} (Fig. 12) |",
            f"| NMSE, largest per-round decrease of ITMTL vs wsc (%) | "
            f"{_fmt(gaps['nmse_max_decrease_per_round_pct'])} | - |",
            f"| NMSE, run mean, decrease of ITMTL vs wsc (%) | {_fmt(gaps['nmse_mean_decrease_pct'])} | - |",
        ]
    text = "\n".join(lines)
    print(text)
    if a.out is not None:
        a.out.mkdir(parents=True, exist_ok=True)
        (a.out / "compare.md").write_text(text + "\n")
        per_round_json = {v: [r.reset_index().to_dict("list") for r in rs] for v, rs in rounds.items()}
        (a.out / "results.json").write_text(
            json.dumps({"runs": res, "gaps": gaps, "rounds": per_round_json}, indent=1, default=float)
        )
        _plots(a.out, res, rounds)


def _plots(out: Path, res: dict[str, list[dict[str, float]]], rounds: dict[str, list[pd.DataFrame]]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(res)
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for x, key, scale, lab in (
        (ax[0], "sync_final_mean_s", 1e6, "final sync error of covered nodes (us)"),
        (ax[1], "loc_nmse", 1.0, "localization NMSE"),
    ):
        ci = [t_ci([r.get(key, np.nan) for r in res[n]]) for n in names]
        m = np.array([c[0] for c in ci]) * scale
        err = np.array([[c[0] - c[1], c[2] - c[0]] for c in ci]).T * scale
        x.bar([LABELS.get(n, n) for n in names], m, yerr=err, capsize=4)
        x.set_ylabel(lab)
        x.set_yscale("log")
        x.tick_params(axis="x", rotation=30)
    fig.tight_layout()
    fig.savefig(out / "variants.png", dpi=120)
    plt.close(fig)
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for n in names:
        idx = np.arange(len(rounds[n]))
        if any("sync_mean_s" in r for r in rounds[n]):
            ax[0].plot(curve(rounds[n], "sync_mean_s", idx) * 1e6, label=LABELS.get(n, n))
        if any("loc_nmse" in r for r in rounds[n]):
            ax[1].plot(curve(rounds[n], "loc_nmse", idx), label=LABELS.get(n, n))
    ax[0].set_xlabel("iteration (round)")
    ax[0].set_ylabel("mean sync error of localized nodes (us)")
    ax[0].set_yscale("log")
    ax[1].set_xlabel("iteration (round)")
    ax[1].set_ylabel("localization NMSE")
    ax[1].set_yscale("log")
    ax[1].legend()
    fig.tight_layout()
    fig.savefig(out / "convergence.png", dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    main()
