"""The tables a run, a variants run and a sweep print (terminal) and show (report.html).

Each builder returns a :class:`~aquasim_py.reporting.display.TextTable` of formatted text (units per
metric, four significant digits), rendered by the CLI in blocks that fit the terminal and by
the reports as HTML, so both show the same numbers.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from aquasim_py.reporting.display import (
    TextTable,
    describe_network,
    fits,
    format_in,
    format_row,
    label,
    text_widths,
    unit_of,
)

__all__ = [
    "BELOW_BOUND",
    "below_bound",
    "comparison_rows",
    "comparison_table",
    "grouped",
    "metrics_table",
    "paper_table",
    "paper_title",
    "sweep_table",
]

#: the row label of a metric of each variant's own protocol family (see comparison_rows)
OWN = "<protocol>"


def _reported(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


#: the note beside a ratio to a bound whose interval lies wholly below 1
BELOW_BOUND = "below the bound: check the bound's assumptions"
#: the mark on such a ratio's cell
BELOW_MARK = " <"
#: metrics kept in the files but not printed as rows (what they say is shown another way)
_HIDDEN = ("localization.rmse_over_crb_ci95_high",)


def below_bound(metrics: Mapping[str, Any]) -> bool:
    """Whether a run's ``localization.rmse_over_crb`` is below 1 beyond its 95 % interval (the
    interval's upper end, ``..._ci95_high``, under 1): an error smaller than the bound allows,
    so one of the bound's assumptions does not hold (the noise model, one-shot fixes)."""
    high = metrics.get("localization.rmse_over_crb_ci95_high")
    return bool(_reported(high) and float(high or 0.0) < 1.0)


def metrics_table(metrics: Mapping[str, Any], title: str) -> TextTable:
    """One run's metrics: a row per metric, its value in the metric's unit, grouped by family
    (:func:`grouped`); a metric equal to one above it is not repeated (a note says so)."""
    rows, same = _distinct([(k, [v]) for k, v in metrics.items() if k not in _HIDDEN])
    body = [[name, *cells] for name, cells in (_cells(k, vals, [metrics]) for k, vals in rows)]
    table = TextTable(title, ["metric", "value"], *grouped(body))
    table.notes += _notes(same, [metrics])
    return table


def _cells(name: str, values: Sequence[Any], runs: Sequence[Mapping[str, Any]]) -> tuple[str, list[str]]:
    """A row's label and cells, a ratio to a bound marked where it is below it (:func:`below_bound`)."""
    shown, cells = format_row(name, values)
    if name == "localization.rmse_over_crb":
        cells = [c + BELOW_MARK if below_bound(m) else c for c, m in zip(cells, runs)]
    return shown, cells


def _notes(same: Mapping[str, list[str]], runs: Sequence[Mapping[str, Any]]) -> list[str]:
    out = []
    if same:
        pairs = "; ".join(f"{' = '.join(names)} = {kept}" for kept, names in same.items())
        out.append(f"equal, printed once: {pairs}")
    if any(below_bound(m) for m in runs):
        out.append(f"{BELOW_MARK.strip()} rmse_over_crb: {BELOW_BOUND} (its 95 % interval lies below 1)")
    return out


def _distinct(rows: Sequence[tuple[str, list[Any]]]) -> tuple[list[tuple[str, list[Any]]], dict[str, list[str]]]:
    """``rows`` without those whose values repeat an earlier row's exactly (the same quantity
    under two names: a protocol's ``loc_rmse_m`` and ``localization.rmse_m``), and kept name ->
    the names left out for it. Only rows of fractional numbers are compared (counts and 0 / 1
    coincide too easily)."""
    seen: dict[tuple[Any, ...], str] = {}
    kept: list[tuple[str, list[Any]]] = []
    same: dict[str, list[str]] = {}
    for name, values in rows:
        key = tuple(float(v) if _reported(v) else None for v in values)
        fractional = any(x is not None and x != round(x) for x in key)
        if fractional and key in seen:
            same.setdefault(seen[key], []).append(name)
            continue
        if fractional:
            seen[key] = name
        kept.append((name, values))
    return kept, same


def grouped(rows: Sequence[list[str]]) -> tuple[list[list[str]], set[int]]:
    """Rows labelled ``family.rest`` as sections: a heading row per family (its index in the
    returned set) and each row labelled ``rest`` under it, so that the label column holds no
    prefix that repeats (a narrower table)."""
    out: list[list[str]] = []
    heads: set[int] = set()
    current = None
    for r in rows:
        fam, dot, rest = r[0].partition(".")
        if not dot:
            fam, rest = "", r[0]
        if fam != current:
            current = fam
            if fam:
                heads.add(len(out))
                out.append([fam, *([""] * (len(r) - 1))])
        out.append([f"  {rest}" if fam else rest, *r[1:]])
    return out, heads


def comparison_rows(results: Mapping[str, Mapping[str, Any]]) -> tuple[list[tuple[str, list[Any]]], dict[str, str]]:
    """The rows of a comparison of runs (variant -> metrics): ``(metric, value per variant)``.

    Families (a metric name's first part) that every variant reports give their metrics as
    they are. A family only some variants report (each protocol's own: ``itmtl.*``,
    ``tshl.*``) is not hidden: when every variant reports at most one such family, its
    metrics are aligned by the rest of the name under ``<protocol>.rest`` (each variant's
    value from its own family; the second value returned says which family that is per
    variant); otherwise each such metric is a row of its own, ``-`` where a variant lacks it.
    Metrics no variant reports as a finite number are left out."""
    names = list(results)
    fams: dict[str, set[str]] = {
        v: {k.split(".", 1)[0] for k, x in m.items() if _reported(x) and "." in k} for v, m in results.items()
    }
    every = set.intersection(*fams.values()) if fams else set()
    partial = {v: sorted(f - every) for v, f in fams.items()}
    merge = all(len(p) <= 1 for p in partial.values()) and sum(1 for p in partial.values() if p) >= 2
    own = {v: p[0] for v, p in partial.items() if p} if merge else {}
    order: dict[str, None] = {}
    for m in results.values():
        for k, x in m.items():
            if _reported(x):
                order[k] = None
    rows: list[tuple[str, list[Any]]] = []
    merged: dict[str, list[Any]] = {}
    for k in order:
        fam, _, rest = k.partition(".")
        if merge and rest and fam not in every:
            if rest not in merged:
                merged[rest] = [results[v].get(f"{own[v]}.{rest}") if v in own else None for v in names]
            continue
        rows.append((k, [results[v].get(k) for v in names]))
    rows += [(f"{OWN}.{rest}", vals) for rest, vals in merged.items()]
    return rows, own


def comparison_table(results: Mapping[str, Mapping[str, Any]], title: str) -> TextTable:
    """Variants side by side (variant -> metrics), a row per metric (:func:`comparison_rows`),
    grouped by family; a row whose values repeat another's is printed once (a note names both)."""
    rows, own = comparison_rows(results)
    rows, same = _distinct([(k, v) for k, v in rows if k not in _HIDDEN])
    runs = list(results.values())
    body = [[shown, *cells] for shown, cells in (_cells(name, values, runs) for name, values in rows)]
    caption = None
    if own:
        caption = f"{OWN}: each variant's own metrics (" + ", ".join(f"{v}: {f}.*" for v, f in own.items()) + ")"
    table = TextTable(title, ["metric", *results], *grouped(body), caption=caption)
    table.notes += _notes(same, runs)
    return table


def paper_table(paper: Any, title: str, width: int | None = None) -> Any:
    """The paper's claims beside this run (a DataFrame: figure, quantity, statistic, ours,
    paper) for a terminal of ``width`` columns: a table when its columns fit with every word
    whole, else one block per claim (no word is cut either way)."""
    from rich.console import Group
    from rich.table import Table

    cols = {("ours (this run)" if c == "ours" else str(c)): [_text(v) for v in paper[c]] for c in paper.columns}
    if width is None or fits(cols, width):
        t = Table(title=title, title_justify="left")
        for c, w in zip(cols, text_widths(cols, width)):
            t.add_column(c, overflow="fold", width=w)
        for i in range(len(paper)):
            t.add_row(*(cols[c][i] for c in cols))
        return t
    blocks: list[Any] = []
    head = [c for c in cols if c in ("figure", "quantity")]
    for i in range(len(paper)):
        t = Table.grid(padding=(0, 1))
        t.add_column(no_wrap=True, style="bold")
        t.add_column()
        name = " - ".join(cols[c][i] for c in head if cols[c][i])
        for c in cols:
            if c not in head and cols[c][i]:
                t.add_row(c, cols[c][i])
        blocks.append(Group(f"[bold]{name}[/bold]" if name else "", t))
    return Group(f"[italic]{title}[/italic]", *blocks)


def _text(v: Any) -> str:
    return "" if v is None or (isinstance(v, float) and math.isnan(v)) else str(v)


def paper_title(sc: Any, citations: Sequence[str]) -> str:
    """The paper table's title: which paper, and the network of this run."""
    paper = "; ".join(citations) if citations else "the protocol's paper"
    return f"{paper}, beside this run (same statistic; paper.csv)\nthis run: {describe_network(sc)}"


def sweep_table(data: Any, summary: Any, metrics: Sequence[str], title: str, max_points: int = 12) -> TextTable:
    """A sweep's metrics per grid point: rows = metrics, columns = grid points (the first
    ``max_points``), each cell the centre over the point's runs and below it its 95 %
    interval (``summary``: :func:`aquasim_py.reporting.sweep.summary`), and ``n=`` when the
    number of runs differs between cells (else n is in the caption)."""
    from aquasim_py.reporting.sweep import point_label

    keys = list(data.grid)
    points = list(dict.fromkeys(tuple(r) for r in data.runs[keys].itertuples(index=False))) if keys else [()]
    shown = points[:max_points]
    header = ["metric"] + [point_label(data, dict(zip(keys, p)), sep="\n") for p in shown]
    idx = summary.set_index([*keys, "metric"])
    found: list[tuple[str, list[Any]]] = []
    for metric in metrics:
        at = [(*p, metric) if keys else metric for p in shown]  # (a one-level index takes the bare name)
        got = [idx.loc[k] if k in idx.index else None for k in at]
        if any(g is not None for g in got):
            found.append((metric, got))
    ns = {int(g["n"]) for _, got in found for g in got if g is not None}
    rows = []
    for metric, got in found:
        u = unit_of(metric, [float(g["center"]) for g in got if g is not None])
        cells = []
        for g in got:
            if g is None:
                cells.append("-")
                continue
            text = format_in(u, float(g["center"]))
            if int(g["n"]) > 1:
                text += f"\n[{format_in(u, float(g['low']))}, {format_in(u, float(g['high']))}]"
            if len(ns) > 1:
                text += f"\nn={int(g['n'])}"
            cells.append(text)
        stat = next(str(g["stat"]) for g in got if g is not None)
        rows.append([label(u), *cells, stat])
    stats = {r.pop() for r in rows}
    if len(stats) > 1:  # say which statistic each row is
        rows = [[f"{r[0]}\n({s})", *r[1:]] for r, s in zip(rows, [_stat_of(summary, m) for m, _ in found])]
    caption = []
    if len(ns) == 1:
        (n,) = ns
        caption.append(f"n = {n} run{'s' * (n != 1)} per grid point")
    if stats == {"geometric mean"}:
        caption.append("each cell: geometric mean over runs [95 % CI, Student t on the log scale]")
    elif stats == {"mean"}:
        caption.append("each cell: mean over runs [95 % CI, Student t, cut at 0 for a metric never negative]")
    elif stats:
        caption.append(
            "each cell: the row's statistic over runs [95 % CI: geometric mean, Student t on the log scale; "
            "mean, Student t, cut at 0 for a metric never negative]"
        )
    if len(points) > len(shown):
        caption.append(f"first {len(shown)} of {len(points)} grid points shown; all in summary.csv")
    if data.failed:
        caption.append(f"{data.failed} failed runs left out (error column of sweep.csv)")
    return TextTable(title, header, rows, caption="; ".join(caption))


def _stat_of(summary: Any, metric: str) -> str:
    return str(summary.loc[summary["metric"] == metric, "stat"].iloc[0])
