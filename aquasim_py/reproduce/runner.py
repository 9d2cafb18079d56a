"""Run a paper's claims as resumable sweeps (:mod:`aquasim_py.sweep`) and evaluate them.

The claims of one paper need runs of a few (scenario file, overrides) pairs, each over a few
variants and the scale's seeds: one *unit* per pair, run as a sweep whose grid is the
``variant`` key, journalled in ``DIR/units/<unit>/rows.jsonl`` as runs finish (so a killed
reproduction resumes without running a finished run again: :func:`aquasim_py.sweep.done_keys`)
and written out as that directory's ``sweep.csv`` / ``summary.csv``. Every unit of a scenario
file runs the same seeds (``run_seed(scenario seed, r)``: the same network and noise for every
variant), so the claims' comparisons are paired by run, also between two units.

Where a claim reads a run another way than its metrics (scored over another time window of
the scale, or a per-interval series), each run's trace tables are kept while it finishes,
read again into its row (``<window>.<metric>``; ``<metric>[k]`` from the protocols'
``interval_metrics``) before the row is journalled, and removed.
"""

from __future__ import annotations

import hashlib
import json
import math
import shutil
import tomllib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aquasim_py import scenario, sweep
from aquasim_py.scenario import Scenario

from .claims import Claim, Paper, Quantity, Reading, Scale, Statistic
from .verdict import Outcome, evaluate, stat

__all__ = ["ClaimResult", "Unit", "evaluate_claims", "plan_units", "resolved", "run_units"]

ROOT = Path(__file__).resolve().parents[2]


@dataclass(frozen=True)
class Unit:
    """Runs of one scenario file with one set of overrides, over ``variants`` and ``runs`` seeds.

    ``windows``: (name, time) pairs the runs' metrics are also scored from; ``intervals``:
    whether the rows need the protocols' per-interval series."""

    name: str
    scenario: Path
    overrides: tuple[str, ...]
    variants: tuple[str | None, ...]
    runs: int
    windows: tuple[tuple[str, float], ...] = ()
    intervals: bool = False

    def load(self) -> Scenario:
        """The scenario with a ``[sweep]`` of the unit's seeds and variants. The file's other
        variants are left out: an override of one protocol's parameter (STVF's Nr) would not
        validate in a variant running another protocol (SLMP)."""
        raw = tomllib.loads(self.scenario.read_text(encoding="utf-8"))
        if isinstance(raw.get("variants"), dict):
            raw["variants"] = {k: v for k, v in raw["variants"].items() if k in self.variants}
        grid = {} if self.variants == (None,) else {"variant": list(self.variants)}
        sets = [*self.overrides, f"sweep.runs={self.runs}", f"sweep.grid={_toml_inline(grid)}"]
        return scenario.load_dict(raw, self.scenario, overrides=sets)

    @property
    def rereads(self) -> bool:
        """Whether each run's traces are read again before its row is journalled."""
        return bool(self.windows) or self.intervals


def _toml_inline(grid: dict[str, list[Any]]) -> str:
    items = ", ".join(f"{k} = {json.dumps(v)}" for k, v in grid.items())
    return "{" + items + "}"


def _resolve(paper: Paper, scale: Scale, claim: Claim, reading: Reading) -> tuple[str, Path, tuple[str, ...]]:
    key = reading.scenarios.get(claim.scenario, claim.scenario)
    if key not in scale.scenarios:
        raise KeyError(f"{paper.key}: claim {claim.id!r} needs scenario {key!r}, not in the scale")
    return key, ROOT / scale.scenarios[key], (*scale.overrides, *reading.overrides, *claim.overrides)


def _variant(q: Quantity, reading: Reading) -> str | None:
    return reading.variants.get(q.variant, q.variant) if q.variant is not None else None


def resolved(q: Quantity, reading: Reading) -> tuple[str, Statistic]:
    """The column a quantity reads under ``reading`` and its statistic."""
    metric, statistic = reading.metrics.get(q.metric, (q.metric, q.statistic))
    return (f"{reading.window}.{metric}" if reading.window else metric), statistic


def _quantity_overrides(scale: Scale, reading: Reading, q: Quantity) -> tuple[str, ...]:
    """Overrides of one quantity's runs only: its variant's (the scale's, then the reading's)
    and its own."""
    v = _variant(q, reading)
    if v is None:
        return q.overrides
    return (*scale.variant_overrides.get(v, ()), *reading.variant_overrides.get(v, ()), *q.overrides)


def _quantities(claim: Claim) -> list[Quantity]:
    return [q for q in (claim.a, claim.b) if q is not None]


def plan_units(
    paper: Paper,
    scale: Scale,
    claims: Sequence[Claim],
    *,
    runs: int | Mapping[str | None, int] | None = None,
    sets: Sequence[str] = (),
) -> list[Unit]:
    """The units ``claims`` need at ``scale``, in a stable order. ``runs``: seeds per quantity
    instead of the scale's, for every scenario (an int, or the key None) or for the scale's
    scenario keys given; ``sets``: overrides of every run."""
    counts: Mapping[str | None, int] = runs if isinstance(runs, Mapping) else ({None: runs} if runs is not None else {})
    found: dict[tuple[Path, tuple[str, ...]], set[str | None]] = {}
    count: dict[tuple[Path, tuple[str, ...]], int] = {}
    windows: dict[tuple[Path, tuple[str, ...]], set[str]] = {}
    intervals: set[tuple[Path, tuple[str, ...]]] = set()
    for claim in claims:
        for reading in paper.claim_readings(claim):
            skey, path, over = _resolve(paper, scale, claim, reading)
            if reading.window and reading.window not in scale.windows:
                raise KeyError(f"{paper.key}: reading {reading.name!r} needs window {reading.window!r}")
            for q in _quantities(claim):
                key = (path, (*over, *_quantity_overrides(scale, reading, q), *sets))
                found.setdefault(key, set()).add(_variant(q, reading))
                count[key] = counts.get(skey, counts.get(None, scale.runs_by_scenario.get(skey, scale.runs)))
                if reading.window:
                    windows.setdefault(key, set()).add(reading.window)
                if resolved(q, reading)[1] in ("time_mean_rms", "interval_mean"):
                    intervals.add(key)
    units = []
    for key, variants in found.items():
        path, over = key
        if None in variants and len(variants) > 1:
            raise ValueError(f"{paper.key}: {path.name} is used both as written and by variant")
        win = tuple((w, scale.windows[w]) for w in sorted(windows.get(key, ())))
        ident = [path.name, list(over), [list(w) for w in win], key in intervals]
        tag = hashlib.sha256(json.dumps(ident).encode()).hexdigest()[:8]
        vs = tuple(sorted(variants, key=lambda v: v or ""))
        units.append(Unit(f"{path.stem}-{tag}", path, over, vs, count[key], win, key in intervals))
    return sorted(units, key=lambda u: u.name)


def _reread(unit: Unit, sc: Scenario, row: dict[str, Any], traces: Path) -> None:
    """Add the run's other readings to ``row`` from its traces (``traces/<key>/``), then remove
    them: its metrics scored over each window, and the protocols' per-interval series."""
    from aquasim_py import metrics, registry, trace

    d = traces / str(row["key"])
    try:
        if row.get("error") or not d.is_dir():
            return
        # read lazily: a table is parsed only when a metric asks for it
        tables = trace.TraceFiles({f.stem: f for f in sorted(d.iterdir()) if f.suffix in (".csv", ".parquet")})
        for name, t0 in unit.windows:
            m = metrics.summarize(
                tables, None, percentiles=sc.metrics.percentiles, warmup_s=t0, unknown_roles=sc.metrics.unknown_roles
            )
            row.update({f"{name}.{k}": _plain(v) for k, v in m.items() if not k.startswith("packets.")})
        if unit.intervals:
            nodes = tables.get("nodes")
            names = [] if nodes is None else list(dict.fromkeys(nodes["protocol"].astype(str)))
            for proto in names:
                fn = getattr(registry.get(proto), "interval_metrics", None)
                if fn is not None:
                    row.update({f"{proto}.{k}": _plain(v) for k, v in fn(tables).items()})
    finally:
        shutil.rmtree(d, ignore_errors=True)


def _plain(v: Any) -> Any:
    return v.item() if isinstance(v, np.generic) else v


def run_units(
    units: Sequence[Unit],
    out: Path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    resume: bool = False,
    progress: Callable[[Unit, int, int], None] | None = None,
) -> dict[str, list[dict[str, Any]]]:
    """Run every unit's missing runs (all, without ``resume``) into ``out/units/<unit>/`` and
    return each unit's rows in plan order. ``progress(unit, done, total)`` after each run."""
    rows: dict[str, list[dict[str, Any]]] = {}
    for unit in units:
        sc = unit.load()
        jobs = sweep.plan(sc)
        d = out / "units" / unit.name
        d.mkdir(parents=True, exist_ok=True)
        journal = d / sweep.JOURNAL
        if not resume:
            journal.unlink(missing_ok=True)
        before, _dropped = sweep.read_journal(journal, repair=True)
        done = sweep.done_keys(before)
        # seed by seed, every variant of a seed before the next seed: a reproduction stopped
        # early has complete, paired seeds
        todo = sorted((j for j in jobs if j.key not in done), key=lambda j: (j.run, j.index))
        if todo:
            base = len(jobs) - len(todo)
            total = len(jobs)
            tick = None if progress is None else (lambda k, _n, u=unit, b=base, t=total: progress(u, b + k, t))
            traces = d / "traces" if unit.rereads else None
            with sweep.Journal(journal) as j:

                def on_row(
                    row: dict[str, Any], j: sweep.Journal = j, u: Unit = unit, s: Scenario = sc, t: Path | None = traces
                ) -> None:
                    if t is not None:
                        _reread(u, s, row, t)
                    j.append(row)

                sweep.run_jobs(
                    sc, todo, workers=workers, scheduler=scheduler, on_row=on_row, progress=tick, traces=traces
                )
            if traces is not None:
                shutil.rmtree(traces, ignore_errors=True)
        rows[unit.name] = sweep.finish(d, jobs)[0]
    return rows


@dataclass(frozen=True)
class ClaimResult:
    claim: Claim
    reading: Reading
    outcome: Outcome
    a_value: float  #: the statistic of quantity a alone
    b_value: float  #: and of b (nan without one)
    a_metric: str  #: the column quantity a read under the reading, and its statistic
    a_statistic: Statistic
    b_metric: str
    b_statistic: Statistic | None
    a_overrides: tuple[str, ...] = ()  #: the ``--set`` overrides of quantity a's runs (its unit's)
    b_overrides: tuple[str, ...] = ()


def _values(rows: Sequence[dict[str, Any]], metric: str, statistic: Statistic, variant: str | None) -> dict[int, Any]:
    """Run -> the metric's value (a float), or for a per-interval statistic the run's series
    ``metric[k]`` in k order (an array; NaN where missing)."""
    out: dict[int, Any] = {}
    prefix = f"{metric}["
    for r in rows:
        if r.get("error") or (variant is not None and r.get("variant") != variant):
            continue
        if statistic in ("time_mean_rms", "interval_mean"):
            keys = sorted((k for k in r if k.startswith(prefix)), key=lambda k: int(k[len(prefix) : -1]))
            out[int(r["run"])] = np.array([_num(r[k]) for k in keys], float)
        else:
            out[int(r["run"])] = _num(r.get(metric))
    return out


def _num(v: Any) -> float:
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else math.nan


def _stack(values: list[Any]) -> np.ndarray:
    """Per-run values as (runs,), or series as (runs, intervals), padded with NaN."""
    if not values or np.ndim(values[0]) == 0:
        return np.array(values, float)
    k = max((len(v) for v in values), default=0)
    out = np.full((len(values), k), math.nan)
    for i, v in enumerate(values):
        out[i, : len(v)] = v
    return out


def evaluate_claims(
    paper: Paper,
    scale: Scale,
    claims: Sequence[Claim],
    rows: dict[str, list[dict[str, Any]]],
    units: Sequence[Unit],
    *,
    sets: Sequence[str] = (),
) -> list[ClaimResult]:
    """Every claim under every one of its readings, from the units' rows."""
    by_key = {(u.scenario, u.overrides): u for u in units}
    results = []
    for claim in claims:
        for reading in paper.claim_readings(claim):
            _key, path, over = _resolve(paper, scale, claim, reading)

            def unit_of(
                q: Quantity, path: Path = path, over: tuple[str, ...] = over, reading: Reading = reading
            ) -> Unit:
                return by_key[(path, (*over, *_quantity_overrides(scale, reading, q), *sets))]

            ma, sa = resolved(claim.a, reading)
            ua = unit_of(claim.a)
            va = _values(rows.get(ua.name, []), ma, sa, _variant(claim.a, reading))
            vb = None
            mb, sb = "", None
            ub_over: tuple[str, ...] = ()
            if claim.b is not None:
                mb, sb = resolved(claim.b, reading)
                ub = unit_of(claim.b)
                ub_over = ub.overrides
                vb = _values(rows.get(ub.name, []), mb, sb, _variant(claim.b, reading))
            runs = sorted(set(va) & set(vb) if vb is not None else set(va))
            a = _stack([va[r] for r in runs])
            b = _stack([vb[r] for r in runs]) if vb is not None else None
            out = evaluate(claim, a, b, sa, sb)

            def alone(x: np.ndarray, how: Statistic) -> float:
                keep = np.isfinite(x) if x.ndim == 1 else np.isfinite(x).any(axis=1)
                if not keep.any():
                    return math.nan
                v = stat(x[keep], how)
                return float(np.nanmean(v)) if v.ndim else float(v)  # a curve: its mean over intervals

            av = alone(a, sa)
            bv = alone(b, sb) if b is not None and sb is not None else math.nan
            results.append(ClaimResult(claim, reading, out, av, bv, ma, sa, mb, sb, ua.overrides, ub_over))
    return results
