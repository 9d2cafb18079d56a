"""Reproductions a researcher can cite: each paper's claims as data (:mod:`.papers`), run as
resumable sweeps (:mod:`.runner`, on :mod:`aquasim_py.sweep`), reported claim by claim under
every reading of the paper's open choices (``claims.csv``, ``index.html``: :mod:`.report`).

    aquasim-py reproduce stvf --quick
    aquasim_py.reproduce.reproduce("stvf", "quick", "out/reproduce/stvf-quick")

``DIR`` holds ``claims.csv`` (and the same as a markdown table, ``claims.md``), ``index.html``,
``reproduce.json`` (what ran: paper, scale,
command, units, timing) and ``units/<unit>/`` (each unit's row journal, ``sweep.csv`` and
``summary.csv``).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from .claims import REL_TOL, Claim, Paper, Quantity, Reading, Scale
from .papers import PAPERS
from .report import claims_table, markdown, write_csv, write_html
from .runner import Unit, evaluate_claims, plan_units, run_units

if TYPE_CHECKING:
    import pandas as pd

__all__ = [
    "PAPERS",
    "REL_TOL",
    "Claim",
    "Paper",
    "Quantity",
    "Reading",
    "Reproduction",
    "Scale",
    "reproduce",
    "select",
]

OUTPUTS = ("claims.csv", "claims.md", "index.html", "reproduce.json")


@dataclass(frozen=True)
class Reproduction:
    paper: Paper
    scale: str
    units: list[Unit]
    table: pd.DataFrame  #: claims.csv
    wall_s: float


def select(paper: Paper, only: Sequence[str] = ()) -> tuple[Claim, ...]:
    """The paper's claims, or those whose id is in ``only`` (KeyError naming an unknown one)."""
    if not only:
        return paper.claims
    ids = {c.id for c in paper.claims}
    bad = [c for c in only if c not in ids]
    if bad:
        raise KeyError(f"{paper.key} has no claim {bad[0]!r} (claims: {', '.join(sorted(ids))})")
    return tuple(c for c in paper.claims if c.id in set(only))


def reproduce(
    paper: str | Paper,
    scale: str,
    out: str | Path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    resume: bool = False,
    only: Sequence[str] = (),
    runs: int | None = None,
    sets: Sequence[str] = (),
    command: str = "",
    progress: Callable[[Unit, int, int], None] | None = None,
) -> Reproduction:
    """Run (or, with ``resume``, finish) ``paper``'s claims at ``scale`` ("quick" | "full") into
    ``out`` and write ``claims.csv`` and ``index.html`` there. ``only``: claim ids; ``runs``:
    seeds per quantity instead of the scale's; ``sets``: ``--set`` overrides on every run."""
    p = PAPERS[paper] if isinstance(paper, str) else paper
    sc: Scale = getattr(p, scale)
    claims = select(p, only)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    units = plan_units(p, sc, claims, runs=runs, sets=sets)
    rows = run_units(units, out, workers=workers, scheduler=scheduler, resume=resume, progress=progress)
    results = evaluate_claims(p, sc, claims, rows, units, sets=sets)
    table = claims_table(p, results)
    write_csv(table, out / "claims.csv")
    (out / "claims.md").write_text(markdown(table))
    write_html(p, scale, sc, table, command, out / "index.html")
    wall = time.perf_counter() - t0
    info = {
        "paper": p.key,
        "scale": scale,
        "command": command,
        "runs_per_quantity": units[0].runs if units else 0,
        "sets": list(sets),
        "only": list(only),
        "units": [
            {"name": u.name, "scenario": u.scenario.name, "overrides": list(u.overrides), "variants": list(u.variants)}
            for u in units
        ],
        "wall_time_s": wall,  # of this invocation (a resumed one: the part run now)
        "verdicts": table["verdict"].value_counts().to_dict(),
    }
    (out / "reproduce.json").write_text(json.dumps(info, indent=2) + "\n")
    return Reproduction(p, scale, units, table, wall)
