"""The routing papers' published trends, checked on the sweeps of scenarios/routing_compare.toml
and scenarios/vbf_radius.toml: one verdict per trend (agrees / disagrees / not checked), with
the numbers behind it, as a Markdown table (docs/routing.md, "The published trends").

    aquasim-py sweep scenarios/routing_compare.toml --out out/routing_compare-sweep
    aquasim-py sweep scenarios/vbf_radius.toml --out out/vbf_radius-sweep
    aquasim-py sweep scenarios/routing_compare.toml --out out/routing_lifetime-sweep \
        --set nodes.1.count=286 --set nodes.1.battery.capacity_j=60 --set nodes.2.battery.capacity_j=60 \
        --set sweep.runs=3 --set 'sweep.grid={variant=["flooding", "vbf", "hh_vbf", "dbr", "eedbr"]}'
    python tools/routing_trends.py out/routing_compare-sweep --radius out/vbf_radius-sweep \
        --lifetime out/routing_lifetime-sweep

A trend "rises with x" agrees when the mean at the largest x exceeds the mean at the smallest
by more than both points' 95 % intervals allow (the upper bound at the smallest x is below the
lower bound at the largest) and no step between neighbouring x falls by more than its
intervals allow. "Highest" agrees when, at every x, no other protocol's mean exceeds the
protocol's upper bound. "Later" agrees when one protocol's lower bound is above the other's
upper bound. A "rises" or "later" whose intervals leave it open is "not resolved" (more
seeds decide it); "disagrees" there means the opposite beyond the intervals. The intervals
are Student-t over the seeds (:func:`aquasim_py.metrics.summarize_runs`).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from aquasim_py.metrics import summarize_runs

COUNT = "nodes.1.count"
RADIUS = "nodes.2.routing_params.radius_m"
#: nodes beside the relays in routing_compare.toml (4 sinks, 10 sources)
OTHERS = 14


@dataclass
class Verdict:
    claim: str
    source: str
    ours: str
    verdict: str


def points(runs: pd.DataFrame, x: str, metric: str) -> pd.DataFrame:
    """Mean and 95 % interval of ``metric`` per (variant, x), sorted by x."""
    if metric not in runs.columns:
        return pd.DataFrame()
    s = summarize_runs(runs, ["variant", x], [metric])
    return s.sort_values(["variant", x]).reset_index(drop=True)


def rises(p: pd.DataFrame, variant: str, x: str) -> tuple[bool, str]:
    """Whether the variant's means rise with ``x`` (module docstring), and the means as text."""
    v = p[p["variant"] == variant].sort_values(x)
    lo, hi = v["ci95_low"].to_numpy(), v["ci95_high"].to_numpy()
    up = bool(hi[0] < lo[-1]) and all(hi[i + 1] >= lo[i] for i in range(len(v) - 1))
    return up, _means(v, x)


def highest(p: pd.DataFrame, variant: str, x: str) -> tuple[bool, str]:
    """Whether no other variant's mean exceeds ``variant``'s upper bound at any ``x``."""
    ok = True
    for _, g in p.groupby(x):
        mine = g[g["variant"] == variant]
        if mine.empty:
            return False, "no such variant"
        others = g[g["variant"] != variant]
        ok &= bool((others["mean"] <= float(mine["ci95_high"].iloc[0])).all())
    best = p.loc[p.groupby(x)["mean"].idxmax()]
    return ok, ", ".join(f"{_x(r[x])}: {r['variant']}" for _, r in best.iterrows())


def _x(v: float) -> str:
    return f"{int(v) + OTHERS} nodes" if float(v).is_integer() else f"W = {v:g} m"


def _means(v: pd.DataFrame, x: str) -> str:
    return ", ".join(f"{r['mean']:.3g} [{r['ci95_low']:.3g}, {r['ci95_high']:.3g}]" for _, r in v.iterrows())


def falls(p: pd.DataFrame, variant: str, x: str) -> bool:
    """Whether the variant's mean at the largest ``x`` is below the one at the smallest beyond
    both intervals (the opposite of :func:`rises`)."""
    v = p[p["variant"] == variant].sort_values(x)
    return bool(len(v)) and bool(v["ci95_low"].iloc[0] > v["ci95_high"].iloc[-1])


def _word(ok: bool, against: bool = True) -> str:
    """The verdict: "agrees"; "disagrees" where the data show the opposite (``against``), or
    where the check has no such third case; else "not resolved" (the intervals overlap)."""
    return "agrees" if ok else "disagrees" if against else "not resolved"


def later(runs: pd.DataFrame, metric: str, first: str, second: str) -> tuple[bool, str]:
    """Whether ``first``'s mean ``metric`` is above ``second``'s beyond both intervals."""
    s = summarize_runs(runs, ["variant"], [metric]).set_index("variant")
    if first not in s.index or second not in s.index:
        return False, "not in the sweep"
    a, b = s.loc[first], s.loc[second]
    text = ", ".join(f"{v}: {r['mean']:.4g} [{r['ci95_low']:.4g}, {r['ci95_high']:.4g}]" for v, r in s.iterrows())
    return bool(a["ci95_low"] > b["ci95_high"]), text


def check(compare: Path, radius: Path | None, lifetime: Path | None = None) -> list[Verdict]:
    runs = pd.read_csv(compare / "sweep.csv")
    out: list[Verdict] = []
    pdr = points(runs, COUNT, "net.pdr")
    ok, txt = rises(pdr, "dbr", COUNT)
    out.append(
        Verdict(
            "DBR's delivery ratio rises with node density",
            "Yan, Shi and Cui 2008",
            txt,
            _word(ok, falls(pdr, "dbr", COUNT)),
        )
    )
    top = pdr[(pdr["variant"] == "dbr") & (pdr[COUNT] == pdr[COUNT].max())]
    dense = float(top["mean"].iloc[0]) if len(top) else float("nan")
    out.append(
        Verdict(
            "DBR delivers at least 95 % of the packets in dense networks",
            "Yan, Shi and Cui 2008, abstract",
            f"{dense:.3f} at {_x(pdr[COUNT].max())}",
            _word(dense >= 0.95),
        )
    )
    red = points(runs, COUNT, "net.copies_per_delivered")
    ok, txt = rises(red, "dbr", COUNT)
    out.append(
        Verdict(
            "DBR's redundancy (copies per delivered packet) rises with density",
            "Yan, Shi and Cui 2008",
            txt,
            _word(ok, falls(red, "dbr", COUNT)),
        )
    )
    ok, txt = highest(pdr, "flooding", COUNT)
    out.append(
        Verdict("flooding has the highest delivery ratio", "the reference", f"best per density: {txt}", _word(ok))
    )
    energy = points(runs, COUNT, "energy.per_delivered_j")
    if energy.empty:
        out.append(
            Verdict(
                "flooding costs the most energy per delivered packet",
                "the reference",
                "no energy in this sweep",
                "not checked",
            )
        )
    else:
        ok, txt = highest(energy, "flooding", COUNT)
        out.append(
            Verdict(
                "flooding costs the most energy per delivered packet",
                "the reference",
                f"highest per density: {txt}",
                _word(ok),
            )
        )
    copies = points(runs, COUNT, "net.copies_per_delivered")
    ok, txt = highest(copies, "flooding", COUNT)
    out.append(
        Verdict(
            "flooding sends the most copies per delivered packet",
            "the reference",
            f"highest per density: {txt}",
            _word(ok),
        )
    )
    if radius is not None:
        rr = pd.read_csv(radius / "sweep.csv")
        for v in ("vbf", "hh_vbf"):
            pr = points(rr, RADIUS, "net.pdr")
            ok, txt = rises(pr, v, RADIUS)
            name = "VBF" if v == "vbf" else "HH-VBF"
            out.append(
                Verdict(
                    f"{name}'s delivery ratio rises with the pipe radius",
                    "Xie, Cui and Lao 2006",
                    txt,
                    _word(ok, falls(pr, v, RADIUS)),
                )
            )
    if lifetime is not None:
        lt = pd.read_csv(lifetime / "sweep.csv")
        alive = lt["energy.first_depleted_s"].isna().sum() if "energy.first_depleted_s" in lt.columns else len(lt)
        if alive:  # a run whose batteries all lasted has no first death to compare (censored)
            verdict, txt = "not checked", f"{alive} of {len(lt)} runs ended with every battery left"
        else:
            ok, txt = later(lt, "energy.first_depleted_s", "eedbr", "dbr")
            verdict = _word(ok, later(lt, "energy.first_depleted_s", "dbr", "eedbr")[0])
        out.append(
            Verdict(
                "EEDBR's first node dies later than DBR's (a longer network lifetime)",
                "Wahid et al. 2011",
                f"first battery empty (s): {txt}",
                verdict,
            )
        )
    return out


def _ci(row: pd.Series, digits: int = 3) -> str:
    if pd.isna(row["mean"]):
        return "-"
    if pd.isna(row["ci95_low"]):
        return f"{row['mean']:.{digits}g} (n = {int(row['n'])})"
    return f"{row['mean']:.{digits}g} [{row['ci95_low']:.{digits}g}, {row['ci95_high']:.{digits}g}]"


def results(runs: pd.DataFrame, by: list[str], metrics: list[str]) -> str:
    """A Markdown table of each metric's mean and 95 % interval per ``by`` group (a metric a
    group never had: "-")."""
    s = summarize_runs(runs, by, [m for m in metrics if m in runs.columns])
    lines = ["| " + " | ".join([*by, *metrics]) + " |", "|" + "---|" * (len(by) + len(metrics))]
    for key, g in s.groupby(by, sort=False):
        g = g.set_index("metric")
        keys = key if isinstance(key, tuple) else (key,)
        cells = [_ci(g.loc[m]) if m in g.index else "-" for m in metrics]
        lines.append("| " + " | ".join([*(f"{k:g}" if isinstance(k, float) else str(k) for k in keys), *cells]) + " |")
    return "\n".join(lines)


#: the metrics of the result tables
DENSITY_METRICS = ["net.pdr", "net.delay_s", "net.hops_mean", "net.copies_per_delivered", "energy.per_delivered_j"]
RADIUS_METRICS = ["net.pdr", "net.copies_per_delivered", "energy.per_delivered_j", "net.delay_s"]
LIFETIME_METRICS = ["net.pdr", "energy.first_depleted_s", "energy.depleted_nodes", "energy.per_delivered_j"]


def table(verdicts: list[Verdict]) -> str:
    lines = ["| trend | source | ours (mean [95 % CI]) | verdict |", "|---|---|---|---|"]
    lines += [f"| {v.claim} | {v.source} | {v.ours} | {v.verdict} |" for v in verdicts]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("compare", type=Path, help="the sweep directory of routing_compare.toml")
    ap.add_argument("--radius", type=Path, help="the sweep directory of vbf_radius.toml")
    ap.add_argument("--lifetime", type=Path, help="a sweep over the variants with small batteries")
    ap.add_argument("--tables", action="store_true", help="also print each sweep's results, mean and 95 %% CI")
    args = ap.parse_args(argv)
    print(table(check(args.compare, args.radius, args.lifetime)))
    if args.tables:
        print("\n" + results(pd.read_csv(args.compare / "sweep.csv"), ["variant", COUNT], DENSITY_METRICS))
        if args.radius is not None:
            print("\n" + results(pd.read_csv(args.radius / "sweep.csv"), ["variant", RADIUS], RADIUS_METRICS))
        if args.lifetime is not None:
            print("\n" + results(pd.read_csv(args.lifetime / "sweep.csv"), ["variant"], LIFETIME_METRICS))
    return 0


if __name__ == "__main__":
    sys.exit(main())
