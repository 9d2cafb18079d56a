"""Reproduce the STVF paper's evaluation (Hu et al., Sensors 2018, Sec. 5): Figs 3-9 and the
headline numbers, for STVF and the SLMP baseline.

    python tools/stvf_figures.py headline            # Sec. 5.2.3 (Ns = 200): avg RMSE, share below, Figs 5-6
    python tools/stvf_figures.py fig3 fig4 fig7 fig8 fig9 --seeds 10 --workers 2
    python tools/stvf_figures.py fig7 --nodes 50 --duration 120 --seeds 10   # scaled-down
    python tools/stvf_figures.py ablation --nodes 50 --duration 120 --training 60 --seeds 4
                                                     # STVF variants vs SLMP (docs/stvf.md)

``--nodes`` scales the network at constant density (area side 500 m x sqrt(nodes / 200)), so a
small run keeps Table 1's geometry per node. Results go to ``--out`` (default
out/stvf_figures) as CSV (one row per run) and PNG. Each run uses the scenario files
``scenarios/stvf.toml`` with ``--set``-style overrides, so what is plotted is what the CLI runs.
"""

from __future__ import annotations

import argparse
import math
import time
import tomllib
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any, cast

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "stvf.toml"
PAPER = {"avg_rmse_m": 7.09, "share_below_avg": 0.785, "converge_within_5": 0.8907}


def overrides_for(
    protocol: str, nodes: int, beacon_share: float, duration: float, seed: int, extra: dict[str, Any]
) -> list[str]:
    """--set overrides for one run: network scaled at constant density, the protocol on both
    groups, and the experiment's parameters (keys relative to the unknown nodes' params when
    they start with 'p.')."""
    side = 500.0 * math.sqrt(nodes / 200.0)
    nb = max(1, int(round(nodes * beacon_share)))
    out = [
        f"simulation.duration_s={duration}",
        f"simulation.seed={seed}",
        f"environment.volume.hi=[{side}, {side}, 30.0]",
        f"nodes[0].count={nb}",
        f"nodes[1].count={nodes - nb}",
        f"nodes[0].protocol={protocol}",
        f"nodes[1].protocol={protocol}",
    ]
    for k, v in extra.items():
        if k.startswith("p."):
            out.append(f"nodes[0].params.{k[2:]}={v}")
            out.append(f"nodes[1].params.{k[2:]}={v}")
        else:
            out.append(f"{k}={v}")
    return out


def run_one(job: dict[str, Any]) -> dict[str, Any]:
    """One simulation; returns the job's keys plus the protocol's metrics and CPU time."""
    from aquasim_py import scenario
    from aquasim_py.node import Node
    from aquasim_py.registry import get

    # the file's base run: its variants set the protocols' own parameters (SLMP's training_s),
    # which the protocols these overrides put on both groups do not take
    raw = tomllib.loads(SCENARIO.read_text())
    raw.pop("variants", None)
    sc = scenario.load_dict(raw, SCENARIO, overrides=job["overrides"])
    c0 = time.process_time()
    sim = scenario.build(sc)
    sim.run(sc.simulation.duration_s)
    cpu = time.process_time() - c0
    frames = sim.trace.frames()
    from aquasim_protocols.stvf.metrics import localization_metrics

    if job.get("t_min") is not None:
        # compare protocols over the same window (SLMP only localizes after its training)
        m = localization_metrics(frames, job["protocol"], t_min=job["t_min"])
    else:
        # the registry holds any class with a name and Params; the built-in ones are Nodes
        m = cast(type[Node], get(job["protocol"])).metrics(frames)
    row = {k: v for k, v in job.items() if k not in ("overrides", "keep", "t_min")}
    row.update(m)
    row["cpu_s"] = cpu
    # the whole run's CPU over all of its localizations, not only the scored ones
    total = (
        m["localizations"]
        if job.get("t_min") is None
        else localization_metrics(frames, job["protocol"])["localizations"]
    )
    row["cpu_per_localization_ms"] = 1e3 * cpu / max(total, 1.0)
    if job.get("keep"):
        row["_frames"] = frames
    return row


def _jobs(name: str, args: argparse.Namespace) -> list[dict[str, Any]]:
    jobs: list[dict[str, Any]] = []

    def add(protocol: str, share: float, extra: dict[str, Any], **tags: Any) -> None:
        for s in range(args.seeds):
            seed = args.seed + s
            jobs.append(
                dict(
                    experiment=name,
                    protocol=protocol,
                    beacon_share=share,
                    seed=seed,
                    overrides=overrides_for(protocol, args.nodes, share, args.duration, seed, extra),
                    **tags,
                )
            )

    shares = [0.10, 0.15, 0.20, 0.25, 0.30]
    if name == "fig3":
        for share in shares:
            for nr in (1, 2, 3, 4, 5):
                add("stvf", share, {"p.n_ref": nr}, t_min=args.score_from, n_ref=nr)
    elif name == "fig4":
        for share in shares:
            for ns in (50, 100, 200, 400):
                add("stvf", share, {"p.n_samples": ns}, t_min=args.score_from, n_samples=ns)
    elif name in ("fig7", "fig8", "fig9"):
        slmp_extra = {"nodes[1].params.training_s": args.training}
        if name == "fig7":
            points = [
                (
                    "density",
                    d,
                    {"channel.max_range_m": round(math.sqrt(d * 250000 / (200 * math.pi)), 2), "p.range_m": 100.0},
                )
                for d in args.densities
            ]
        elif name == "fig8":
            points = [("delta", d, {"p.delta": d}) for d in (0.8, 0.85, 0.9, 0.95, 0.97, 0.99, 1.0)]
        else:
            points = [("noise_ratio", r, {"p.noise_ratio": r}) for r in (0.005, 0.01, 0.02, 0.03, 0.04)]
        for key, val, extra in points:
            add("stvf", 0.20, {**extra, "nodes[1].params.n_ref": 2}, t_min=args.training, **{key: val})
            add("slmp", 0.20, {**extra, **slmp_extra}, t_min=args.training, **{key: val})
    elif name == "ablation":
        # What separates STVF from SLMP at Table 1's density: one change per row (docs/stvf.md).
        matched = round(3 * (0.02 * 50.0 / 1.5) ** 2, 3)  # Gam(3, beta) with mean 1/sigma^2, 2 % of 50 m
        variants: dict[str, dict[str, Any]] = {
            "Nr=2": {"nodes[1].params.n_ref": 2},
            "Nr=3 (Table 1)": {},
            "Nr=3, one sample set": {"p.common_random_numbers": "true"},
            "Nr=3, noise prior matched": {"p.noise_rate_ms2": matched},
            "Nr=2, noise prior matched": {"nodes[1].params.n_ref": 2, "p.noise_rate_ms2": matched},
            "Nr=5": {"nodes[1].params.n_ref": 5},
        }
        for variant, changes in variants.items():
            add("stvf", 0.20, changes, t_min=args.training, variant=variant)
        add("slmp", 0.20, {"nodes[1].params.training_s": args.training}, t_min=args.training, variant="SLMP")
    else:
        raise SystemExit(f"unknown experiment {name!r}")
    return jobs


def _plot_xy(df: pd.DataFrame, x: str, group: str, ys: list[tuple[str, str]], path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(ys), figsize=(5 * len(ys), 4))
    for ax, (col, label) in zip(np.atleast_1d(axes), ys):
        for g, sub in df.groupby(group):
            stats = sub.groupby(x)[col].agg(["mean", "sem"]).reset_index()
            ax.errorbar(stats[x], stats["mean"], yerr=stats["sem"].fillna(0), marker="o", capsize=3, label=str(g))
        ax.set_xlabel(x)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.legend(title=group)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _plot_bars(df: pd.DataFrame, x: str, ys: list[tuple[str, str]], path: Path, title: str) -> None:
    """Horizontal bars (mean +- s.e.m.) for categorical experiments, in the order run."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    order = list(dict.fromkeys(df[x]))
    fig, axes = plt.subplots(1, len(ys), figsize=(6 * len(ys), 0.5 * len(order) + 1.5), sharey=True)
    for ax, (col, label) in zip(np.atleast_1d(axes), ys):
        stats = df.groupby(x)[col].agg(["mean", "sem"]).reindex(order)
        colors = ["tab:blue" if p == "slmp" else "tab:orange" for p in df.groupby(x)["protocol"].first().reindex(order)]
        ax.barh(range(len(order)), stats["mean"], xerr=stats["sem"].fillna(0), color=colors, capsize=3)
        ax.set_yticks(range(len(order)), order)
        ax.set_xlabel(label)
        ax.grid(alpha=0.3, axis="x")
    np.atleast_1d(axes)[0].invert_yaxis()  # the axes share y: invert once, first run on top
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def headline(args: argparse.Namespace, out: Path) -> None:
    """Sec. 5.2.3's run(s): Table 1 with Nr = 3 and Ns = 200, every instant a node is localized;
    avg RMSE, share below it, iterations (Figs 5 and 6)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = []
    frames = None
    for s in range(args.seeds):
        job = dict(
            experiment="headline",
            protocol="stvf",
            seed=args.seed + s,
            keep=s == 0,
            overrides=overrides_for("stvf", args.nodes, 0.2, args.duration, args.seed + s, {"p.n_samples": 200}),
        )
        row = run_one(job)
        if s == 0:
            frames = row.pop("_frames")
        rows.append(row)
        print({k: (round(v, 4) if isinstance(v, float) else v) for k, v in row.items()}, flush=True)
    df = pd.DataFrame(rows)
    df.to_csv(out / "headline.csv", index=False)
    assert frames is not None
    from aquasim_protocols.stvf.metrics import localization_metrics

    late = localization_metrics(frames, "stvf", t_min=args.training)
    print(
        f"seed {args.seed}, t >= {args.training} s (SLMP's window):",
        {k: round(v, 4) for k, v in late.items()},
        flush=True,
    )
    frames["estimates"].to_csv(out / "headline_estimates.csv", index=False)
    e = frames["estimates"]
    e = e[e["protocol"] == "stvf"]
    err2 = (e.x - e.true_x) ** 2 + (e.y - e.true_y) ** 2 + (e.z - e.true_z) ** 2
    per_node = np.sqrt(err2.groupby(e.node).mean())
    fig, ax = plt.subplots(1, 3, figsize=(16, 4))
    ax[0].bar(range(len(per_node)), per_node.to_numpy())
    ax[0].axhline(per_node.mean(), color="k", ls="--", label=f"mean {per_node.mean():.2f} m")
    ax[0].axhline(PAPER["avg_rmse_m"], color="r", ls=":", label="paper 7.09 m")
    ax[0].set(xlabel="unknown node", ylabel="RMSE (m)", title="Fig. 5a")
    ax[0].legend()
    node = (per_node - per_node.median()).abs().idxmin()
    tr = e[(e.node == node) & (e.time <= e.time.min() + 100)]
    ax[1].plot(tr.true_x, tr.true_y, "k-", label="true")
    ax[1].plot(tr.x, tr.y, "r.", ms=3, label="STVF")
    ax[1].set(xlabel="x (m)", ylabel="y (m)", title=f"Fig. 5b: node {node}, 100 s")
    ax[1].legend()
    it = np.sort(e["iterations"].to_numpy())
    ax[2].step(it, np.arange(1, it.size + 1) / it.size, where="post")
    ax[2].axvline(5, color="r", ls=":")
    ax[2].set(xlabel="iterations", ylabel="CDF", title=f"Fig. 6: <=5 in {np.mean(it <= 5):.1%}")
    fig.tight_layout()
    fig.savefig(out / "fig5_fig6.png", dpi=120)
    plt.close(fig)
    summary = df[
        [
            "avg_rmse_m",
            "share_below_avg",
            "converge_within_5",
            "mean_iterations",
            "coverage",
            "cpu_s",
            "cpu_per_localization_ms",
        ]
    ].agg(["mean", "std"])
    print(summary.to_string())
    print("paper:", PAPER)


# experiment -> (x column, group column, [(y column, label)], title)
FIGURES: dict[str, tuple[str, str, list[tuple[str, str]], str]] = {
    "fig3": (
        "n_ref",
        "beacon_share",
        [("mean_error_m", "localization error (m)"), ("coverage", "coverage")],
        "Fig. 3: STVF vs Nr",
    ),
    "fig4": (
        "n_samples",
        "beacon_share",
        [
            ("mean_error_m", "localization error (m)"),
            ("cpu_per_localization_ms", "CPU per localization, whole run (ms)"),
        ],
        "Fig. 4: STVF vs samples",
    ),
    "fig7": (
        "density",
        "protocol",
        [("coverage", "coverage"), ("mean_error_m", "localization error (m)")],
        "Fig. 7, density: STVF vs SLMP",
    ),
    "fig8": (
        "delta",
        "protocol",
        [("coverage", "coverage"), ("mean_error_m", "localization error (m)")],
        "Fig. 8, confidence threshold: STVF vs SLMP",
    ),
    "fig9": (
        "noise_ratio",
        "protocol",
        [("coverage", "coverage"), ("mean_error_m", "localization error (m)")],
        "Fig. 9, ranging noise std / delay: STVF vs SLMP",
    ),
    "ablation": (
        "variant",
        "protocol",
        [("mean_error_m", "localization error (m)"), ("coverage", "coverage")],
        "STVF variants against SLMP, density 16, 20 % beacons",
    ),
}


def report(name: str, df: pd.DataFrame, args: argparse.Namespace, out: Path) -> None:
    """PNG (mean +- s.e.m. over seeds) and a printed table for one experiment's runs."""
    x, group, ys, title = FIGURES[name]
    setup = (
        f"{args.nodes} nodes, {args.duration:g} s, {df['seed'].nunique()} seed(s)"
        + f", scored t >= {args.training if group == 'protocol' else (args.score_from or 0):g} s"
        + "; mean +- s.e.m."
    )
    if pd.api.types.is_numeric_dtype(df[x]):
        _plot_xy(df, x, group, ys, out / f"{name}.png", f"{title}\n({setup})")
    else:
        _plot_bars(df, x, ys, out / f"{name}.png", f"{title}\n({setup})")
    cols = [c for c, _ in ys] + (["avg_rmse_m"] if "avg_rmse_m" in df else [])
    print(name, setup)
    print(df.groupby([x, group])[cols].agg(["mean", "sem"]).round(3).to_string(), flush=True)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("experiments", nargs="+", help="headline fig3 fig4 fig7 fig8 fig9 ablation")
    ap.add_argument("--nodes", type=int, default=200)
    ap.add_argument("--duration", type=float, default=500.0)
    ap.add_argument("--training", type=float, default=100.0, help="SLMP beacon training (s)")
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument(
        "--score-from",
        type=float,
        default=None,
        help="fig3/fig4: score STVF on t >= this (s), after its start-up transient",
    )
    ap.add_argument("--densities", type=float, nargs="+", default=[6, 8, 12, 16, 20, 24], help="node densities of fig7")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", default=str(ROOT / "out" / "stvf_figures"))
    ap.add_argument(
        "--replot",
        action="store_true",
        help="redraw the PNGs and tables from the CSVs already in --out (give the same set-up options)",
    )
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name in args.experiments:
        if name == "headline":
            headline(args, out)
            continue
        if args.replot:
            report(name, pd.read_csv(out / f"{name}.csv"), args, out)
            continue
        jobs = _jobs(name, args)
        rows: list[dict[str, Any]] = []
        partial = out / f"{name}.partial.csv"
        with ProcessPoolExecutor(max(1, args.workers)) as ex:
            for row in ex.map(run_one, jobs):  # job order, whatever finishes first
                rows.append(row)
                pd.DataFrame(rows).to_csv(partial, index=False)  # a long sweep can be read while it runs
        df = pd.DataFrame(rows)
        df.to_csv(out / f"{name}.csv", index=False)
        partial.unlink(missing_ok=True)
        report(name, df, args, out)


if __name__ == "__main__":
    main()
