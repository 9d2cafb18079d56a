"""The one way to run a scenario: :func:`run_scenario` (and :func:`run_variants` for every
variant of a file). The CLI, sweeps (local processes and Dask workers) and notebooks all run
through :func:`run_scenario`.

Example (a notebook)::

    import aquasim_py
    res = aquasim_py.run_scenario("scenarios/itmtl.toml", variant="wsc", seed=7,
                                  overrides={"simulation.duration_s": 120})
    res.metrics["localization.rmse_m"]
    res.tables["estimates"].groupby("node").error.mean()
    res.write("out/itmtl-wsc")          # exactly what `aquasim-py ... --variant wsc` writes

Outputs are staged (:func:`staged_output`, :mod:`aquasim_py.outdir`): written to a hidden
temporary directory and moved into place only when complete, so a failed run leaves nothing
behind; an existing directory is written into only when it is an aquasim-py output (or with
``overwrite=True``), and then only the files the tool wrote there are removed or replaced.
"""

from __future__ import annotations

import gc
import json
import math
import os
import shutil
import sys
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from aquasim_py import scenario as _scenario
from aquasim_py._version import __version__
from aquasim_py.outdir import staged_output
from aquasim_py.rows import json_safe, rows_to_csv
from aquasim_py.scenario import Scenario, ScenarioError
from aquasim_py.scenario.load import Overrides, variant_error

if TYPE_CHECKING:
    import pandas as pd

    from aquasim_py.net.metrics import NetWindow

__all__ = [
    "RunResult",
    "check_output_format",
    "citations_of",
    "compare",
    "execute",
    "json_safe",
    "network_window",
    "paper_citations",
    "relocate_results",
    "run_scenario",
    "run_staged",
    "run_variants",
    "staged_output",
    "write_comparison",
]

#: ``(simulated time, end time)`` in seconds, called as the run advances
ProgressFn = Callable[[float, float], None]
Progress = bool | ProgressFn | None


# --------------------------------------------------------------------------- results
@dataclass(eq=False)
class RunResult:
    """One finished run: its trace tables, metrics and the exact scenario that produced them.

    ``tables``: trace table name -> DataFrame, read from the files the run streamed when first
    asked for (:class:`~aquasim_py.trace.TraceFiles`): the tables ``[trace] tables`` selects
    and those the metrics read (the latter from a scratch directory that lives as long as this
    result); a table neither needed was not kept. ``metrics``: summary metrics (name -> number);
    ``scenario``: the resolved scenario (defaults, variant, overrides and seed applied);
    ``variant``: the variant's name, or None for the file as written.
    """

    scenario: Scenario
    tables: Mapping[str, pd.DataFrame]
    metrics: dict[str, Any]
    wall_time_s: float
    variant: str | None = None
    out: Path | None = field(default=None)  # where write() last put the outputs
    #: metric family -> "ExceptionType: message" for families whose computation failed
    metric_errors: dict[str, str] = field(default_factory=dict)
    #: the bound beside each estimate that declared its references (``bounds.csv``,
    #: :mod:`aquasim_py.estimate_bounds`); None where none did
    bounds: pd.DataFrame | None = None

    @property
    def seed(self) -> int:
        return self.scenario.simulation.seed

    @property
    def name(self) -> str:
        """``scenario`` or ``scenario/variant``."""
        return self.scenario.name if self.variant is None else f"{self.scenario.name}/{self.variant}"

    def summary(self) -> dict[str, Any]:
        """What ``summary.json`` holds (JSON-safe: NaN becomes null)."""
        sc = self.scenario
        return json_safe(
            {
                "aquasim_py_version": __version__,
                "scenario_file": str(sc.path),
                "seed": sc.simulation.seed,
                "variant": self.variant,
                "wall_time_s": self.wall_time_s,
                "metrics": self.metrics,
                **({"metric_errors": self.metric_errors} if self.metric_errors else {}),
                "scenario": sc.to_dict(),
            }
        )

    def reports(self) -> list[Any]:
        """What each protocol's optional ``report(tables)`` returns (rich renderables or text)."""
        out = []
        for cls in self.scenario.protocols():
            report = getattr(cls, "report", None)
            if callable(report):
                try:
                    r = report(self.tables)
                except Exception as e:  # a failed report must not lose the run's outputs
                    name = getattr(cls, "name", cls.__name__)
                    r = f"{name}: report failed ({type(e).__name__}: {e})"
                if r is not None and r != "":
                    out.append(r)
        return out

    def derived_tables(self) -> dict[str, Any]:
        """The tables behind what the protocols' reports print (each protocol's optional
        ``derived_tables(tables) -> {name: DataFrame}``, e.g. ITMTL's per-round table), written
        beside the trace tables so a printed table is never only on the terminal."""
        out: dict[str, Any] = {}
        for cls in self.scenario.protocols():
            derive = getattr(cls, "derived_tables", None)
            if callable(derive):
                try:
                    out.update(derive(self.tables))
                except Exception as e:  # like a failed report: the run's outputs are kept
                    name = getattr(cls, "name", cls.__name__)
                    self.metric_errors[f"{name}.derived_tables"] = f"{type(e).__name__}: {e}"
        return out

    @property
    def missing_tables(self) -> list[str]:
        """Tables ``[trace] tables`` asks for that this run did not produce."""
        wanted = self.scenario.trace.tables or []
        return [n for n in wanted if n not in self.tables]

    def write(self, directory: str | Path, *, overwrite: bool = False) -> Path:
        """Write the outputs of a plain run (the selected trace tables and ``summary.json``)
        to ``directory``, staged: all or nothing. A non-empty directory that is not an
        aquasim-py output is refused unless ``overwrite`` (which replaces only the files
        written here). Returns the directory."""
        directory = Path(directory)
        check_output_format(self.scenario)
        with staged_output(directory, self.scenario.path, "out", overwrite=overwrite) as tmp:
            self.write_into(tmp, final=directory)
        return directory

    def write_into(self, directory: str | Path, *, final: str | Path | None = None) -> None:
        """Write the outputs into an existing directory, unstaged. ``final``: the directory the
        outputs will end up in (recorded as ``output.directory``); default ``directory``.

        A table the run already streamed into ``directory`` stays as it is; one streamed
        elsewhere is copied (converted when its file format differs)."""
        from aquasim_py.trace import TraceFiles, write_frames

        directory = Path(directory)
        final = Path(final) if final is not None else directory
        self.scenario.output.directory = str(final)  # the resolved scenario says where its outputs went
        self.out = final
        wanted = self.scenario.trace.tables
        fmt = self.scenario.trace.format
        frames: dict[str, Any] = {}
        for name in self.tables:
            if wanted is not None and name not in wanted:
                continue
            src = self.tables.path(name) if isinstance(self.tables, TraceFiles) else None
            dst = directory / f"{name}.{fmt}"
            if src is None or src.suffix != dst.suffix:
                frames[name] = self.tables[name]
            elif src.resolve() != dst.resolve():
                shutil.copyfile(src, dst)
        if self.bounds is not None and (wanted is None or "estimates" in wanted):
            frames["bounds"] = self.bounds
        write_frames({**frames, **self.derived_tables()}, directory, fmt)
        (directory / "summary.json").write_text(json.dumps(self.summary(), indent=2) + "\n")

    def __repr__(self) -> str:
        rows = getattr(self.tables, "rows", lambda k: len(self.tables[k]))  # without reading the files
        tables = ", ".join(f"{k} ({rows(k)} rows)" for k in self.tables)
        shown = [k for k in self.metrics if not k.startswith("packets.")][:4] or list(self.metrics)[:4]
        metrics = ", ".join(f"{k}={_short(self.metrics[k])}" for k in shown)
        more = len(self.metrics) - len(shown)
        return (
            f"<RunResult {self.name} seed={self.seed} {self.scenario.simulation.duration_s:g} s simulated"
            f" in {self.wall_time_s:.1f} s\n  tables: {tables}\n  metrics: {metrics}"
            + (f" (+{more} more)" if more > 0 else "")
            + ">"
        )


def _short(v: Any) -> str:
    return f"{v:.4g}" if isinstance(v, float) else str(v)


# --------------------------------------------------------------------------- running
def _as_scenario(
    scenario_or_path: Scenario | str | os.PathLike[str],
    variant: str | None,
    seed: int | None,
    overrides: Overrides,
) -> Scenario:
    if isinstance(scenario_or_path, Scenario):
        if variant is None and seed is None and not overrides:
            return scenario_or_path
        return _scenario.resolve(scenario_or_path, variant=variant, overrides=overrides, seed=seed)
    return _scenario.load(Path(scenario_or_path), overrides=overrides, seed=seed, variant=variant)


def run_scenario(
    scenario_or_path: Scenario | str | os.PathLike[str],
    *,
    variant: str | None = None,
    seed: int | None = None,
    overrides: Overrides = (),
    out: str | Path | None = None,
    overwrite: bool = False,
    progress: Progress = None,
) -> RunResult:
    """Run one scenario and return its tables, metrics and resolved scenario.

    Args:
        scenario_or_path: A scenario file, or a :class:`~aquasim_py.scenario.Scenario` from
            :func:`aquasim_py.scenario.load` (re-resolved from its source when ``variant``,
            ``seed`` or ``overrides`` are given).
        variant: One of the file's ``[variants.NAME]``; None: the file as written.
        seed: Replaces ``[simulation] seed``.
        overrides: ``"key.path=value"`` strings (as ``--set``), ``(key path, value)`` pairs or
            a mapping key path -> value; applied after the variant.
        out: Also write the outputs there (staged, as the CLI does).
        overwrite: As for :meth:`RunResult.write`.
        progress: True for a progress bar on stderr, False for none, a callable
            ``(t_s, until_s)``; None shows a bar only when stderr is a terminal.

    Returns:
        The finished run: trace tables, metrics, the resolved scenario.

    Raises:
        ScenarioError: The scenario is bad (:class:`~aquasim_py.scenario.ScenarioError`,
            naming the file, the key and the problem), before anything runs.

    Examples:
        Two simulated minutes of the beacon scenario (paths from the repository's root):

        >>> import aquasim_py
        >>> res = aquasim_py.run_scenario(
        ...     "scenarios/beacon.toml", overrides={"simulation.duration_s": 120}
        ... )
        >>> res.metrics["beacon.ranges"]  # one-way ranges the six sensors measured
        288
        >>> round(res.metrics["beacon.range_rmse_m"], 2)  # m
        2.75
        >>> res.tables["ranges"].columns.tolist()[:6]
        ['time', 'node', 'protocol', 'anchor', 'uid', 'tx_local']

        The same run, one of a file's variants, another seed:
        ``aquasim_py.run_scenario("scenarios/itmtl.toml", variant="wsc", seed=7)``.
    """
    sc = _as_scenario(scenario_or_path, variant, seed, overrides)
    if out is not None:
        return run_staged(sc, out, overwrite=overwrite, progress=progress)
    return execute(sc, progress)


def run_staged(
    sc: Scenario, out: str | Path, *, key: str = "out", overwrite: bool = False, progress: Progress = None
) -> RunResult:
    """Run ``sc`` with its trace tables streamed into the staging directory of ``out`` and
    moved into place when complete (``key``: the option or scenario key named in a refusal)."""
    out = Path(out)
    check_output_format(sc)
    with staged_output(out, sc.path, key, overwrite=overwrite) as tmp:
        res = execute(sc, progress, dest=tmp)
        res.write_into(tmp, final=out)
    relocate_results({"": res}, tmp, out)
    return res


def relocate_results(results: Mapping[str, RunResult], tmp: Path, final: Path) -> None:
    """The staged files of ``results`` were moved from ``tmp`` into ``final``: their tables are
    read from there from now on."""
    from aquasim_py.trace import TraceFiles

    for res in results.values():
        if isinstance(res.tables, TraceFiles):
            res.tables.relocate(tmp, final)


@contextmanager
def _streamed_trace(sim: Any, sc: Scenario, dest: Path | None) -> Iterator[Callable[[], Any]]:
    """Route every trace table of ``sim`` to a file as the run goes: the tables ``[trace]
    tables`` selects into ``dest`` (None: the scratch directory), those only the metrics read
    (:func:`~aquasim_py.metrics.tables_read`) into a scratch directory, the others nowhere.
    Gives a function that finishes the files and returns their
    :class:`~aquasim_py.trace.TraceFiles`, which then owns the scratch directory; an error
    or a signal inside the block removes it."""
    from aquasim_py import metrics
    from aquasim_py.outdir import scratch_dir
    from aquasim_py.trace import TraceFiles

    wanted = sc.trace.tables
    needed = metrics.tables_read(sc.protocols())
    fmt = sc.trace.format
    if fmt == "parquet" and dest is None and not _has_pyarrow():
        fmt = "csv"  # no file asked for: parquet only when it can be written (write() converts)
    made: list[Path] = []  # the scratch directory, recorded before it is made: what an error removes
    try:
        scratch = scratch_dir(made)

        def route(name: str) -> Path | None:
            if wanted is None or name in wanted:
                return (dest if dest is not None else scratch) / f"{name}.{fmt}"
            if needed is None or name in needed:
                return scratch / f"{name}.{fmt}"
            return None

        def finish() -> TraceFiles:
            done = sim.trace.close()
            files = {k: p for k, (p, _) in done.items() if p is not None}
            dropped = [k for k, (p, _) in done.items() if p is None]
            tallies = {k: t.tallies for k, t in sim.trace.tables.items() if t.tallies}
            kept = {k: (df, tuple(t.columns)) for k, t in sim.trace.tables.items() if (df := t.kept()) is not None}
            return TraceFiles(files, {k: n for k, (_, n) in done.items()}, dropped, scratch, tallies, kept)

        for name, columns in metrics.TALLIED.items():  # counted as written, not read back
            sim.trace.table(name).tally(columns)
        if fmt == "csv":  # (parquet's read-back has its own dtypes)
            for name, columns in metrics.columns_kept(sc.protocols()).items():  # kept as written
                sim.trace.table(name).keep(columns)
        sim.trace.stream(route, fmt)
        yield finish
    except BaseException:
        for p in made:
            shutil.rmtree(p, ignore_errors=True)
        raise


def _has_pyarrow() -> bool:
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        return False
    return True


def execute(sc: Scenario, progress: Progress = False, dest: Path | None = None) -> RunResult:
    """Build and run a resolved scenario, streaming its trace tables (those ``[trace] tables``
    selects into the existing directory ``dest``, unstaged: callers stage), then compute the
    metrics from the files written."""
    from aquasim_py import metrics
    from aquasim_py.estimate_bounds import applied_range_noise, estimate_bounds

    sim = _scenario.build(sc)
    with _streamed_trace(sim, sc, dest) as finish:
        wall = _run(sim, sc, progress)
        tables = finish()
    # The metrics read the tables back from the files: the network (nodes, modem buffers,
    # SimPy queue; reference cycles) is freed first, so that reading reuses its memory instead
    # of adding to the run's peak (STVF's Table 1 run).
    del sim, finish
    gc.collect()
    errors: dict[str, str] = {}
    bounds = estimate_bounds(tables, applied_range_noise(sc))
    m = metrics.summarize(
        tables,
        sc.protocols(),
        percentiles=sc.metrics.percentiles,
        warmup_s=sc.metrics.warmup_s,
        unknown_roles=sc.metrics.unknown_roles,
        errors=errors,
        bounds=bounds,
        network=network_window(sc),
    )
    return RunResult(
        scenario=sc,
        tables=tables,
        metrics=dict(m),
        wall_time_s=wall,
        variant=sc.variant,
        metric_errors=errors,
        bounds=bounds,
    )


def network_window(sc: Scenario) -> NetWindow | None:
    """The window of a run's network metrics (``net.*``): computed where a node group names
    its MAC or runs a protocol that asks for them (``net_metrics = True``, the traffic
    protocol); None elsewhere (a run as before MACs existed gets no new metrics)."""
    from aquasim_py.net.metrics import NetWindow

    if not (any(g.mac is not None for g in sc.nodes) or any(getattr(c, "net_metrics", False) for c in sc.protocols())):
        return None
    return NetWindow(sc.metrics.warmup_s, sc.simulation.duration_s, _scenario.channel_config(sc).airtime)


def _run(sim: Any, sc: Scenario, progress: Progress) -> float:
    """Run ``sim`` for the scenario's duration with the progress display asked for; returns
    the wall time (s)."""
    duration = sc.simulation.duration_s
    label = sc.name if sc.variant is None else f"{sc.name}/{sc.variant}"
    started = time.perf_counter()
    if progress is None:
        progress = sys.stderr.isatty()
    if progress is True:
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

        with Progress(
            TextColumn("[bold]{task.description}"),
            BarColumn(),
            TextColumn("{task.completed:.0f}/{task.total:.0f} s simulated"),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
            console=console(stderr=True),
            transient=True,
        ) as prog:
            task = prog.add_task(label, total=duration)
            sim.run(duration, progress=lambda t, until: prog.update(task, completed=t))
    elif callable(progress):
        sim.run(duration, progress=progress)
    else:
        sim.run(duration)
    return time.perf_counter() - started


def run_variants(
    scenario_or_path: Scenario | str | os.PathLike[str],
    *,
    variants: Sequence[str] | None = None,
    seed: int | None = None,
    overrides: Overrides = (),
    out: str | Path | None = None,
    overwrite: bool = False,
    progress: Progress = None,
) -> dict[str, RunResult]:
    """Run every variant of a scenario (or those named in ``variants``) on the same network and
    seed; returns variant name -> result, in file order.

    Every variant is resolved and built before the first one runs, so a bad variant fails
    with nothing run. ``out``: write each variant's outputs under ``out/NAME/`` (each exactly
    what a plain run writes) and the comparison (:func:`compare`) as ``out/variants.csv``,
    all staged as one directory. A file without variants gives one result under the name
    ``"default"``. The other arguments are those of :func:`run_scenario`.
    """
    if isinstance(scenario_or_path, Scenario):
        base = scenario_or_path
        if seed is not None or overrides:
            base = _scenario.resolve(base, overrides=overrides, seed=seed)
    else:
        base = _scenario.load(Path(scenario_or_path), overrides=overrides, seed=seed)
    resolved = resolve_variants(base, variants)
    if out is None:
        return {name: run_scenario(sc, progress=progress) for name, sc in resolved.items()}
    out = Path(out)
    for sc in resolved.values():
        check_output_format(sc)
    with staged_output(out, base.path, "out", overwrite=overwrite) as tmp:
        results = run_resolved_into(resolved, tmp, out, progress)
    relocate_results(results, tmp, out)
    return results


def resolve_variants(base: Scenario, names: Sequence[str] | None = None) -> dict[str, Scenario]:
    """The resolved scenario of each variant (``names``, default every declared one, in file
    order; a file without variants gives itself as ``"default"``), each built once so that
    what only the physics rejects fails before anything runs."""
    declared = base.declared_variants
    if names is None:
        names = declared
    out: dict[str, Scenario] = {}
    if not declared and not names:
        out["default"] = base
    for name in names:
        out[name] = _scenario.resolve(base, variant=name)
    for sc in out.values():
        try:
            _scenario.build(sc)
        except ScenarioError as e:
            raise variant_error(sc, e) from None
    return out


def run_resolved_into(
    resolved: Mapping[str, Scenario], tmp: Path, final: Path, progress: Progress
) -> dict[str, RunResult]:
    """Run each resolved variant, writing it under ``tmp/NAME`` (recorded as ``final/NAME``),
    then ``tmp/variants.csv``. Once ``tmp`` is moved into place, :func:`relocate_results`."""
    results: dict[str, RunResult] = {}
    for name, sc in resolved.items():
        (tmp / name).mkdir()
        res = execute(sc, progress, dest=tmp / name)
        res.write_into(tmp / name, final=final / name)
        results[name] = res
    write_comparison(results, tmp / "variants.csv")
    paper = paper_comparison(results)
    if paper is not None:
        paper.to_csv(tmp / "paper.csv", index=False)
    return results


# --------------------------------------------------------------------------- comparison
def compare(results: Mapping[str, RunResult]) -> pd.DataFrame:
    """One row per variant (index ``variant``), one column per metric any of them reports:
    the metrics most variants report first (in first-seen order), then the others."""
    import pandas as pd

    common, rest = comparison_columns(results)
    df = pd.DataFrame([{c: r.metrics.get(c, math.nan) for c in common + rest} for r in results.values()])
    df.index = pd.Index(list(results), name="variant")
    return df


def comparison_columns(results: Mapping[str, RunResult]) -> tuple[list[str], list[str]]:
    """(metrics reported, as a finite number, by more than half of the results; the others)."""
    order: dict[str, int] = {}
    for r in results.values():
        for k, v in r.metrics.items():
            reported = isinstance(v, (int, float)) and not (isinstance(v, float) and math.isnan(v))
            order[k] = order.get(k, 0) + int(reported)
    n = len(results)
    common = [k for k, c in order.items() if 2 * c > n]
    return common, [k for k in order if k not in common]


def paper_comparison(results: Mapping[str, RunResult]) -> pd.DataFrame | None:
    """What the protocols' papers report beside the same statistics of these variants: each
    protocol class's optional ``paper_comparison(results) -> DataFrame | None`` (one row per
    claim: figure, quantity, statistic, ours, paper), rows concatenated; None when no protocol
    gives one. A comparison that fails gives one row saying so (the runs' outputs are kept)."""
    import pandas as pd

    frames, seen = [], set()
    for res in results.values():
        for cls in res.scenario.protocols():
            fn = getattr(cls, "paper_comparison", None)
            if not callable(fn) or getattr(fn, "__func__", fn) in seen:
                continue
            seen.add(getattr(fn, "__func__", fn))
            try:
                df = fn(results)
            except Exception as e:
                name = getattr(cls, "name", cls.__name__)
                df = pd.DataFrame(
                    [{"quantity": f"{name}: paper comparison failed", "ours": f"{type(e).__name__}: {e}"}]
                )
            if df is not None and len(df):
                frames.append(df)
    return pd.concat(frames, ignore_index=True) if frames else None


def paper_citations(results: Mapping[str, RunResult]) -> list[str]:
    """The papers :func:`paper_comparison` compares with (:func:`citations_of` the results'
    protocols)."""
    return citations_of([cls for res in results.values() for cls in res.scenario.protocols()])


def citations_of(classes: Sequence[type]) -> list[str]:
    """The ``citation`` (str) of each protocol class that gives a ``paper_comparison``, else
    "the paper of protocol NAME", once each, in order."""
    out: list[str] = []
    for cls in classes:
        if not callable(getattr(cls, "paper_comparison", None)):
            continue
        cite = getattr(cls, "citation", None)
        text = cite if isinstance(cite, str) and cite else f"the paper of protocol {getattr(cls, 'name', '?')}"
        if text not in out:
            out.append(text)
    return out


def write_comparison(results: Mapping[str, RunResult], path: str | Path) -> None:
    """``variants.csv``: :func:`compare` with exact float text (as ``sweep.csv``)."""
    common, rest = comparison_columns(results)
    rows = [{"variant": name, **r.metrics} for name, r in results.items()]
    rows_to_csv(rows, ["variant", *common, *rest], path)


# --------------------------------------------------------------------------- output
def check_output_format(sc: Scenario) -> None:
    """Parquet traces need pyarrow: say so before running, not after."""
    if sc.trace.format == "parquet":
        try:
            import pyarrow  # noqa: F401
        except ImportError:
            raise ScenarioError(
                sc.path, "trace.format", "parquet needs pyarrow (pip install 'aquasim-py[parquet]')"
            ) from None


def console(stderr: bool = False) -> Any:
    """A rich console on stdout (or stderr): a terminal sets its own width, a pipe or a file
    gets 120 columns (room for the sweep table)."""
    from rich.console import Console

    stream = sys.stderr if stderr else sys.stdout
    width = None if stream.isatty() or os.environ.get("COLUMNS") else 120
    return Console(file=stream, highlight=False, width=width)
