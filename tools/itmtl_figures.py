"""Draw the ITMTL paper's Figs 10, 13, 14 and 15-17 from the sweeps' CSV files.

    aquasim-py sweep scenarios/itmtl_fig10_sweep.toml --out out/itmtl-fig10
    python tools/itmtl_figures.py fig10 out/itmtl-fig10/sweep.csv --out docs/itmtl/figs
    (likewise fig13 / fig14 from itmtl_fig13_sweep.toml / itmtl_fig14_sweep.toml and
    network from itmtl_network_sweep.toml: Figs 15-17)

Each figure shows the mean over the sweep's runs with its 95 % t-interval (error bars), and a
markdown table of the same numbers is written beside the PNG (``figNN.md``). Metrics are the
generic ones every protocol reports (``localization.nmse``, ``sync.final_mean_abs_error_s``)
so that protocols are compared on one definition; Fig. 16 (the paper's "average
synchronization errors of ordinary nodes in the whole network") is the generic final sync
error over every ordinary node with a clock estimate, and Fig. 15 ITMTL's
``itmtl.coverage_final`` (share of ordinary nodes localized in one of their last three
rounds, the paper's "range of synchronization and localization").
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy import stats

LABELS = {"itmtl": "ITMTL", "wsc": "ITMTL-wsc", "tshl": "TSHL", "mu_sync": "MU-Sync", "mobi_sync": "Mobi-Sync"}
NMSE = "localization.nmse"
SYNC = "sync.final_mean_abs_error_s"


def ci(x: pd.Series) -> pd.Series:
    """Mean and 95 % t half-width of the finite values."""
    a = x.to_numpy(float)
    a = a[np.isfinite(a)]
    if a.size < 2:
        return pd.Series({"mean": a.mean() if a.size else np.nan, "half": np.nan, "n": a.size})
    return pd.Series(
        {
            "mean": a.mean(),
            "half": stats.t.ppf(0.975, a.size - 1) * a.std(ddof=1) / np.sqrt(a.size),
            "n": a.size,
        }
    )


def summarize(df: pd.DataFrame, by: list[str], metric: str) -> pd.DataFrame:
    return df.groupby(by, sort=True)[metric].apply(ci).unstack()


def _plot(
    out: Path,
    name: str,
    tab: pd.DataFrame,
    x: str,
    series: str | None,
    ylabel: str,
    xlabel: str,
    label: Callable[[Any], str | None] = str,
    log: bool = True,
    title: str = "",
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    groups = [(None, tab)] if series is None else list(tab.groupby(level=series))
    for key, g in groups:
        xs = g.index.get_level_values(x)
        ax.errorbar(
            xs,
            g["mean"],
            yerr=g["half"],
            marker="o",
            capsize=3,
            linestyle="-" if pd.api.types.is_numeric_dtype(xs) else "none",  # no line between categories
            label=None if key is None else (label(key) or str(key)),
        )
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    if log:
        ax.set_yscale("log")
    if series is not None:
        ax.legend()
    fig.tight_layout()
    fig.savefig(out / f"{name}.png", dpi=120)
    plt.close(fig)


def _md(tab: pd.DataFrame, scale: float = 1.0, fmt: str = ".3g") -> str:
    rows = ["| " + " | ".join(tab.index.names) + " | mean | 95 % CI | runs |", "|" + "---|" * (tab.index.nlevels + 3)]
    for idx, r in tab.iterrows():
        keys = idx if isinstance(idx, tuple) else (idx,)
        m, h = r["mean"] * scale, r["half"] * scale
        rows.append(
            "| " + " | ".join(str(k) for k in keys) + f" | {m:{fmt}} | [{m - h:{fmt}}, {m + h:{fmt}}] | {int(r['n'])} |"
        )
    return "\n".join(rows)


def fig10(df: pd.DataFrame, out: Path) -> str:
    df = df.assign(references=df["nodes.0.placement"].map(lambda s: len(json.loads(s)["positions"])))
    tab = summarize(df, ["variant", "references"], NMSE)
    _plot(
        out,
        "fig10",
        tab,
        "references",
        "variant",
        "localization NMSE",
        "number of anchors",
        LABELS.get,
        title="Fig. 10 analogue: NMSE vs number of references (anchors only)",
    )
    return "Fig. 10: NMSE vs number of references\n\n" + _md(tab)


def fig13(df: pd.DataFrame, out: Path) -> str:
    df = df.assign(tracking=df["nodes.1.params.imm"].map(lambda v: "IMM" if str(v) == "True" else "none"))
    tab = summarize(df, ["tracking", "nodes.1.mobility.iota"], NMSE)
    _plot(
        out,
        "fig13",
        tab,
        "nodes.1.mobility.iota",
        "tracking",
        "localization NMSE",
        "current coefficient iota",
        title="Fig. 13 analogue: ITMTL with and without IMM tracing",
    )
    return "Fig. 13: NMSE with and without IMM tracing\n\n" + _md(tab)


def fig14(df: pd.DataFrame, out: Path) -> str:
    df = df.assign(mobility=df["nodes.1.mobility"].map(lambda s: json.loads(s)["model"]))
    tab = summarize(df, ["mobility"], NMSE)
    _plot(
        out,
        "fig14",
        tab,
        "mobility",
        None,
        "localization NMSE",
        "mobility model",
        title="Fig. 14 analogue: ITMTL under three mobility models",
    )
    return "Fig. 14: NMSE vs mobility model\n\n" + _md(tab)


def network(df: pd.DataFrame, out: Path) -> str:
    side = df["environment.volume"].map(lambda s: json.loads(s)["hi"][0])
    n = df["nodes"].map(lambda s: sum(g["count"] for g in json.loads(s)))
    df = df.assign(
        density=np.round(n * np.pi * 1200.0**2 / side**2, 1),
        anchors=df["nodes"].map(
            lambda s: f"{round(100 * json.loads(s)[0]['count'] / sum(g['count'] for g in json.loads(s)))} %"
        ),
    )
    parts = []
    for name, metric, lab, log in (
        ("fig15", "itmtl.coverage_final", "range of sync and localization (share of nodes)", False),
        ("fig16", SYNC, "average final sync error of the ordinary nodes (s)", True),
        ("fig17", NMSE, "localization NMSE", True),
    ):
        tab = summarize(df, ["anchors", "density"], metric)
        title = f"Fig. {name[3:]} analogue: ITMTL, 30 nodes, promotion on"
        _plot(out, name, tab, "density", "anchors", lab, "node density (mean neighbours)", log=log, title=title)
        parts.append(f"{name}: {lab}\n\n" + _md(tab))
    return "\n\n".join(parts)


FIGS = {"fig10": fig10, "fig13": fig13, "fig14": fig14, "network": network}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("figure", choices=list(FIGS))
    ap.add_argument("csv", type=Path)
    ap.add_argument("--out", type=Path, default=Path("docs/itmtl/figs"))
    a = ap.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    text = FIGS[a.figure](pd.read_csv(a.csv), a.out)
    (a.out / f"{a.figure}.md").write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
