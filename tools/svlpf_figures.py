"""SVL-PF reproduction (Li et al., Sensors 18:8, 2018): Monte Carlo runs, Tables 2-3, Figs. 4-7.

Each run simulates the network once and runs all four estimators on the same reports (the
fusion node's ``also`` parameter; every estimator has its own random stream, so its numbers
equal those of a run of that estimator alone, i.e. of the scenario's variant).

    # Monte Carlo (per-run CSVs under OUT/runs/, resumable: finished runs are skipped)
    nice -n 10 python tools/svlpf_figures.py run --runs 50 --workers 2 [--out out/svlpf_mc]
    # Tables 2-3 (mean over runs +- 95 % CI of the eq-32 average accumulated error, k = 10..100)
    python tools/svlpf_figures.py tables [--out out/svlpf_mc]
    # Figs. 4-7 (trajectories and per-frame errors of one run) as PNGs under OUT/
    python tools/svlpf_figures.py figures [--out out/svlpf_mc] [--seed 1]
    # the diagnosis (eq 25) against the channel's obstructed links, per SNR estimate noise
    nice -n 10 python tools/svlpf_figures.py diagnosis --runs 10 --snr-std 0 1 3 6

Configurations: ``excessive`` = scenarios/svlpf_obstructed.toml (Table 3, Figs. 6-7: the excessive noise
on the obstructed links), ``gaussian`` = scenarios/svlpf_gaussian.toml (Table 2, Figs. 4-5),
``every_link`` = scenarios/svlpf.toml (Scenario 2 read as 25 % noise on every link;
docs/svlpf.md).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy: one BLAS thread per worker
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
ALSO = 'nodes.0.params.also=["toa_pf", "lssvr_pf", "consensus"]'
CONFIGS: dict[str, tuple[str, list[str]]] = {
    "excessive": ("scenarios/svlpf_obstructed.toml", []),
    "gaussian": ("scenarios/svlpf_gaussian.toml", []),
    "every_link": ("scenarios/svlpf.toml", []),
}
NAMES = {"svlpf": "SVL-PF", "consensus": "Consensus Estimation", "lssvr_pf": "LSSVR-PF", "toa_pf": "ToA-PF"}
#: the paper's Tables 2 and 3 (k = 10, 20, ..., 100), for the side-by-side print
PAPER = {
    "gaussian": {
        "svlpf": [2.2723, 2.3781, 2.6469, 2.6243, 2.5688, 2.5631, 2.5405, 2.5059, 2.5209, 2.4971],
        "consensus": [2.4758, 2.7938, 3.3335, 3.4380, 3.3274, 3.3984, 3.4429, 3.5236, 3.6684, 3.7120],
        "lssvr_pf": [2.4915, 2.6860, 3.1510, 3.1835, 3.4320, 3.3845, 3.3690, 3.5250, 3.7554, 3.8613],
        "toa_pf": [5.3947, 5.1016, 4.8245, 4.4975, 4.5450, 4.4157, 4.3370, 4.1996, 4.2199, 4.2943],
    },
    "excessive": {
        "svlpf": [3.4576, 3.5440, 3.5353, 3.5832, 3.4888, 3.4695, 3.4276, 3.4292, 3.4305, 3.4523],
        "consensus": [4.1671, 4.6963, 5.1126, 5.9764, 5.8122, 5.7013, 5.6783, 5.6683, 5.7145, 5.9295],
        "lssvr_pf": [5.2951, 5.5807, 5.5747, 6.1289, 6.1254, 6.6172, 7.1446, 7.5155, 7.8664, 8.2197],
        "toa_pf": [4.9028, 4.6084, 5.3006, 5.8910, 6.1165, 6.3656, 6.4334, 6.4526, 6.3611, 6.5046],
    },
}
STEPS = list(range(10, 101, 10))


def simulate(config: str, seed: int, overrides: list[str]) -> Any:
    """Run the scenario of ``config`` as written (its [variants] dropped) with ``overrides``;
    returns the finished Simulation."""
    import tomllib

    from aquasim_py import scenario

    path, extra = CONFIGS[config]
    raw = tomllib.loads((ROOT / path).read_text())
    raw.pop("variants", None)
    sc = scenario.load_dict(raw, ROOT / path, overrides=[*overrides, *extra], seed=seed)
    sim = scenario.build(sc)
    sim.run(sc.simulation.duration_s)
    return sim


def one_run(config: str, seed: int, out: str) -> str:
    """Simulate one (configuration, seed) with the four estimators side by side (ALSO) and
    write its per-frame errors; returns the CSV path."""
    from aquasim_protocols.svlpf.metrics import step_errors

    dest = Path(out) / "runs" / f"{config}_seed{seed}.csv"
    if dest.is_file():
        return str(dest)
    sim = simulate(config, seed, [ALSO])
    e = step_errors(sim.trace.frames())
    e.insert(0, "seed", seed)
    e.insert(0, "config", config)
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = dest.with_suffix(".tmp")
    e.to_csv(tmp, index=False)
    os.replace(tmp, dest)
    return str(dest)


def cmd_run(args: argparse.Namespace) -> None:
    jobs = [(c, s) for c in args.configs for s in range(1, args.runs + 1)]
    with ProcessPoolExecutor(max_workers=args.workers) as ex:
        futs = [ex.submit(one_run, c, s, args.out) for c, s in jobs]
        for i, f in enumerate(futs, 1):
            print(f"[{i}/{len(futs)}] {f.result()}", flush=True)


def load_runs(out: str) -> pd.DataFrame:
    files = sorted((Path(out) / "runs").glob("*.csv"))
    if not files:
        sys.exit(f"error: {out}/runs: no Monte Carlo results (run the 'run' command first)")
    return pd.concat([pd.read_csv(f) for f in files], ignore_index=True)


def summary(df: pd.DataFrame) -> pd.DataFrame:
    """Mean, 95 % CI half-width (Student t over runs) and run count of eave per (config, algorithm, k)."""
    from scipy import stats

    d = df[df["k"].isin(STEPS)]
    g = d.groupby(["config", "algorithm", "k"])["eave"]
    s = g.agg(["mean", "std", "count"]).reset_index()
    s["ci95"] = stats.t.ppf(0.975, np.maximum(s["count"] - 1, 1)) * s["std"] / np.sqrt(s["count"])
    return s


def cmd_tables(args: argparse.Namespace) -> None:
    df = load_runs(args.out)
    s = summary(df)
    for config, title in (
        ("gaussian", "Table 2 (universal noise)"),
        ("excessive", "Table 3 (excessive noise)"),
        ("every_link", "Table 3, Scenario 2 read as 25 % noise on every link"),
    ):
        c = s[s["config"] == config]
        if len(c) == 0:
            continue
        n = int(c["count"].min())
        print(f"\n{title}: average accumulated error (m), eq 32, mean +- 95 % CI over {n} runs")
        print(f"{'method':<22}" + "".join(f"{'k=' + str(k):>13}" for k in STEPS))
        for algo in ("svlpf", "consensus", "lssvr_pf", "toa_pf"):
            a = c[c["algorithm"] == algo].set_index("k")
            if len(a) == 0:
                continue
            print(f"{NAMES[algo]:<22}" + "".join(f"{a.loc[k, 'mean']:>7.2f}+-{a.loc[k, 'ci95']:<4.2f}" for k in STEPS))
            paper = PAPER["excessive" if config == "every_link" else config]
            print(f"{'  paper':<22}" + "".join(f"{v:>13.2f}" for v in paper[algo]))
        paired(df[(df["config"] == config) & (df["k"] == 100)])
    if args.csv:
        s.to_csv(Path(args.out) / "tables.csv", index=False)


def paired(d: pd.DataFrame) -> None:
    """Per-seed differences of eq 32 at k = 100 against SVL-PF: mean +- 95 % CI (paired t)."""
    from scipy import stats

    w = d.pivot_table(index="seed", columns="algorithm", values="eave")
    if "svlpf" not in w.columns or len(w) < 2:
        return
    parts = []
    for algo in ("consensus", "lssvr_pf", "toa_pf"):
        if algo in w.columns:
            diff = (w[algo] - w["svlpf"]).dropna()
            h = stats.t.ppf(0.975, len(diff) - 1) * diff.std() / np.sqrt(len(diff))
            parts.append(f"{NAMES[algo]} {diff.mean():+.2f}+-{h:.2f}")
    print("paired difference to SVL-PF at k=100 (m): " + ", ".join(parts))


def diagnosis_run(snr_std: float, seed: int) -> pd.DataFrame:
    """One run of scenarios/svlpf_obstructed.toml (SVL-PF alone) with the receivers' SNR estimate noise
    std ``snr_std`` (dB): per frame, the flagged sensors against the selected sensors whose
    link from the target the channel obstructed (ground truth: the obstacle field rebuilt
    from the run's keyed streams, as the channel draws it)."""
    from aquasim_py.channel.obstacles import ObstacleField

    sim = simulate("excessive", seed, [f"channel.snr_estimate_std_db={snr_std}"])
    cfg = sim.channel_config.obstacles
    truth = ObstacleField(
        cfg, lambda a, b: float(sim.rng("obstacle", a, b).random()), lambda a, b: sim.rng("obstacle", a, b, "delay")
    )
    rows = []
    sv = sim.trace.frames()["svlpf"]
    for sel, flg in zip(sv["selected"], sv["flagged"]):
        sel_ids = {int(i) for i in str(sel).split()}
        flagged = {int(i) for i in str(flg).split() if i.isdigit()}
        obstructed = {i for i in sel_ids if truth.obstructed(1, i)}  # node 1: the target
        rows.append((snr_std, seed, len(obstructed), len(flagged - obstructed), len(obstructed - flagged)))
    return pd.DataFrame(rows, columns=["snr_std_db", "seed", "obstructed", "false_flags", "misses"])


def cmd_diagnosis(args: argparse.Namespace) -> None:
    jobs = [(x, s) for x in args.snr_std for s in range(1, args.runs + 1)]
    with ProcessPoolExecutor(max_workers=args.workers) as ex:
        d = pd.concat(list(ex.map(diagnosis_run, *zip(*jobs))), ignore_index=True)
    print(f"diagnosis (eq 25) of scenarios/svlpf.toml, {args.runs} runs x 100 frames per SNR noise level")
    print(
        f"{'SNR noise std (dB)':>18} {'obstructed/frame':>17} {'false flags/frame':>18} {'misses/frame':>13} {'exact frames':>13}"
    )
    for x, g in d.groupby("snr_std_db"):
        exact = ((g["false_flags"] == 0) & (g["misses"] == 0)).mean()
        print(
            f"{x:>18g} {g['obstructed'].mean():>17.2f} {g['false_flags'].mean():>18.4f}"
            f" {g['misses'].mean():>13.4f} {100 * exact:>12.1f}%"
        )


def cmd_figures(args: argparse.Namespace) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    df = load_runs(args.out)
    out = Path(args.out)
    colors = {"svlpf": "green", "toa_pf": "red", "consensus": "black", "lssvr_pf": "purple"}
    for config, (ftraj, ferr) in (("gaussian", (4, 5)), ("excessive", (6, 7))):
        d = df[(df["config"] == config) & (df["seed"] == args.seed)]
        if len(d) == 0:
            continue
        fig = plt.figure(figsize=(6, 5))
        ax = fig.add_subplot(projection="3d")
        truth = d[d["algorithm"] == "svlpf"].sort_values("k")
        ax.plot(truth["true_x"], truth["true_y"], truth["true_z"], color="blue", label="real state")
        for algo, g in d.groupby("algorithm"):
            g = g.sort_values("k")
            ax.plot(g["x"], g["y"], g["z"], color=colors[str(algo)], lw=0.8, label=NAMES[str(algo)])
        ax.set(xlabel="x (m)", ylabel="y (m)", zlabel="depth (m)", title=f"Fig. {ftraj}: trajectories ({config})")
        ax.legend(fontsize=7)
        fig.savefig(out / f"fig{ftraj}_{config}_trajectory.png", dpi=120)
        plt.close(fig)
        fig, ax = plt.subplots(figsize=(7, 4))
        for algo, g in d.groupby("algorithm"):
            g = g.sort_values("k")
            ax.plot(g["k"], g["error"], color=colors[str(algo)], lw=0.9, label=NAMES[str(algo)])
        ax.set(xlabel="time frame k", ylabel="localization error E_k (m)", title=f"Fig. {ferr}: errors ({config})")
        ax.legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(out / f"fig{ferr}_{config}_errors.png", dpi=120)
        plt.close(fig)
    print(f"figures written under {out}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run", help="Monte Carlo runs")
    r.add_argument("--runs", type=int, default=50)
    r.add_argument("--workers", type=int, default=2)
    r.add_argument("--configs", nargs="+", default=sorted(CONFIGS), choices=sorted(CONFIGS))
    t = sub.add_parser("tables", help="print Tables 2-3")
    t.add_argument("--csv", action="store_true", help="also write OUT/tables.csv")
    f = sub.add_parser("figures", help="draw Figs. 4-7")
    f.add_argument("--seed", type=int, default=1)
    for p in (r, t, f):
        p.add_argument("--out", default=str(ROOT / "out" / "svlpf_mc"))
    g = sub.add_parser("diagnosis", help="the diagnosis against the obstructed links, per SNR estimate noise")
    g.add_argument("--runs", type=int, default=10)
    g.add_argument("--workers", type=int, default=2)
    g.add_argument("--snr-std", type=float, nargs="+", default=[0.0, 1.0, 3.0, 6.0])
    args = ap.parse_args()
    {"run": cmd_run, "tables": cmd_tables, "figures": cmd_figures, "diagnosis": cmd_diagnosis}[args.cmd](args)


if __name__ == "__main__":
    main()
