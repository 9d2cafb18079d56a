"""Monte Carlo and parameter sweeps: one run per (grid point, seed), on local cores or Dask.

A scenario's ``[sweep]`` table gives ``runs`` (Monte Carlo repetitions) and ``grid``, a table
of key paths to value lists; the sweep is the Cartesian product of the grid values (keys in
file order, values in list order) times ``runs``, the run index varying fastest. Run ``r``
uses the seed :func:`run_seed` ``(scenario seed, r)`` at every grid point (common random
numbers: grid points differ by their parameters, not by their luck).

The grid key ``variant`` takes names of the scenario's ``[variants.NAME]`` tables: each such
job runs that variant, with the other grid values (and ``--set``) applied on top of it; the
rows carry the variant's name in the ``variant`` column. Without that key a sweep runs the
file as written.

Every run goes through :func:`aquasim_py.run_scenario`. Rows come back in job order whatever
the number of workers or their finishing order, and each run depends only on its own
(scenario, overrides, seed), so a sweep gives the same rows serially, on 2 local processes,
or on a Dask cluster.
"""

from __future__ import annotations

import contextlib
import csv
import ctypes
import itertools
import json
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aquasim_py import scenario as _scenario
from aquasim_py.scenario import VARIANT_KEY

__all__ = [
    "DaskMissingError",
    "Job",
    "bases",
    "check_points",
    "columns",
    "plan",
    "rows_to_csv",
    "run_job",
    "run_jobs",
    "run_seed",
]

Progress = Callable[[int, int], None]


class DaskMissingError(ImportError):
    """``--scheduler`` was given but dask.distributed is not installed."""


@dataclass(frozen=True)
class Job:
    """One run of a sweep: its position in the output, swept values and seed."""

    index: int
    point: tuple[tuple[str, Any], ...]  # (key path, value) per grid key, in grid order
    run: int
    seed: int


def run_seed(base_seed: int, run: int) -> int:
    """Seed of Monte Carlo run ``run``: a SeedSequence hash of (base seed, run), 63 bits.

    Stable across platforms and numpy versions (SeedSequence's hashing is specified), and
    distinct runs get statistically independent streams even for neighbouring base seeds.
    """
    state = np.random.SeedSequence([int(base_seed), int(run)]).generate_state(1, dtype=np.uint64)
    return int(state[0] >> np.uint64(1))


def plan(sc: _scenario.Scenario) -> list[Job]:
    """Every job of the scenario's sweep, in output order."""
    if sc.sweep is None:
        raise _scenario.ScenarioError(sc.path, "sweep", "the scenario has no [sweep] table")
    keys = list(sc.sweep.grid)
    values = [sc.sweep.grid[k] for k in keys]
    jobs: list[Job] = []
    for combo in itertools.product(*values):
        for r in range(sc.sweep.runs):
            jobs.append(Job(len(jobs), tuple(zip(keys, combo)), r, run_seed(sc.simulation.seed, r)))
    return jobs


def bases(sc: _scenario.Scenario, jobs: Sequence[Job]) -> dict[str | None, dict[str, Any]]:
    """The resolved scenario each job starts from, by variant (None: the file as written), as
    plain data without the ``sweep`` and ``variants`` tables (a run needs neither)."""
    out: dict[str | None, dict[str, Any]] = {}
    for job in jobs:
        v = _variant_of(job)
        if v not in out:
            src = sc if v is None else _scenario.resolve(sc, variant=v)
            out[v] = {k: x for k, x in src.to_dict().items() if k not in ("sweep", "variants")}
    return out


def _variant_of(job: Job) -> str | None:
    return next((v for k, v in job.point if k == VARIANT_KEY), None)


def _job_scenario(base: dict[str, Any], path: str | None, job: Job) -> _scenario.Scenario:
    overrides = [(_scenario.parse_key_path(k), v) for k, v in job.point if k != VARIANT_KEY]
    return _scenario.load_dict(base, path, overrides=overrides, seed=job.seed)


def check_points(sc: _scenario.Scenario, jobs: Sequence[Job]) -> None:
    """Build (without running) every grid point once: what only the physics rejects fails
    here, before any run."""
    path = str(sc.path) if sc.path is not None else None
    start = bases(sc, jobs)
    for job in jobs:
        if job.run == 0:
            _scenario.build(_job_scenario(start[_variant_of(job)], path, job))


def run_job(base: dict[str, Any], path: str | None, job: Job) -> dict[str, Any]:
    """Run one job (in any process) and return its row: swept values, run, seed, metrics.

    ``base`` is the job's resolved scenario (:func:`bases`), ``path`` its file (for relative
    file names and messages).
    """
    from aquasim_py.runner import run_scenario

    res = run_scenario(_job_scenario(base, path, job), progress=False)
    row: dict[str, Any] = dict(job.point)
    row["run"] = job.run
    row["seed"] = job.seed
    # plain Python numbers: a protocol's metrics may hand back numpy scalars
    row.update({k: v.item() if isinstance(v, np.generic) else v for k, v in res.metrics.items()})
    return row


def run_jobs(
    sc: _scenario.Scenario,
    jobs: Sequence[Job],
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: Progress | None = None,
) -> list[dict[str, Any]]:
    """Run ``jobs`` and return their rows in job order.

    ``workers``: local processes (default ``os.cpu_count()``; 1 runs in this process).
    ``scheduler``: a Dask scheduler address ("tcp://host:8786"); then ``workers`` is ignored.
    ``progress(done, total)`` is called after each finished run (in this process).
    """
    # the runs need no [sweep] table (and re-checking its grid in every run would be wasted)
    start = bases(sc, jobs)
    path = str(sc.path) if sc.path is not None else None
    total = len(jobs)
    results: list[dict[str, Any] | None] = [None] * total
    pos = {job.index: i for i, job in enumerate(jobs)}
    done = 0

    def _done(i: int, row: dict[str, Any]) -> None:
        nonlocal done
        results[i] = row
        done += 1
        if progress is not None:
            progress(done, total)

    if scheduler is not None:
        _run_dask(scheduler, start, path, jobs, pos, _done)
    else:
        n = workers if workers is not None else (os.cpu_count() or 1)
        n = max(1, min(int(n), total)) if total else 1
        if n == 1:
            for i, job in enumerate(jobs):
                _done(i, run_job(start[_variant_of(job)], path, job))
        else:
            # Worker processes may be forked: the CLI's progress display runs no thread for
            # that reason (a lock held by another thread at fork time would stay held).
            with ProcessPoolExecutor(max_workers=n, initializer=_worker_init, initargs=(os.getpid(),)) as pool:
                futs = {pool.submit(run_job, start[_variant_of(job)], path, job): job for job in jobs}
                try:
                    for fut in as_completed(futs):
                        _done(pos[futs[fut].index], fut.result())
                except BaseException:
                    for f in futs:
                        f.cancel()
                    _end_workers(pool)  # an interrupted sweep does not wait for runs in flight
                    raise
    rows = [r for r in results if r is not None]
    # a drop reason absent from a run's trace means none of those drops happened in it
    counts = {k for r in rows for k in r if k.startswith("packets.")}
    for r in rows:
        for k in counts:
            r.setdefault(k, 0)
    return rows


def _worker_init(parent: int) -> None:
    """Start-up of a local worker process: it dies with the sweep's parent process.

    Interruptions go to the parent (a terminal's Ctrl-C reaches the whole process group), which
    ends its workers itself. On Linux the kernel kills the worker when the parent dies, even by
    SIGKILL (``prctl(PR_SET_PDEATHSIG)``); elsewhere a daemon thread polls the parent's pid.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)  # not the parent's handler, inherited by fork
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):
            _watch_parent(parent)
    else:
        _watch_parent(parent)
    if os.getppid() != parent:  # the parent died before the request above took effect
        os._exit(1)


_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>


def _watch_parent(parent: int) -> None:
    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, name="aquasim-parent-watch", daemon=True).start()


def _end_workers(pool: ProcessPoolExecutor) -> None:
    """Kill the pool's worker processes (their runs are abandoned) so that leaving the pool's
    ``with`` block does not wait for the runs in flight."""
    procs = getattr(pool, "_processes", None) or {}  # CPython keeps its workers here
    for p in list(procs.values()):
        with contextlib.suppress(Exception):
            p.kill()
    pool.shutdown(wait=False, cancel_futures=True)


def _run_dask(
    scheduler: str,
    start: dict[str | None, dict[str, Any]],
    path: str | None,
    jobs: Sequence[Job],
    pos: dict[int, int],
    done: Callable[[int, dict[str, Any]], None],
) -> None:
    try:
        from dask.distributed import Client
        from dask.distributed import as_completed as dask_completed
    except ImportError as e:
        raise DaskMissingError("--scheduler needs dask.distributed: pip install 'aquasim-py[dask]'") from e
    with Client(scheduler) as client:
        futs = [client.submit(run_job, start[_variant_of(job)], path, job, pure=False) for job in jobs]
        index = {f.key: job.index for f, job in zip(futs, jobs)}
        for fut in dask_completed(futs):
            done(pos[index[fut.key]], fut.result())


def columns(rows: Sequence[dict[str, Any]], jobs: Sequence[Job]) -> list[str]:
    """CSV columns: grid keys (grid order), run, seed, then every metric name sorted."""
    grid = [k for k, _ in jobs[0].point] if jobs else []
    fixed = set(grid) | {"run", "seed"}
    metric_names = sorted({k for r in rows for k in r if k not in fixed})
    return grid + ["run", "seed"] + metric_names


def _cell(v: Any) -> Any:
    if v is None:
        return ""
    if isinstance(v, float):
        return "nan" if math.isnan(v) else repr(float(v))  # repr round-trips exactly
    if isinstance(v, (list, dict)):
        return json.dumps(v)
    return v


def rows_to_csv(rows: Sequence[dict[str, Any]], cols: Sequence[str], path: str | Path) -> None:
    """Write rows (missing metrics left empty) with exact float text."""
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(cols)
        for r in rows:
            w.writerow([_cell(r.get(c)) for c in cols])
