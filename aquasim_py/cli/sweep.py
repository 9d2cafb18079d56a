"""``aquasim-py sweep SCENARIO.toml``: every (grid point, seed) of the scenario's ``[sweep]``
table, each run through :func:`aquasim_py.run_scenario` (by :mod:`aquasim_py.sweep`), on local
processes or a Dask cluster. Rows are journalled in ``DIR/rows.jsonl`` as runs finish
(``--resume`` picks up from it); at the end ``sweep.csv`` (plan order), ``summary.csv``,
``sweep.json`` and, with pyarrow, ``sweep.parquet``."""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import sys
import time
from collections.abc import Mapping, Sequence
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

from aquasim_py import __version__
from aquasim_py.cli import common
from aquasim_py.rows import json_safe

EXAMPLES = """\
examples:
  aquasim-py sweep scenarios/beacon.toml                 # all local cores
  aquasim-py sweep scenarios/beacon.toml --workers 1 --out out/serial
  aquasim-py sweep scenarios/beacon.toml --set sweep.runs=20
  aquasim-py sweep scenarios/beacon.toml --scheduler tcp://10.0.0.5:8786   # Dask cluster
  aquasim-py sweep scenarios/itmtl_sweep.toml --set 'sweep.grid.variant=["itmtl", "wsc"]'
  aquasim-py sweep scenarios/beacon.toml --resume        # after Ctrl-C or a crash

The scenario's [sweep] table gives runs (Monte Carlo seeds per grid point) and grid
(key paths -> value lists; the key variant takes [variants.NAME] names). DIR is --out, else
the [output] directory with "-sweep" appended, else out/<scenario file stem>-sweep. Each
finished run's row is appended to DIR/rows.jsonl at once; at the end DIR/sweep.csv holds one
row per run (key, error, metrics) in plan order whatever the number of workers or
interruptions, DIR/summary.csv the mean, std and 95 % CI per grid point. Exit status 1 when
any run failed (its error is in the error column). A DIR that holds an interrupted sweep is
refused (exit 2) unless --resume (continue it) or --overwrite (discard its saved runs).
"""

OUTPUTS = ("sweep.csv", "sweep.json", "summary.csv", "sweep.parquet")


def parser() -> argparse.ArgumentParser:
    p = common.Parser(
        prog="aquasim-py sweep",
        description="Run every (grid point, seed) of a scenario's [sweep] table and write sweep.csv.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    common.add_common(p)
    for a in p._actions:  # a sweep's own default directory (common's help describes a plain run's)
        if a.dest == "out":
            a.help = (
                "output directory (default: the [output] directory + '-sweep', else out/<scenario file stem>-sweep)"
            )
        if a.dest == "overwrite":
            a.help = (
                f"{a.help}; also start afresh over an interrupted sweep in DIR, discarding its saved runs "
                "(without it, or --resume, such a directory is refused)"
            )
    p.add_argument(
        "--resume",
        action="store_true",
        help="keep the rows already in DIR/rows.jsonl and run only the missing (or failed) runs",
    )
    p.add_argument("--keep-traces", action="store_true", help="also keep each run's trace tables under DIR/runs/<key>/")
    p.add_argument(
        "--report", action="store_true", help="also write plots and report.html (see 'aquasim-py report --help')"
    )
    p.add_argument(
        "--workers",
        type=common.positive_int,
        metavar="N",
        help=f"local worker processes (default: the core count, here {os.cpu_count()})",
    )
    p.add_argument("--scheduler", metavar="ADDRESS", help="run on a Dask cluster at ADDRESS (needs 'aquasim-py[dask]')")
    common.add_metrics(p)
    return p


def command(argv: Sequence[str]) -> int:
    args = parser().parse_args(argv)  # --help exits here
    from aquasim_py import scenario, sweep
    from aquasim_py.runner import console

    sc = scenario.load(args.scenario, overrides=args.set, seed=args.seed)
    if sc.sweep is None:
        raise scenario.ScenarioError(sc.path, "sweep", "no [sweep] table: add one with runs and grid to run a sweep")
    out, key = common.output_dir(sc, args.out, suffix="-sweep")
    jobs = sweep.plan(sc)
    # build every grid point once (no run): a value only the physics rejects fails here, early
    sweep.check_points(sc, jobs)
    if args.scheduler is not None:
        try:
            import dask.distributed  # noqa: F401
        except ImportError:
            raise common.UsageError("--scheduler needs dask.distributed: pip install 'aquasim-py[dask]'") from None
    workers = args.workers if args.workers is not None else (os.cpu_count() or 1)
    if not args.resume and not args.overwrite and out.is_dir() and (saved := sweep.saved_runs(out)):
        # a sweep that starts afresh empties the journal: never over finished runs unasked
        runs = f"{saved} finished run{'s' * (saved != 1)}"
        raise common.UsageError(
            f"{out} holds an interrupted sweep ({runs} saved in {sweep.JOURNAL}): finish it with --resume, "
            "or start again with --overwrite (discards them)"
        )
    _prepare(out, sc.path, key, resume=args.resume, overwrite=args.overwrite)
    journal_path = out / sweep.JOURNAL
    before, dropped = sweep.read_journal(journal_path, repair=True) if args.resume else ([], 0)
    skip = sweep.done_keys(before)
    todo = [j for j in jobs if j.key not in skip]
    already = len(jobs) - len(todo)
    if args.resume and not args.quiet:
        note = f" (dropped {dropped} partially written row{'s' * (dropped != 1)})" if dropped else ""
        print(f"resuming {out}: {already} of {len(jobs)} runs already done{note}")
    traces = out / sweep.RUNS if args.keep_traces else None
    started = time.perf_counter()
    try:
        with sweep.Journal(journal_path) as journal:
            if common._progress_wanted(args.quiet):
                _run_with_bar(sc, todo, len(jobs), already, workers, args.scheduler, journal, traces)
            else:
                sweep.run_jobs(
                    sc, todo, workers=workers, scheduler=args.scheduler, on_row=journal.append, traces=traces
                )
    except (KeyboardInterrupt, BrokenProcessPool) as e:
        rows, cols = sweep.finish(out, jobs)
        _write_info(out, sc, args, workers, rows, cols, jobs, time.perf_counter() - started)
        if isinstance(e, common.Interrupted):
            why = f"interrupted by {signal.Signals(e.signum).name}"
        else:
            why = "interrupted" if isinstance(e, KeyboardInterrupt) else "a worker process died"
        print(
            f"error: {why}: {len(rows)} of {len(jobs)} runs saved in {out}; finish with --resume",
            file=sys.stderr,
        )
        if isinstance(e, common.Interrupted):
            return 128 + e.signum  # 130 for SIGINT, 143 for SIGTERM
        return 130 if isinstance(e, KeyboardInterrupt) else 1
    wall = time.perf_counter() - started
    rows, cols = sweep.finish(out, jobs)
    if traces is not None and traces.is_dir():  # kept traces are the sweep's files too
        from aquasim_py.outdir import record_files

        record_files(out, sorted(p.relative_to(out).as_posix() for p in traces.rglob("*") if p.is_file()))
    _write_info(out, sc, args, workers, rows, cols, jobs, wall)
    if not args.quiet:
        con = console()
        con.print(summary_table(out, sc.name, common.metric_patterns(args.metrics), width=con.width))
    reused = f" ({already} from the journal)" if already else ""
    print(f"{len(rows)} runs{reused} in {wall:.1f} s -> {out / 'sweep.csv'}")
    if args.report:
        from aquasim_py.cli.report import reports_for

        for html in reports_for(out, metrics=common.metric_patterns(args.metrics)):
            print(f"report: {html}")
    failed = sum(1 for r in rows if r.get("error"))
    if failed:
        print(
            f"error: {failed} of {len(rows)} runs failed (see the error column of {out / 'sweep.csv'})", file=sys.stderr
        )
        return 1
    return 0


def _prepare(out: Path, file: Path | None, key: str, *, resume: bool, overwrite: bool = False) -> None:
    """Make the sweep's directory (before any run). Without ``resume``, a previous sweep's
    outputs there are removed: the new sweep starts from an empty journal (the caller has
    refused an interrupted sweep's saved runs unless ``overwrite``). A non-empty
    directory that is not an aquasim-py output is refused unless ``overwrite`` (then only the
    sweep's own files are written and removed there); the directory's manifest lists the
    sweep's files from the start, so an interrupted sweep's directory is its own."""
    from aquasim_py.outdir import record_files, refuse_foreign
    from aquasim_py.scenario import ScenarioError
    from aquasim_py.sweep import JOURNAL, RUNS

    own = refuse_foreign(out, file, key, overwrite=overwrite)
    try:
        out.mkdir(parents=True, exist_ok=True)
        record_files(out, [JOURNAL, *OUTPUTS])
        # written again when this sweep ends or is interrupted: until then the directory reads
        # as an unfinished sweep (sweep.saved_runs), also if this one is killed
        (out / "sweep.json").unlink(missing_ok=True)
        if not resume:
            for name in (JOURNAL, *OUTPUTS):
                (out / name).unlink(missing_ok=True)
            if own:  # a runs/ folder in a user's directory is the user's
                shutil.rmtree(out / RUNS, ignore_errors=True)
    except OSError as e:
        raise ScenarioError(file, key, f"cannot write to {out}: {e.strerror or e}") from None


def _write_info(
    out: Path,
    sc: Any,
    args: argparse.Namespace,
    workers: int,
    rows: Sequence[Mapping[str, Any]],
    cols: Sequence[str],
    jobs: Sequence[Any],
    wall: float,
) -> None:
    info = {
        "aquasim_py_version": __version__,
        "scenario_file": str(sc.path),
        "seed": sc.simulation.seed,
        "runs": len(rows),
        "planned": len(jobs),
        "complete": len(rows) == len(jobs),
        "failed": sum(1 for r in rows if r.get("error")),
        "resumed": bool(args.resume),
        "workers": None if args.scheduler else workers,
        "scheduler": args.scheduler,
        "wall_time_s": wall,  # of this invocation (a resumed sweep: the part run now)
        "columns": list(cols),
        "scenario": sc.to_dict(),
    }
    tmp = out / ".sweep.json.tmp"
    tmp.write_text(json.dumps(json_safe(info), indent=2) + "\n")
    os.replace(tmp, out / "sweep.json")


def _run_with_bar(
    sc: Any,
    todo: Sequence[Any],
    total: int,
    already: int,
    workers: int,
    scheduler: str | None,
    journal: Any,
    traces: Path | None,
) -> None:
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    from aquasim_py import sweep
    from aquasim_py.runner import console

    with Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("runs"),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        # no refresh thread: worker processes are forked while this display is up
        console=console(stderr=True),
        transient=True,
        auto_refresh=False,
    ) as prog:
        task = prog.add_task(f"{sc.name} sweep", total=total, completed=already, start=False)
        prog.refresh()

        def tick(done: int, _total: int) -> None:
            prog.start_task(task)
            prog.update(task, completed=already + done)
            prog.refresh()

        sweep.run_jobs(
            sc, todo, workers=workers, scheduler=scheduler, progress=tick, on_row=journal.append, traces=traces
        )


def summary_table(out: Path, name: str, patterns: Sequence[str] | None, width: int | None = None) -> Any:
    """The sweep's metrics per grid point from ``out/sweep.csv``: centre, 95 % interval and n
    (:func:`aquasim_py.reporting.tables.sweep_table`), the metrics ``patterns`` select (default all but
    the packet counts)."""
    from rich.text import Text

    from aquasim_py.reporting import sweep as report_sweep
    from aquasim_py.reporting import tables

    data = report_sweep.load(out)
    metrics = report_sweep.select(data.metrics, patterns)
    if not metrics or data.runs.empty:
        why = "no successful run" if data.runs.empty else f"no metric matches {', '.join(patterns or [])}"
        return Text(f"{name} sweep: {why} (sweep.csv)")
    table = tables.sweep_table(data, report_sweep.summary(data, metrics), metrics, f"{name} sweep: per grid point")
    if not patterns:
        table.notes.append("packet counts and any other metric: --metrics PATTERN (e.g. 'packets.*'); all: sweep.csv")
    return table.rich(width)
