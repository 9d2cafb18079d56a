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

Sweeps survive interruption. Every run has a key (:func:`run_key`, a hash of its resolved
scenario, swept values and seed). Each finished run's row is appended to the journal
``DIR/rows.jsonl`` (one JSON object per line, flushed and fsynced) as it arrives, in finishing
order; ``sweep.csv`` is rewritten from the journal in plan order (:func:`finish`), so it is the
same whatever the interruption. :func:`read_journal` drops a partially written last line (a
process killed mid-write), and a resumed sweep runs only the keys without a successful row. A
run whose protocol raises gives a row with its ``error`` and no metrics; the others go on.
A sweep that did not complete (``sweep.json`` missing, or not ``complete``) keeps its finished
runs in the journal (:func:`saved_runs`): the CLI refuses to start another sweep over them
without ``--resume`` (continue) or ``--overwrite`` (discard).
"""

from __future__ import annotations

import gc
import hashlib
import itertools
import json
import os
import shutil
import time
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from aquasim_py import plugins
from aquasim_py import scenario as _scenario
from aquasim_py.rows import json_safe, rows_to_csv
from aquasim_py.scenario import VARIANT_KEY

__all__ = [
    "JOURNAL",
    "DaskMissingError",
    "Job",
    "Journal",
    "bases",
    "check_points",
    "columns",
    "finish",
    "plan",
    "read_journal",
    "rows_to_csv",
    "run_job",
    "run_jobs",
    "run_key",
    "run_seed",
    "saved_runs",
]

JOURNAL = "rows.jsonl"  # the append-only row journal inside a sweep's directory
RUNS = "runs"  # per-run trace tables (--keep-traces): DIR/runs/<key>/

Progress = Callable[[int, int], None]


class DaskMissingError(ImportError):
    """``--scheduler`` was given but dask.distributed is not installed."""


@dataclass(frozen=True)
class Job:
    """One run of a sweep: its position in the output, swept values, seed and key."""

    index: int
    point: tuple[tuple[str, Any], ...]  # (key path, value) per grid key, in grid order
    run: int
    seed: int
    key: str = ""  # run_key(resolved scenario, point, seed); set by plan()


def run_seed(base_seed: int, run: int) -> int:
    """Seed of Monte Carlo run ``run``: a SeedSequence hash of (base seed, run), 63 bits.

    Stable across platforms and numpy versions (SeedSequence's hashing is specified), and
    distinct runs get statistically independent streams even for neighbouring base seeds.
    """
    state = np.random.SeedSequence([int(base_seed), int(run)]).generate_state(1, dtype=np.uint64)
    return int(state[0] >> np.uint64(1))


def plan(sc: _scenario.Scenario) -> list[Job]:
    """Every job of the scenario's sweep, in output order, each with its :func:`run_key`."""
    if sc.sweep is None:
        raise _scenario.ScenarioError(sc.path, "sweep", "the scenario has no [sweep] table")
    keys = list(sc.sweep.grid)
    values = [sc.sweep.grid[k] for k in keys]
    jobs: list[Job] = []
    for combo in itertools.product(*values):
        for r in range(sc.sweep.runs):
            jobs.append(Job(len(jobs), tuple(zip(keys, combo)), r, run_seed(sc.simulation.seed, r)))
    start = bases(sc, jobs)
    return [replace(j, key=run_key(start[_variant_of(j)], j.point, j.seed)) for j in jobs]


def run_key(base: dict[str, Any], point: Sequence[tuple[str, Any]], seed: int) -> str:
    """A run's stable identity: the first 16 hex digits of the SHA-256 of the canonical JSON
    (sorted keys, no spaces) of its resolved scenario ``base`` (without ``[output]``: where
    results go does not change them), its swept values in grid order and its seed."""
    payload = {
        "scenario": {k: v for k, v in base.items() if k != "output"},
        "point": [[k, v] for k, v in point],
        "seed": int(seed),
    }
    text = json.dumps(json_safe(payload), sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


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
    return _scenario.load_dict(_free_implied_counts(base, overrides), path, overrides=overrides, seed=job.seed)


def _free_implied_counts(base: dict[str, Any], overrides: Sequence[tuple[Any, Any]]) -> dict[str, Any]:
    """``base`` with the count of each group whose placement is swept (and count is not) left
    to the new placement, when the old one implied it (explicit, grid): resolving the file
    filled that count in, and a swept placement with another number of positions would
    otherwise contradict it."""
    groups = base.get("nodes") or []
    n = len(groups)

    def swept(key: str) -> set[int]:
        return {
            loc[1] % n
            for loc, _ in overrides
            if len(loc) >= 3 and loc[0] == "nodes" and loc[2] == key and isinstance(loc[1], int) and -n <= loc[1] < n
        }

    free = {i for i in swept("placement") - swept("count") if groups[i]["placement"]["kind"] in ("explicit", "grid")}
    if not free:
        return base
    return {**base, "nodes": [{**g, "count": None} if i in free else g for i, g in enumerate(groups)]}


def check_points(sc: _scenario.Scenario, jobs: Sequence[Job]) -> None:
    """Build (without running) every grid point once: what only the physics rejects fails
    here, before any run."""
    path = str(sc.path) if sc.path is not None else None
    start = bases(sc, jobs)
    for job in jobs:
        if job.run == 0:
            _scenario.build(_job_scenario(start[_variant_of(job)], path, job))


def _one_line(e: BaseException) -> str:
    text = " ".join(str(e).split())
    return f"{type(e).__name__}: {text}" if text else type(e).__name__


def plugin_sources(start: dict[str | None, dict[str, Any]], path: str | None, jobs: Sequence[Job]) -> dict[str, str]:
    """The source text of every file plug-in (``protocol = "./x.py:Class"``) the jobs use, by
    the path key a worker computes from the same ``path`` (:mod:`aquasim_py.plugins`): the
    files travel with the jobs, so a worker without them (Dask, another machine) runs them."""
    specs = {str(g.get("protocol")) for b in start.values() for g in (b.get("nodes") or [])}
    specs |= {v for j in jobs for _, v in j.point if isinstance(v, str)}
    return plugins.sources(sorted(specs), Path(path).parent if path is not None else None)


def run_job(
    base: dict[str, Any],
    path: str | None,
    job: Job,
    traces: str | None = None,
    sources: dict[str, str] | None = None,
) -> dict[str, Any]:
    """Run one job (in any process) and return its row: swept values, run, seed, key, error,
    metrics.

    ``base`` is the job's resolved scenario (:func:`bases`), ``path`` its file (for relative
    file names and messages). An exception inside the run is caught and recorded: the row then
    has its one-line ``error`` and no metrics (the other runs go on). ``traces``: a directory
    to keep this run's trace tables in, under ``traces/<key>/`` (complete or absent).
    ``sources``: the file plug-ins' text (:func:`plugin_sources`), loaded from there.
    """
    from aquasim_py.runner import execute

    if sources:
        plugins.provide(sources)

    row: dict[str, Any] = dict(job.point)
    row["run"] = job.run
    row["seed"] = job.seed
    row["key"] = job.key
    row["error"] = None
    tmp = final = None
    if traces is not None:  # the tables stream into tmp as the run goes, renamed when complete
        final = Path(traces) / job.key
        tmp = Path(traces) / f".{job.key}.tmp-{os.getpid()}"
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir(parents=True)
    try:
        res = execute(_job_scenario(base, path, job), dest=tmp)
    except BaseException as e:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
        if not isinstance(e, Exception):
            raise
        row["error"] = _one_line(e)  # a protocol's bug must not stop the sweep: record it in the row
        return row
    # plain Python numbers: a protocol's metrics may hand back numpy scalars
    row.update({k: v.item() if isinstance(v, np.generic) else v for k, v in res.metrics.items()})
    if tmp is not None and final is not None:
        res.write_into(tmp, final=final)
        shutil.rmtree(final, ignore_errors=True)  # a run repeated on --resume replaces its tables
        os.rename(tmp, final)
    return row


def run_jobs(
    sc: _scenario.Scenario,
    jobs: Sequence[Job],
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: Progress | None = None,
    on_row: Callable[[dict[str, Any]], None] | None = None,
    traces: str | Path | None = None,
) -> list[dict[str, Any]]:
    """Run ``jobs`` and return their rows in job order.

    ``workers``: local processes (default ``os.cpu_count()``; 1 runs in this process).
    ``scheduler``: a Dask scheduler address ("tcp://host:8786"); then ``workers`` is ignored.
    ``progress(done, total)`` is called after each finished run (in this process), and
    ``on_row(row)`` before it, in finishing order, with the row as the run returned it (e.g.
    :meth:`Journal.append`). ``traces``: keep each run's tables under ``traces/<key>/``.
    """
    # the runs need no [sweep] table (and re-checking its grid in every run would be wasted)
    start = bases(sc, jobs)
    path = str(sc.path) if sc.path is not None else None
    tdir = str(traces) if traces is not None else None
    sources = plugin_sources(start, path, jobs)
    total = len(jobs)
    results: list[dict[str, Any] | None] = [None] * total
    pos = {job.index: i for i, job in enumerate(jobs)}
    done = 0

    def _done(i: int, row: dict[str, Any]) -> None:
        nonlocal done
        if on_row is not None:
            on_row(row)
        results[i] = row
        done += 1
        if progress is not None:
            progress(done, total)

    if scheduler is not None:
        _run_dask(scheduler, start, path, jobs, pos, _done, tdir, sources)
    else:
        n = workers if workers is not None else (os.cpu_count() or 1)
        n = max(1, min(int(n), total)) if total else 1
        if n == 1:
            # A finished simulation is cyclic garbage (SimPy processes <-> environment) that
            # the generational GC frees only rarely, so a long in-process sweep's memory would
            # creep up (+73 MB over 1000 small runs, tools/bench_sweep_memory.py). A full
            # collection costs ~0.1 s with pandas and scipy loaded: one every 5 s at most.
            collected = time.monotonic()
            for i, job in enumerate(jobs):
                _done(i, run_job(start[_variant_of(job)], path, job, tdir, sources))
                if time.monotonic() - collected > 5.0:
                    gc.collect()
                    collected = time.monotonic()
        else:
            _run_local(n, start, path, jobs, _done, tdir, sources)
    rows = [r for r in results if r is not None]
    fill_counts(rows)
    return rows


def _run_local(
    n: int,
    start: dict[str | None, dict[str, Any]],
    path: str | None,
    jobs: Sequence[Job],
    done: Callable[[int, dict[str, Any]], None],
    traces: str | None,
    sources: dict[str, str],
) -> None:
    # Worker processes may be forked: the CLI's progress display runs no thread for that
    # reason (a lock held by another thread at fork time would stay held). At most 2n jobs
    # are queued at a time: the parent holds O(n) futures whatever the sweep's size (flat
    # memory), and an interruption has little queued work to cancel.
    todo = iter(enumerate(jobs))
    pending: dict[Future[dict[str, Any]], int] = {}
    with ProcessPoolExecutor(max_workers=n, initializer=_die_with_parent, initargs=(os.getpid(),)) as pool:
        try:
            while True:
                while len(pending) < 2 * n:
                    nxt = next(todo, None)
                    if nxt is None:
                        break
                    i, job = nxt
                    pending[pool.submit(run_job, start[_variant_of(job)], path, job, traces, sources)] = i
                if not pending:
                    break
                finished, _ = wait(pending, return_when=FIRST_COMPLETED)
                for fut in sorted(finished, key=pending.__getitem__):
                    done(pending.pop(fut), fut.result())
        except BaseException:
            # Ctrl-C, or a dead worker: the runs in flight are lost anyway; stop them now
            # rather than wait for them (a run can take minutes)
            pool.shutdown(wait=False, cancel_futures=True)
            for proc in list((getattr(pool, "_processes", None) or {}).values()):
                proc.terminate()
            raise


def _die_with_parent(parent: int) -> None:
    """Worker initializer: end this worker when the sweep's process dies (e.g. SIGKILL).

    A ProcessPoolExecutor worker holds both ends of its job queue, so it never sees its parent
    go and would wait forever, holding the parent's stdout open. On Linux the kernel sends it
    SIGKILL when the parent dies (``PR_SET_PDEATHSIG``); elsewhere a daemon thread polls.
    Ctrl-C is the parent's business: the workers ignore SIGINT (no traceback from each), and
    the parent stops them."""
    import signal
    import sys

    signal.signal(signal.SIGINT, signal.SIG_IGN)

    if sys.platform.startswith("linux"):
        import ctypes

        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)  # 1 = PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass
        if os.getppid() != parent:  # the parent died before prctl took effect
            os._exit(1)
        return
    import threading
    import time

    def _watch() -> None:
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=_watch, daemon=True).start()


def _run_dask(
    scheduler: str,
    start: dict[str | None, dict[str, Any]],
    path: str | None,
    jobs: Sequence[Job],
    pos: dict[int, int],
    done: Callable[[int, dict[str, Any]], None],
    traces: str | None,
    sources: dict[str, str],
) -> None:
    try:
        from dask.distributed import Client
        from dask.distributed import as_completed as dask_completed
    except ImportError as e:
        raise DaskMissingError("--scheduler needs dask.distributed: pip install 'aquasim-py[dask]'") from e
    with Client(scheduler) as client:
        # traces: the workers write them, so DIR must be on a file system they share
        # the file plug-ins' text (a few kB) travels with each task: no worker needs the files
        futs = [client.submit(run_job, start[_variant_of(job)], path, job, traces, sources, pure=False) for job in jobs]
        index = {f.key: job.index for f, job in zip(futs, jobs)}
        try:
            for fut in dask_completed(futs):
                done(pos[index[fut.key]], fut.result())
        except BaseException:
            client.cancel(futs)
            raise


def fill_counts(rows: Iterable[dict[str, Any]]) -> None:
    """A drop reason absent from a run's trace means none of those drops happened in it: 0.

    Only successful runs (no ``error``) get the zeros; a failed run has no counts."""
    rows = list(rows)
    counts = {k for r in rows for k in r if k.startswith("packets.")}
    for r in rows:
        if not r.get("error"):
            for k in counts:
                r.setdefault(k, 0)


def columns(rows: Sequence[dict[str, Any]], jobs: Sequence[Job]) -> list[str]:
    """CSV columns: grid keys (grid order), run, seed, key and error (when the rows have them),
    then every metric name sorted."""
    grid = [k for k, _ in jobs[0].point] if jobs else []
    extra = [c for c in ("key", "error") if any(c in r for r in rows)]
    fixed = set(grid) | {"run", "seed", "key", "error"}
    metric_names = sorted({k for r in rows for k in r if k not in fixed})
    return grid + ["run", "seed"] + extra + metric_names


# --------------------------------------------------------------------------- the row journal
class Journal:
    """The append-only row journal ``DIR/rows.jsonl``: one JSON object per finished run, in
    finishing order, each line flushed and fsynced before the next run is counted done, so a
    crash or a kill loses only runs in flight, never a written row. Floats are written exactly
    (JSON's shortest round-trip text; NaN as ``NaN``)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._fh = open(self.path, "a", encoding="utf-8")  # noqa: SIM115  (closed by close())

    def append(self, row: dict[str, Any]) -> None:
        self._fh.write(json.dumps(row, separators=(",", ":")) + "\n")
        self._fh.flush()
        os.fsync(self._fh.fileno())

    def close(self) -> None:
        self._fh.close()

    def __enter__(self) -> Journal:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def read_journal(path: str | Path, *, repair: bool = False) -> tuple[list[dict[str, Any]], int]:
    """The journal's complete rows, in file order, and how many broken lines were dropped.

    A line is complete when it ends with a newline and parses as a JSON object with a ``key``;
    a process killed mid-write leaves at most one incomplete last line. ``repair``: rewrite the
    file with only the complete rows (atomically), so appending after it starts a clean line.
    A missing journal has no rows.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        return [], 0
    lines = data.split(b"\n")
    tail = lines.pop()  # b"" when the file ends with a newline, else an unfinished line
    rows: list[dict[str, Any]] = []
    good: list[bytes] = []
    dropped = 1 if tail.strip() else 0
    for line in lines:
        try:
            row = json.loads(line)
        except ValueError:
            row = None
        if isinstance(row, dict) and isinstance(row.get("key"), str):
            rows.append(row)
            good.append(line)
        elif line.strip():
            dropped += 1
    if repair and (dropped or tail):
        _atomic_write(path, b"".join(x + b"\n" for x in good))
    return rows, dropped


def _atomic_write(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    with open(tmp, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def saved_runs(out: str | Path) -> int:
    """How many finished runs (keys with a successful journal row) an interrupted sweep left
    in ``out``; 0 when there are none or the sweep there completed (``sweep.json`` says
    ``complete``). Interrupted means: no ``sweep.json`` (killed, or still running) or one
    written on an interruption (``complete`` false)."""
    out = Path(out)
    done = done_keys(read_journal(out / JOURNAL)[0])
    if not done:
        return 0
    try:
        info = json.loads((out / "sweep.json").read_text())
    except (OSError, ValueError):
        return len(done)
    return 0 if isinstance(info, dict) and info.get("complete") is True else len(done)


def latest_rows(rows: Iterable[dict[str, Any]], jobs: Sequence[Job]) -> list[dict[str, Any]]:
    """One row per job that has one, in plan order: a key's last journal row wins (a failed
    run repeated on ``--resume`` is replaced by its new row). Rows of keys not in the plan (a
    changed scenario) are left out."""
    by_key: dict[str, dict[str, Any]] = {}
    for r in rows:
        by_key[r["key"]] = r
    return [by_key[j.key] for j in jobs if j.key in by_key]


def done_keys(rows: Iterable[dict[str, Any]]) -> set[str]:
    """Keys whose latest row is a success: what ``--resume`` skips (failed runs run again)."""
    last: dict[str, dict[str, Any]] = {}
    for r in rows:
        last[r["key"]] = r
    return {k for k, r in last.items() if not r.get("error")}


def finish(out: str | Path, jobs: Sequence[Job]) -> tuple[list[dict[str, Any]], list[str]]:
    """Rewrite ``out/sweep.csv`` from the journal, in plan order (atomically), with
    ``summary.csv`` (:func:`aquasim_py.metrics.summarize_runs` per grid point over the
    successful runs, and the reports' centre and interval,
    :func:`aquasim_py.reporting.intervals.summarize`, as ``center_stat``, ``center``,
    ``center_ci95_low`` and ``center_ci95_high``) and ``sweep.parquet`` when pyarrow is installed. Returns the rows and the
    columns. The same journal rows give the same bytes whatever order they finished in."""
    out = Path(out)
    rows = latest_rows(read_journal(out / JOURNAL)[0], jobs)
    fill_counts(rows)
    cols = columns(rows, jobs)
    tmp = out / f".sweep.csv.tmp-{os.getpid()}"
    rows_to_csv(rows, cols, tmp)
    with open(tmp, "rb+") as fh:
        os.fsync(fh.fileno())
    os.replace(tmp, out / "sweep.csv")
    _write_summary(out, jobs, cols)
    return rows, cols


#: the statistic the reports draw and tabulate, beside the mean in summary.csv
CENTER_COLUMNS = ("center_stat", "center", "center_ci95_low", "center_ci95_high")


def _write_summary(out: Path, jobs: Sequence[Job], cols: Sequence[str]) -> None:
    import pandas as pd

    from aquasim_py.metrics import summarize_runs
    from aquasim_py.reporting import intervals

    grid = [k for k, _ in jobs[0].point] if jobs else []
    df = pd.read_csv(out / "sweep.csv", dtype={"key": str, "error": str})
    if "error" in df.columns:
        df["error"] = df["error"].fillna("")
    fixed = set(grid) | {"run", "seed", "key", "error"}
    ok = df[df["error"] == ""] if "error" in df.columns else df
    metric_cols = [c for c in cols if c not in fixed and pd.api.types.is_numeric_dtype(ok[c])]
    if metric_cols and len(ok):
        summary = summarize_runs(ok, by=grid, metrics=metric_cols)
        # the reports' centre (the geometric mean of a metric positive in every run), named
        center = intervals.summarize(ok, grid, metric_cols).drop(columns="n")
        center.columns = [*grid, "metric", *CENTER_COLUMNS]
        summary = summary.merge(center, on=[*grid, "metric"], how="left", validate="one_to_one")
    else:
        cols_out = [*grid, "metric", "n", "mean", "std", "ci95_low", "ci95_high", *CENTER_COLUMNS]
        summary = pd.DataFrame(columns=cols_out)
    summary.to_csv(out / "summary.csv", index=False, lineterminator="\n")
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        return
    df.to_parquet(out / "sweep.parquet", index=False)
