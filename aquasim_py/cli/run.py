"""``aquasim-py SCENARIO.toml``: run a scenario (every variant, one variant, or the file as
written when it declares none) through :func:`aquasim_py.run_scenario`."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from aquasim_py.cli import common

if TYPE_CHECKING:  # the modules that run a scenario are imported when one runs (--help stays light)
    from aquasim_py.runner import RunResult
    from aquasim_py.scenario import Scenario

#: every subcommand and what it does (the first line of ``aquasim-py --help``'s epilog)
SUBCOMMANDS = (
    ("SCENARIO.toml", "run a scenario (this page)"),
    ("sweep", "a Monte Carlo or parameter sweep of a scenario, on local cores or a Dask cluster"),
    ("report", "plots and report.html of a finished run, variants run or sweep"),
    ("reproduce", "rerun a paper's claims over seeds and readings and give each a verdict"),
    ("arrivals", "the eigenrays (delay, level, angles, bounces) of a link in a scenario's environment"),
    ("help", "this page; 'aquasim-py help COMMAND' is 'aquasim-py COMMAND --help'"),
)

EXAMPLES = (
    "commands:\n"
    + "".join(f"  aquasim-py {name:<14} {what}\n" for name, what in SUBCOMMANDS)
    + """
examples:
  aquasim-py scenarios/beacon.toml
  aquasim-py scenarios/beacon.toml --seed 7 --out out/beacon-7
  aquasim-py scenarios/beacon.toml --set simulation.duration_s=120 --set nodes.1.count=12
  aquasim-py scenarios/beacon.toml --set 'environment.sound_speed={model="constant", speed_mps=1490}'
  aquasim-py scenarios/itmtl.toml                        # every [variants.NAME], one table
  aquasim-py scenarios/itmtl.toml --variant wsc          # one variant, as a plain run
  aquasim-py sweep scenarios/beacon.toml --workers 2
  aquasim-py sweep scenarios/beacon.toml --scheduler tcp://10.0.0.5:8786
  aquasim-py report out/beacon                       # plots and report.html of a finished run
  aquasim-py modems                                  # the modem presets ([channel] modem = "NAME")

--set values are TOML (numbers, strings in quotes, [arrays], {inline tables}, true/false);
anything that is not valid TOML is taken as a plain string. List items are addressed by
index: nodes.1.count or nodes[1].count. --set applies on top of every variant.

A scenario with [variants.NAME] tables runs every variant on the same network and seed,
writes each under DIR/NAME/ and the comparison to DIR/variants.csv.
"""
)


def parser() -> argparse.ArgumentParser:
    p = common.Parser(
        prog="aquasim-py",
        description="Simulate an underwater acoustic sensor network scenario and write its trace "
        "tables and metrics. Other commands (below): sweep, report, reproduce, arrivals; "
        "'aquasim-py COMMAND --help' for each.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="version", version=common.version_line())
    common.add_common(p)
    p.add_argument(
        "--variant",
        metavar="NAME",
        help="run only this [variants.NAME] of the scenario and write what a plain run writes "
        "(default: every variant, each under DIR/NAME/)",
    )
    p.add_argument(
        "--report", action="store_true", help="also write plots and report.html (see 'aquasim-py report --help')"
    )
    return p


def command(argv: Sequence[str]) -> int:
    args = parser().parse_args(argv)  # --help and --version exit here
    from aquasim_py import scenario
    from aquasim_py.reporting import tables
    from aquasim_py.runner import console, run_staged

    sc = scenario.load(args.scenario, overrides=args.set, seed=args.seed, variant=args.variant)
    progress = common._progress_wanted(args.quiet)
    if args.variant is None and sc.variant_names:
        return _all_variants(sc, args, progress)
    if args.variant is not None:
        default, key = common.output_dir(sc, None)
        out = Path(args.out) if args.out else default / args.variant
        key = "--out" if args.out else key
    else:
        out, key = common.output_dir(sc, args.out)
    sc.output.directory = str(out)  # the resolved scenario says where its outputs went
    res = run_staged(sc, out, key=key, overwrite=args.overwrite, progress=progress)
    _warn_missing(res)
    if not args.quiet:
        con = console()
        what = sc.name if sc.variant is None else f"{sc.name}/{sc.variant}"
        title = f"{what}: metrics (seed {sc.simulation.seed}, {sc.simulation.duration_s:g} s simulated)"
        con.print(tables.metrics_table(res.metrics, title).rich(con.width))
        for r in res.reports():
            con.print(r)
        con.print(f"output: {out}", soft_wrap=True)
    _report(out, args)
    return 0


def _all_variants(base: Scenario, args: argparse.Namespace, progress: bool) -> int:
    from aquasim_py.runner import (
        check_output_format,
        console,
        paper_comparison,
        relocate_results,
        resolve_variants,
        run_resolved_into,
        staged_output,
    )

    resolved = resolve_variants(base)  # every variant validated and built before any runs
    out, key = common.output_dir(base, args.out)
    for sc in resolved.values():
        check_output_format(sc)
    with staged_output(out, base.path, key, overwrite=args.overwrite) as tmp:
        results = run_resolved_into(resolved, tmp, out, progress)
    relocate_results(results, tmp, out)
    for res in results.values():
        _warn_missing(res)
    if not args.quiet:
        con = console()
        con.print(comparison_table(results, base, width=con.width))
        paper = paper_comparison(results)
        if paper is not None:
            con.print(paper_table(paper, base, results, width=con.width))
        more = f", the papers' numbers: {out / 'paper.csv'}" if paper is not None else ""
        con.print(f"output: {out}/<variant>/, comparison: {out / 'variants.csv'}{more}", soft_wrap=True)
    _report(out, args)
    return 0


def _report(out: Path, args: argparse.Namespace) -> None:
    """``--report``: plots and report.html beside the outputs (each variant's in its directory)."""
    if not args.report:
        return
    from aquasim_py.cli.report import reports_for

    for p in reports_for(out):
        if not args.quiet:
            print(f"report: {p}")


def comparison_table(results: Mapping[str, RunResult], base: Scenario, width: int | None = None) -> Any:
    """The variants side by side: a row per metric (each unit shown), a column per variant, in
    blocks of columns that fit ``width`` (:func:`aquasim_py.reporting.tables.comparison_table`)."""
    from aquasim_py.reporting import tables

    sim = base.simulation
    title = f"{base.name}: variants (seed {sim.seed}, {sim.duration_s:g} s simulated)"
    table = tables.comparison_table({name: res.metrics for name, res in results.items()}, title)
    table.notes.append("every metric of every variant, exactly: variants.csv")
    return table.rich(width)


def paper_table(paper: Any, base: Scenario, results: Mapping[str, RunResult], width: int | None = None) -> Any:
    """The protocols' papers beside this run (:func:`aquasim_py.runner.paper_comparison`): the
    paper named (each protocol's ``citation``) and the network described in the title, one
    row (or block) per claim with what the paper's number is a statistic of."""
    from rich.console import Group
    from rich.text import Text

    from aquasim_py.reporting import tables
    from aquasim_py.runner import paper_citations

    table = tables.paper_table(paper, tables.paper_title(base, paper_citations(results)), width)
    where = reproductions_of(results)
    if not where:
        return table
    said = ", ".join(f"`aquasim-py reproduce {key}` (docs/reproductions/{key}.md)" for key in where)
    return Group(table, Text(f"one network and seed; the verdict on each claim, over seeds and readings: {said}"))


def reproductions_of(results: Mapping[str, RunResult]) -> list[str]:
    """The papers (``aquasim-py reproduce`` names) of the protocols these variants ran."""
    from aquasim_py.reproduce.papers import PAPERS

    names = {getattr(cls, "name", "") for res in results.values() for cls in res.scenario.protocols()}
    return [key for key in PAPERS if key in names]


#: drop reason -> the scenario key that most often causes it
_DROP_KEYS = {
    "range": "channel.max_range_m",
    "snr": "channel.snr_threshold_db",
    "no_path": "environment",
    "collision": "channel.collision",
    "half_duplex": "the protocols' timing",
}


def nothing_heard(res: RunResult) -> str | None:
    """A warning when packets were sent but none was received, naming the key to look at
    (the commonest drop reason's, else ``channel.max_range_m`` against the nearest two nodes'
    distance, as with 3.5 typed for 3.5 km); None when something was heard or nothing sent."""
    m = res.metrics
    sent, received = m.get("packets.sent", 0), m.get("packets.received", 0)
    if not sent or received:
        return None
    drops = {k.removeprefix("packets.dropped."): v for k, v in m.items() if k.startswith("packets.dropped.") and v}
    c = res.scenario.channel
    head = f"{sent} packets sent and none received"
    if drops:
        reason = max(drops, key=lambda k: drops[k])
        key = _DROP_KEYS.get(reason, "channel")
        value = f" = {c.max_range_m:g} m" if key == "channel.max_range_m" else ""
        return f"{head} ({drops[reason]} dropped: {reason}); check {key}{value}"
    nearest = _nearest_pair_m(res)
    apart = f" while the nearest two nodes are {nearest:.4g} m apart" if nearest is not None else ""
    return f"{head}: no node was within channel.max_range_m = {c.max_range_m:g} m of a sender{apart}"


def _nearest_pair_m(res: RunResult) -> float | None:
    """The smallest distance (m) between two nodes at the first position sample, if sampled."""
    import numpy as np

    try:
        pos = res.tables["positions"]
    except LookupError:
        return None
    if not len(pos):
        return None
    first = pos[pos["time"] == pos["time"].min()][["x", "y", "z"]].to_numpy(float)
    if len(first) < 2:
        return None
    d = np.linalg.norm(first[:, None, :] - first[None, :, :], axis=-1)
    return float(d[np.triu_indices(len(first), 1)].min())


def _warn_missing(res: RunResult) -> None:
    silent = nothing_heard(res)
    if silent is not None:
        print(f"warning: {res.name}: {silent}", file=sys.stderr)
    for name in res.missing_tables:
        print(f"warning: trace table {name!r} was not produced by this run", file=sys.stderr)
    for family, problem in res.metric_errors.items():
        print(
            f"warning: {res.name}: metrics {family!r} failed ({problem}); see metric_errors in summary.json",
            file=sys.stderr,
        )
