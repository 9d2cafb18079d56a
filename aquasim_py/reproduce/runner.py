"""Run a paper's claims as resumable sweeps (:mod:`aquasim_py.sweep`) and evaluate them.

The claims of one paper need runs of a few (scenario file, overrides) pairs, each over a few
variants and the scale's seeds: one *unit* per pair, run as a sweep whose grid is the
``variant`` key, journalled in ``DIR/units/<unit>/rows.jsonl`` as runs finish (so a killed
reproduction resumes without running a finished run again: :func:`aquasim_py.sweep.done_keys`)
and written out as that directory's ``sweep.csv`` / ``summary.csv``. Every variant of a unit
runs on the same seeds, so the claims' comparisons are paired.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from aquasim_py import scenario, sweep
from aquasim_py.scenario import Scenario

from .claims import Claim, Paper, Quantity, Reading, Scale
from .verdict import Outcome, evaluate

__all__ = ["ClaimResult", "Unit", "evaluate_claims", "plan_units", "run_units"]

ROOT = Path(__file__).resolve().parents[2]


@dataclass(frozen=True)
class Unit:
    """Runs of one scenario file with one set of overrides, over ``variants`` and ``runs`` seeds."""

    name: str
    scenario: Path
    overrides: tuple[str, ...]
    variants: tuple[str | None, ...]
    runs: int

    def load(self) -> Scenario:
        """The scenario with a ``[sweep]`` of the unit's seeds and variants."""
        grid = {} if self.variants == (None,) else {"variant": list(self.variants)}
        sets = [*self.overrides, f"sweep.runs={self.runs}", f"sweep.grid={_toml_inline(grid)}"]
        return scenario.load(self.scenario, overrides=sets)


def _toml_inline(grid: dict[str, list[Any]]) -> str:
    items = ", ".join(f"{k} = {json.dumps(v)}" for k, v in grid.items())
    return "{" + items + "}"


def _resolve(paper: Paper, scale: Scale, claim: Claim, reading: Reading) -> tuple[Path, tuple[str, ...]]:
    key = reading.scenarios.get(claim.scenario, claim.scenario)
    if key not in scale.scenarios:
        raise KeyError(f"{paper.key}: claim {claim.id!r} needs scenario {key!r}, not in the scale")
    return ROOT / scale.scenarios[key], (*scale.overrides, *reading.overrides, *claim.overrides)


def _variant(q: Quantity, reading: Reading) -> str | None:
    return reading.variants.get(q.variant, q.variant) if q.variant is not None else None


def _quantities(claim: Claim) -> list[Quantity]:
    return [q for q in (claim.a, claim.b) if q is not None]


def plan_units(
    paper: Paper, scale: Scale, claims: Sequence[Claim], *, runs: int | None = None, sets: Sequence[str] = ()
) -> list[Unit]:
    """The units ``claims`` need at ``scale`` (``runs``, ``sets``: replace the scale's seed count,
    add overrides to every run), in a stable order."""
    found: dict[tuple[Path, tuple[str, ...]], set[str | None]] = {}
    for claim in claims:
        for reading in paper.claim_readings(claim):
            path, over = _resolve(paper, scale, claim, reading)
            key = (path, (*over, *sets))
            found.setdefault(key, set()).update(_variant(q, reading) for q in _quantities(claim))
    units = []
    for (path, over), variants in found.items():
        if None in variants and len(variants) > 1:
            raise ValueError(f"{paper.key}: {path.name} is used both as written and by variant")
        tag = hashlib.sha256(json.dumps([path.name, list(over)]).encode()).hexdigest()[:8]
        vs = tuple(sorted(variants, key=lambda v: v or ""))
        units.append(Unit(f"{path.stem}-{tag}", path, over, vs, runs if runs is not None else scale.runs))
    return sorted(units, key=lambda u: u.name)


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
            with sweep.Journal(journal) as j:
                sweep.run_jobs(sc, todo, workers=workers, scheduler=scheduler, on_row=j.append, progress=tick)
        rows[unit.name] = sweep.finish(d, jobs)[0]
    return rows


@dataclass(frozen=True)
class ClaimResult:
    claim: Claim
    reading: Reading
    outcome: Outcome
    a_value: float  #: the statistic of quantity a alone
    b_value: float  #: and of b (nan without one)


def _series(rows: Sequence[dict[str, Any]], q: Quantity, variant: str | None) -> dict[int, float]:
    out: dict[int, float] = {}
    for r in rows:
        if r.get("error") or (variant is not None and r.get("variant") != variant):
            continue
        v = r.get(q.metric)
        out[int(r["run"])] = float(v) if isinstance(v, (int, float)) and v is not None else math.nan
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
            path, over = _resolve(paper, scale, claim, reading)
            unit = by_key[(path, (*over, *sets))]
            urows = rows.get(unit.name, [])
            sa = _series(urows, claim.a, _variant(claim.a, reading))
            sb = _series(urows, claim.b, _variant(claim.b, reading)) if claim.b is not None else None
            runs = sorted(set(sa) & set(sb) if sb is not None else set(sa))
            a = np.array([sa[r] for r in runs], float)
            b = np.array([sb[r] for r in runs], float) if sb is not None else None
            out = evaluate(claim, a, b)

            def stat(x: np.ndarray, q: Quantity) -> float:
                x = x[np.isfinite(x)]
                if x.size == 0:
                    return math.nan
                return float(np.sqrt(np.mean(x**2)) if q.statistic == "rms" else np.mean(x))

            av = stat(a, claim.a)
            bv = stat(b, claim.b) if b is not None and claim.b is not None else math.nan
            results.append(ClaimResult(claim, reading, out, av, bv))
    return results
