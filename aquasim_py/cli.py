"""The ``aquasim-py`` command: run a scenario, or a sweep of it.

User mistakes (bad scenario, bad override, unwritable output) print one line
``error: FILE: KEY.PATH: problem`` on stderr and exit with status 2, before anything is
written. Outputs are staged in a hidden temporary directory next to the target and renamed
into place only when complete, so an interrupted or failed run leaves no half-written
directory (and an existing one untouched until the new one is ready).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import sys
import tempfile
import time
import uuid
import warnings
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any, NoReturn

from aquasim_py import __version__
from aquasim_py.scenario import Scenario, ScenarioError

__all__ = ["main", "staged_output"]

EXIT_USAGE = 2

_RUN_EXAMPLES = """\
examples:
  aquasim-py scenarios/beacon.toml
  aquasim-py scenarios/beacon.toml --seed 7 --out out/beacon-7
  aquasim-py scenarios/beacon.toml --set simulation.duration_s=120 --set nodes.1.count=12
  aquasim-py scenarios/beacon.toml --set 'environment.sound_speed={model="constant", speed_mps=1490}'
  aquasim-py sweep scenarios/beacon.toml --workers 2
  aquasim-py sweep scenarios/beacon.toml --scheduler tcp://10.0.0.5:8786

--set values are TOML (numbers, strings in quotes, [arrays], {inline tables}, true/false);
anything that is not valid TOML is taken as a plain string. List items are addressed by
index: nodes.1.count or nodes[1].count.
"""

_SWEEP_EXAMPLES = """\
examples:
  aquasim-py sweep scenarios/beacon.toml                 # all local cores
  aquasim-py sweep scenarios/beacon.toml --workers 1 --out out/serial
  aquasim-py sweep scenarios/beacon.toml --set sweep.runs=20
  aquasim-py sweep scenarios/beacon.toml --scheduler tcp://10.0.0.5:8786   # Dask cluster

The scenario's [sweep] table gives runs (Monte Carlo seeds per grid point) and grid
(key paths -> value lists). One row per run goes to DIR/sweep.csv, in the same order
whatever the number of workers.
"""


class UsageError(Exception):
    """A command-line mistake that is not about the scenario file."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line, not usage + message
        raise UsageError(f"{message} (see {self.prog} --help)")


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {v}")
    return v


def _seed(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {text!r}") from None
    if not 0 <= v < 2**63:
        raise argparse.ArgumentTypeError(f"expected an integer in [0, 2^63), got {v}")
    return v


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", metavar="SCENARIO.toml", help="scenario file")
    p.add_argument(
        "--out", metavar="DIR", help="output directory (default: [output] directory, else out/<scenario name>)"
    )
    p.add_argument("--seed", type=_seed, metavar="N", help="override [simulation] seed")
    p.add_argument(
        "--set", action="append", default=[], metavar="KEY.PATH=VALUE", help="override any scenario value (repeatable)"
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar and no tables")


def _run_parser() -> argparse.ArgumentParser:
    p = _Parser(
        prog="aquasim-py",
        description="Simulate an underwater acoustic sensor network scenario and write its trace "
        "tables and metrics. Use 'aquasim-py sweep SCENARIO.toml' for a Monte Carlo "
        "or parameter sweep (see 'aquasim-py sweep --help').",
        epilog=_RUN_EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="version", version=f"aquasim-py {__version__}")
    _common(p)
    return p


def _sweep_parser() -> argparse.ArgumentParser:
    p = _Parser(
        prog="aquasim-py sweep",
        description="Run every (grid point, seed) of a scenario's [sweep] table and write sweep.csv.",
        epilog=_SWEEP_EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _common(p)
    p.add_argument(
        "--workers",
        type=_positive_int,
        metavar="N",
        help=f"local worker processes (default: the core count, here {os.cpu_count()})",
    )
    p.add_argument("--scheduler", metavar="ADDRESS", help="run on a Dask cluster at ADDRESS (needs 'aquasim-py[dask]')")
    return p


# --------------------------------------------------------------------------- output staging
@contextmanager
def staged_output(target: str | Path, file: Path | None, key: str) -> Iterator[Path]:
    """Yield a fresh temporary directory beside ``target``; rename it to ``target`` on success.

    Fails with :class:`ScenarioError` (naming ``key``) before yielding if the location cannot
    be written. On any exception the temporary directory, and any parent directory created
    here, are removed; an existing ``target`` is replaced only after the new one is complete.
    """
    target = Path(target)
    parent = target.parent
    created: list[Path] = []

    def _unmake() -> None:
        for d in reversed(created):
            with suppress(OSError):
                d.rmdir()

    try:
        missing = []
        d = parent
        while not d.exists():
            missing.append(d)
            if d.parent == d:
                break
            d = d.parent
        for d in reversed(missing):
            d.mkdir()
            created.append(d)
        if target.exists() and not target.is_dir():
            raise ScenarioError(file, key, f"{target} exists and is not a directory")
        tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.tmp-", dir=parent))
        # mkdtemp makes it private (0700); the final directory gets the usual permissions
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o777 & ~umask)
    except ScenarioError:
        _unmake()
        raise
    except OSError as e:
        _unmake()
        raise ScenarioError(file, key, f"cannot write to {target}: {e.strerror or e}") from None
    ok = False
    try:
        yield tmp
        ok = True
    finally:
        if not ok:
            shutil.rmtree(tmp, ignore_errors=True)
            _unmake()
    if target.exists():
        old = parent / f".{target.name}.old-{uuid.uuid4().hex[:8]}"
        os.rename(target, old)
        os.rename(tmp, target)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.rename(tmp, target)


# --------------------------------------------------------------------------- helpers
def _json_safe(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return None  # strict JSON has no NaN
    if isinstance(v, dict):
        return {k: _json_safe(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_json_safe(x) for x in v]
    if hasattr(v, "item") and callable(v.item):  # numpy scalars
        return _json_safe(v.item())
    return v


def _fmt(v: Any) -> str:
    if isinstance(v, bool):
        return str(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "-" if math.isnan(v) else f"{v:.6g}"
    return str(v)


def _console(stderr: bool = False) -> Any:
    from rich.console import Console

    stream = sys.stderr if stderr else sys.stdout
    # a terminal sets its own width; a pipe or a file gets room for the sweep table
    width = None if stream.isatty() or os.environ.get("COLUMNS") else 120
    return Console(file=stream, highlight=False, width=width)


def _metrics_table(m: Mapping[str, Any], title: str) -> Any:
    from rich.table import Table

    t = Table(title=title)
    t.add_column("metric")
    t.add_column("value", justify="right")
    for k, v in m.items():
        t.add_row(k, _fmt(v))
    return t


def _output_dir(sc: Scenario, out: str | None, suffix: str = "") -> tuple[Path, str]:
    if out:
        return Path(out), "--out"
    if sc.output.directory:
        return Path(sc.output.directory + suffix), "output.directory"
    return Path("out") / f"{sc.name}{suffix}", "output.directory"


def _check_format(sc: Scenario) -> None:
    if sc.trace.format == "parquet":
        try:
            import pyarrow  # noqa: F401
        except ImportError:
            raise ScenarioError(
                sc.path, "trace.format", "parquet needs pyarrow (pip install 'aquasim-py[parquet]')"
            ) from None


def _progress_wanted(quiet: bool) -> bool:
    return not quiet and sys.stderr.isatty()


# --------------------------------------------------------------------------- commands
def _run(argv: Sequence[str]) -> int:
    from aquasim_py import metrics, scenario
    from aquasim_py.trace import write_frames

    args = _run_parser().parse_args(argv)
    sc = scenario.load(args.scenario, overrides=args.set, seed=args.seed)
    out, key = _output_dir(sc, args.out)
    sc.output.directory = str(out)  # the resolved scenario says where its outputs went
    _check_format(sc)
    sim = scenario.build(sc)
    duration = sc.simulation.duration_s
    with staged_output(out, sc.path, key) as tmp:
        started = time.perf_counter()
        if _progress_wanted(args.quiet):
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

            with Progress(
                TextColumn("[bold]{task.description}"),
                BarColumn(),
                TextColumn("{task.completed:.0f}/{task.total:.0f} s simulated"),
                TimeElapsedColumn(),
                TimeRemainingColumn(),
                console=_console(stderr=True),
                transient=True,
            ) as prog:
                task = prog.add_task(sc.name, total=duration)
                sim.run(duration, progress=lambda t, until: prog.update(task, completed=t))
        else:
            sim.run(duration)
        wall = time.perf_counter() - started
        frames = sim.trace.frames()
        protocols = sc.protocols()
        m = metrics.summarize(
            frames,
            protocols,
            percentiles=sc.metrics.percentiles,
            warmup_s=sc.metrics.warmup_s,
            unknown_roles=sc.metrics.unknown_roles,
        )
        wanted = sc.trace.tables
        selected = frames if wanted is None else {k: v for k, v in frames.items() if k in wanted}
        write_frames(selected, tmp, sc.trace.format)
        summary = {
            "aquasim_py_version": __version__,
            "scenario_file": str(sc.path),
            "seed": sc.simulation.seed,
            "wall_time_s": wall,
            "metrics": m,
            "scenario": sc.to_dict(),
        }
        (tmp / "summary.json").write_text(json.dumps(_json_safe(summary), indent=2) + "\n")
    if wanted is not None:
        for name in wanted:
            if name not in frames:
                print(f"warning: trace table {name!r} was not produced by this run", file=sys.stderr)
    if not args.quiet:
        con = _console()
        con.print(_metrics_table(m, f"{sc.name}: metrics (seed {sc.simulation.seed}, {duration:g} s simulated)"))
        for cls in protocols:
            report = getattr(cls, "report", None)
            if callable(report):
                r = report(frames)
                if r is not None and r != "":
                    con.print(r)
        con.print(f"output: {out}", soft_wrap=True)
    return 0


def _sweep(argv: Sequence[str]) -> int:
    from aquasim_py import scenario, sweep

    args = _sweep_parser().parse_args(argv)
    sc = scenario.load(args.scenario, overrides=args.set, seed=args.seed)
    if sc.sweep is None:
        raise ScenarioError(sc.path, "sweep", "no [sweep] table: add one with runs and grid to run a sweep")
    out, key = _output_dir(sc, args.out, suffix="-sweep")
    jobs = sweep.plan(sc)
    # build every grid point once (no run): a value only the physics rejects fails here, early
    base = {k: v for k, v in sc.to_dict().items() if k != "sweep"}
    for job in jobs:
        if job.run == 0:
            scenario.build(scenario.load_dict(base, sc.path, overrides=list(job.point)))
    if args.scheduler is not None:
        try:
            import dask.distributed  # noqa: F401
        except ImportError:
            raise UsageError("--scheduler needs dask.distributed: pip install 'aquasim-py[dask]'") from None
    workers = args.workers if args.workers is not None else (os.cpu_count() or 1)
    with staged_output(out, sc.path, key) as tmp:
        started = time.perf_counter()
        if _progress_wanted(args.quiet):
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
                console=_console(stderr=True),
                transient=True,
                auto_refresh=False,
            ) as prog:
                task = prog.add_task(f"{sc.name} sweep", total=len(jobs), start=False)
                prog.refresh()

                def tick(done: int, total: int) -> None:
                    prog.start_task(task)
                    prog.update(task, completed=done)
                    prog.refresh()

                rows = sweep.run_jobs(sc, jobs, workers=workers, scheduler=args.scheduler, progress=tick)
        else:
            rows = sweep.run_jobs(sc, jobs, workers=workers, scheduler=args.scheduler)
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
        (tmp / "sweep.json").write_text(json.dumps(_json_safe(info), indent=2) + "\n")
    if not args.quiet:
        con = _console()
        con.print(_sweep_table(rows, jobs, cols))
        con.print(f"{len(rows)} runs in {wall:.1f} s -> {out / 'sweep.csv'}", soft_wrap=True)
    return 0


def _sweep_table(rows: Sequence[Mapping[str, Any]], jobs: Sequence[Any], cols: Sequence[str]) -> Any:
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
            cells.append(_fmt(float(vals.mean())) if vals.size else "-")
        t.add_row(c, *cells)
    return t


@contextmanager
def _one_line_warnings() -> Iterator[None]:
    """Scenario deprecations (e.g. an old mobility model name) as one ``warning:`` line each."""
    from aquasim_py.scenario import ScenarioDeprecationWarning

    def show(message: Warning | str, category: type[Warning], *args: Any, **kwargs: Any) -> None:
        print(f"warning: {message}", file=sys.stderr)

    with warnings.catch_warnings():
        warnings.simplefilter("default", ScenarioDeprecationWarning)
        warnings.showwarning = show
        yield


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``aquasim-py``; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        with _one_line_warnings():
            if argv and argv[0] == "sweep":
                return _sweep(argv[1:])
            return _run(argv)
    except ScenarioError as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except UsageError as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except SystemExit as e:  # argparse's --help / --version
        return int(e.code) if isinstance(e.code, int) else (0 if e.code is None else EXIT_USAGE)
    except KeyboardInterrupt:
        print("error: interrupted (no output written)", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
