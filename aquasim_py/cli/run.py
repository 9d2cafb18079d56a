"""``aquasim-py SCENARIO.toml``: run a scenario (every variant, one variant, or the file as
written when it declares none) through :func:`aquasim_py.run_scenario`."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from aquasim_py.cli import common
from aquasim_py.reporting import tables
from aquasim_py.runner import (
    RunResult,
    check_output_format,
    console,
    paper_citations,
    paper_comparison,
    relocate_results,
    resolve_variants,
    run_resolved_into,
    run_staged,
    staged_output,
)
from aquasim_py.scenario import Scenario

EXAMPLES = """\
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


def parser() -> argparse.ArgumentParser:
    p = common.Parser(
        prog="aquasim-py",
        description="Simulate an underwater acoustic sensor network scenario and write its trace "
        "tables and metrics. Use 'aquasim-py sweep SCENARIO.toml' for a Monte Carlo "
        "or parameter sweep (see 'aquasim-py sweep --help').",
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
    from aquasim_py import scenario

    args = parser().parse_args(argv)
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
    sim = base.simulation
    title = f"{base.name}: variants (seed {sim.seed}, {sim.duration_s:g} s simulated)"
    table = tables.comparison_table({name: res.metrics for name, res in results.items()}, title)
    table.notes.append("every metric of every variant, exactly: variants.csv")
    return table.rich(width)


def paper_table(paper: Any, base: Scenario, results: Mapping[str, RunResult], width: int | None = None) -> Any:
    """The protocols' papers beside this run (:func:`aquasim_py.runner.paper_comparison`): the
    paper named (each protocol's ``citation``) and the network described in the title, one
    row (or block) per claim with what the paper's number is a statistic of."""
    return tables.paper_table(paper, tables.paper_title(base, paper_citations(results)), width)


def _warn_missing(res: RunResult) -> None:
    for name in res.missing_tables:
        print(f"warning: trace table {name!r} was not produced by this run", file=sys.stderr)
    for family, problem in res.metric_errors.items():
        print(
            f"warning: {res.name}: metrics {family!r} failed ({problem}); see metric_errors in summary.json",
            file=sys.stderr,
        )
