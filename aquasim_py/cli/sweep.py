"""``aquasim-py sweep SCENARIO.toml``: every (grid point, seed) of the scenario's ``[sweep]``
table, each run through :func:`aquasim_py.run_scenario` (by :mod:`aquasim_py.sweep`), on local
processes or a Dask cluster; writes ``sweep.csv`` and ``sweep.json``."""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from collections.abc import Mapping, Sequence
from typing import Any

from aquasim_py import __version__
from aquasim_py.cli import common
from aquasim_py.runner import console, json_safe, staged_output

EXAMPLES = """\
examples:
  aquasim-py sweep scenarios/beacon.toml                 # all local cores
  aquasim-py sweep scenarios/beacon.toml --workers 1 --out out/serial
  aquasim-py sweep scenarios/beacon.toml --set sweep.runs=20
  aquasim-py sweep scenarios/beacon.toml --scheduler tcp://10.0.0.5:8786   # Dask cluster
  aquasim-py sweep scenarios/itmtl_sweep.toml --set 'sweep.grid.variant=["itmtl", "wsc"]'

The scenario's [sweep] table gives runs (Monte Carlo seeds per grid point) and grid
(key paths -> value lists; the key variant takes [variants.NAME] names). One row per run
goes to DIR/sweep.csv, in the same order whatever the number of workers.
"""


def parser() -> argparse.ArgumentParser:
    p = common.Parser(
        prog="aquasim-py sweep",
        description="Run every (grid point, seed) of a scenario's [sweep] table and write sweep.csv.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    common.add_common(p)
    p.add_argument(
        "--workers",
        type=common.positive_int,
        metavar="N",
        help=f"local worker processes (default: the core count, here {os.cpu_count()})",
    )
    p.add_argument("--scheduler", metavar="ADDRESS", help="run on a Dask cluster at ADDRESS (needs 'aquasim-py[dask]')")
    return p


def command(argv: Sequence[str]) -> int:
    from aquasim_py import scenario, sweep

    args = parser().parse_args(argv)
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
    try:
        return _run(sc, args, jobs, workers, out, key)
    except common.Interrupted as e:  # SIGINT / SIGTERM: say what became of the finished runs
        e.detail = f"{_finished[0]} of {len(jobs)} sweep runs had finished; no rows kept, no output written"
        raise


_finished = [0]  # runs of the current sweep finished so far (for the interruption message)


def _count(done: int, total: int) -> None:
    _finished[0] = done


def _run(sc: Any, args: argparse.Namespace, jobs: list[Any], workers: int, out: Any, key: str) -> int:
    from aquasim_py import sweep

    _count(0, len(jobs))
    with staged_output(out, sc.path, key, overwrite=args.overwrite) as tmp:
        started = time.perf_counter()
        if common._progress_wanted(args.quiet):
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

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
                task = prog.add_task(f"{sc.name} sweep", total=len(jobs), start=False)
                prog.refresh()

                def tick(done: int, total: int) -> None:
                    _count(done, total)
                    prog.start_task(task)
                    prog.update(task, completed=done)
                    prog.refresh()

                rows = sweep.run_jobs(sc, jobs, workers=workers, scheduler=args.scheduler, progress=tick)
        else:
            rows = sweep.run_jobs(sc, jobs, workers=workers, scheduler=args.scheduler, progress=_count)
        wall = time.perf_counter() - started
        cols = sweep.columns(rows, jobs)
        sweep.rows_to_csv(rows, cols, tmp / "sweep.csv")
        info = {
            "aquasim_py_version": __version__,
            "scenario_file": str(sc.path),
            "seed": sc.simulation.seed,
            "runs": len(rows),
            "workers": None if args.scheduler else workers,
            "scheduler": args.scheduler,
            "wall_time_s": wall,
            "columns": cols,
            "scenario": sc.to_dict(),
        }
        (tmp / "sweep.json").write_text(json.dumps(json_safe(info), indent=2) + "\n")
    if not args.quiet:
        con = console()
        con.print(summary_table(rows, jobs, cols))
        con.print(f"{len(rows)} runs in {wall:.1f} s -> {out / 'sweep.csv'}", soft_wrap=True)
    return 0


def summary_table(rows: Sequence[Mapping[str, Any]], jobs: Sequence[Any], cols: Sequence[str]) -> Any:
    """Mean of every metric per grid point (at most 8 grid points shown)."""
    import numpy as np
    from rich.table import Table

    grid_keys = [k for k, _ in jobs[0].point] if jobs else []
    points: dict[tuple, list[Mapping[str, Any]]] = {}
    for job, row in zip(jobs, rows):
        points.setdefault(tuple(json.dumps(v) for _, v in job.point), []).append(row)
    shown = list(points)[:8]
    caption = f"columns: {', '.join(grid_keys)}" if grid_keys else None
    if len(points) > len(shown):
        caption = f"{caption} (first {len(shown)} of {len(points)} grid points)"
    t = Table(title="sweep: mean over runs per grid point", caption=caption)
    t.add_column("metric", no_wrap=True)
    for p in shown:
        t.add_column(", ".join(p) or "all runs", justify="right")
    for c in cols:
        if c in grid_keys or c in ("run", "seed"):
            continue
        cells = []
        for p in shown:
            vals = np.array([float(r.get(c, math.nan)) for r in points[p]], dtype=float)
            vals = vals[np.isfinite(vals)]
            cells.append(common.fmt(float(vals.mean())) if vals.size else "-")
        t.add_row(c, *cells)
    return t
