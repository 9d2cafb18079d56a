"""docs/traces.md against the code: the kernel tables' columns are the schema's, in order, and
the columns and tables the built-in protocols write (their contract cases, test_contract.CASES,
plus a tracking case of Ramezani's) are the documented ones, both ways."""

from __future__ import annotations

import functools
import re
from pathlib import Path

import pandas as pd
from test_contract import CASES, SCENARIOS  # tests/protocols, beside this file

from aquasim_py import scenario
from aquasim_py.estimate_bounds import applied_range_noise, estimate_bounds
from aquasim_py.trace import SCHEMAS

DOC = Path(__file__).resolve().parents[2] / "docs" / "traces.md"
#: the marked section whose columns another environment writes (absent from these runs)
RANGE_DEPENDENT = "range-dependent environment only"
#: cases beyond the contract's, for columns its tiny runs do not reach
EXTRA_CASES = {"ramezani#tracking": ("ramezani_tracking.toml", ["simulation.duration_s=60.0"])}
#: documented tables that no run here writes, and why
RARE_TABLES = {
    "ramezani_failures": "written only when a frame's estimation fails",
}
KERNEL_TABLES = ("packets", "positions", "estimates", "clocks", "nodes")


def _sections() -> list[tuple[str, str, tuple[str, ...], list[str]]]:
    """(table, qualifier, protocols, columns) of each documented table section: a heading
    ``## table``, ``## table, qualifier`` or ``### table: proto, proto``; its columns are the
    first cells of the markdown table under it."""
    out: list[tuple[str, str, tuple[str, ...], list[str]]] = []
    cols: list[str] | None = None
    for line in DOC.read_text().splitlines():
        head = re.match(r"#{2,3} (.*)", line)
        if head:
            title = head.group(1).replace("`", "")
            name, _, protos = title.partition(":")
            table, _, qualifier = name.partition(",")
            cols = None
            if re.fullmatch(r"[a-z_]+", table.strip()):
                cols = []
                out.append(
                    (table.strip(), qualifier.strip(), tuple(p.strip() for p in protos.split(",") if p.strip()), cols)
                )
            continue
        cell = re.match(r"\| `([A-Za-z0-9_]+)` \|", line)
        if cell and cols is not None:
            cols.append(cell.group(1))
    return out


@functools.cache
def _written() -> dict[str, dict[str, set[str]]]:
    """table -> protocol -> the columns of that table in the runs where the protocol wrote
    rows to it (every table of the run, written or not; "" for tables without a protocol)."""
    out: dict[str, dict[str, set[str]]] = {}
    for file, overrides in {**CASES, **EXTRA_CASES}.values():
        file, _, variant = file.partition("#")
        sc = scenario.load(SCENARIOS / file, overrides=overrides)
        if variant:
            sc = scenario.resolve(sc, variant=variant)
        sim = scenario.build(sc)
        sim.run(until=sc.simulation.duration_s)
        frames = sim.trace.frames()
        # the table the runner computes from the traces after a run (aquasim_py.estimate_bounds)
        bounds = estimate_bounds(frames, applied_range_noise(sc))
        if bounds is not None:
            frames["bounds"] = bounds
        for table, df in frames.items():
            if not len(df.columns):
                continue
            protos = pd.unique(df["protocol"].astype(str)) if "protocol" in df.columns else [""]
            for p in protos:
                out.setdefault(table, {}).setdefault(str(p), set()).update(df.columns)
    return out


def test_kernel_tables_are_the_schema_in_order() -> None:
    generic = {t: cols for t, q, protos, cols in _sections() if not q and not protos}
    assert set(KERNEL_TABLES) <= set(generic)
    for table, schema in SCHEMAS.items():
        assert generic[table] == [c for c, _ in schema], table
    assert set(generic["nodes"]) == set().union(*_written()["nodes"].values())


def test_every_written_column_is_documented_and_every_documented_one_written() -> None:
    sections = _sections()
    written = _written()
    documented_tables = {t for t, *_ in sections}
    assert set(written) <= documented_tables, f"undocumented tables: {sorted(set(written) - documented_tables)}"
    absent = documented_tables - set(written)
    assert absent == set(RARE_TABLES), f"documented tables no run writes: {sorted(absent - set(RARE_TABLES))}"
    problems = []
    for table, by_proto in written.items():
        for proto, cols in by_proto.items():
            allowed = {c for t, q, protos, cs in sections if t == table and (proto in protos or not protos) for c in cs}
            extra = cols - allowed
            if extra:
                problems.append(f"{table} of {proto or 'the kernel'}: undocumented {sorted(extra)}")
    for table, qualifier, protos, cols in sections:
        if qualifier == RANGE_DEPENDENT or table in RARE_TABLES:
            continue
        seen = set().union(*(c for p, c in written.get(table, {}).items() if not protos or p in protos))
        missing = set(cols) - seen
        if missing:
            problems.append(
                f"{table} ({', '.join(protos) or qualifier or 'kernel'}): documented, never written {sorted(missing)}"
            )
    assert not problems, "\n".join(problems)
