"""``claims.csv``, ``claims.md`` and the HTML page of a reproduction: claim | paper | ours
[95 % CI] under each reading | verdict, every number in its unit
(:mod:`aquasim_py.reporting.display`), with n and the statistic beside it."""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from aquasim_py.reporting.display import Unit, format_in, unit_of

from .claims import MIN_RUNS, REL_TOL, Paper, Scale
from .runner import ClaimResult

if TYPE_CHECKING:
    import pandas as pd

__all__ = [
    "claims_table",
    "markdown",
    "number_unit",
    "ours_text",
    "short_statistic",
    "wording",
    "write_csv",
    "write_html",
]

COLUMNS = [
    "paper",
    "claim",
    "figure",
    "text",
    "kind",
    "reading",
    "paper_value",
    "paper_text",
    "paper_runs",
    "unit",
    "ours",
    "ci95_low",
    "ci95_high",
    "paper_in_ci",
    "pi95_low",
    "pi95_high",
    "paper_in_pi",
    "n",
    "a",
    "a_metric",
    "a_overrides",
    "a_value",
    "b",
    "b_metric",
    "b_overrides",
    "b_value",
    "statistic_of_runs",
    "reduce",
    "statistic",
    "verdict",
    "flag",
]

_STAT_NAMES = {"mean": "means", "rms": "RMS", "time_mean_rms": "eq-37 RMSEs", "interval_mean": "per-round means"}
_REDUCE = {"max": "largest over rounds of the ", "median": "median over rounds of the "}


def number_unit(kind: str, metric: str, values: Sequence[Any] = ()) -> Unit:
    """How a claim's number prints: the unit of its metric (a difference of metrics has the
    metric's unit), % for a gap, none for a ratio."""
    if kind == "gap_pct":
        return unit_of("gap_pct")
    if kind == "ratio":
        return Unit("ratio")
    return unit_of(metric.rsplit(".", 1)[-1], values)


def short_statistic(kind: str, statistic: str, n: int, reduce: str = "") -> str:
    """What the number is, in a few words: "paired difference of means, n = 100"."""
    s = _STAT_NAMES.get(statistic, statistic)
    if isinstance(reduce, str) and reduce:
        kind = f"{reduce}_{kind}"
    what = {
        "value": s if statistic != "mean" else "mean",
        "reference": s if statistic != "mean" else "mean",
        "less": f"paired difference of {s}",
        "gap_pct": f"gap between {s}",
        "ratio": f"ratio of {s}",
        "max_gap_pct": f"{_REDUCE['max']}gap between {s}",
        "median_gap_pct": f"{_REDUCE['median']}gap between {s}",
    }.get(kind, s)
    return f"{what}, n = {n}"


def claims_table(paper: Paper, results: Sequence[ClaimResult]) -> pd.DataFrame:
    """One row per (claim, reading): the paper's value, ours with its CI (and the prediction
    interval of one run where the paper's number is one run), the verdict and its flag."""
    import pandas as pd

    rows = []
    for r in results:
        c, o = r.claim, r.outcome
        u = number_unit(c.kind, r.a_metric, [o.ours, o.low, o.high])
        rows.append(
            {
                "paper": paper.key,
                "claim": c.id,
                "figure": c.figure,
                "text": c.text,
                "kind": c.kind,
                "reading": r.reading.name,
                "paper_value": c.paper if c.paper is not None else math.nan,
                "paper_text": c.paper_text,
                "paper_runs": c.paper_runs,
                "unit": {"": "", "us": "s", "ns": "s", "ms": "s"}.get(u.unit, u.unit),
                "ours": o.ours,
                "ci95_low": o.low,
                "ci95_high": o.high,
                "paper_in_ci": _yes_no(o.paper_in_ci),
                "pi95_low": o.pi_low,
                "pi95_high": o.pi_high,
                "paper_in_pi": _yes_no(o.paper_in_pi),
                "n": o.n,
                "a": c.a.name,
                "a_metric": r.a_metric,
                "a_overrides": " ".join(r.a_overrides),
                "a_value": r.a_value,
                "b": c.b.name if c.b is not None else "",
                "b_metric": r.b_metric,
                "b_overrides": " ".join(r.b_overrides),
                "b_value": r.b_value,
                "statistic_of_runs": r.a_statistic,
                "reduce": c.reduce,
                "statistic": c.statistic,
                "verdict": o.verdict,
                "flag": o.flag,
            }
        )
    return pd.DataFrame(rows, columns=COLUMNS)


def _yes_no(v: bool | None) -> str:
    return "" if v is None else "yes" if v else "no"


def write_csv(table: pd.DataFrame, path: Path) -> None:
    """Write atomically (float text exact: repr round-trips)."""
    tmp = path.with_name(f".{path.name}.tmp")
    table.to_csv(tmp, index=False, lineterminator="\n", float_format=None)
    tmp.replace(path)


def _unit(row: Any) -> Unit:
    return number_unit(str(row.kind), str(row.a_metric), [row.ours, row.ci95_low, row.ci95_high, row.paper_value])


def _fmt(u: Unit, v: Any) -> str:
    return format_in(u, v, 3) if v is not None and not (isinstance(v, float) and math.isnan(v)) else "-"


def ours_text(row: Any) -> str:
    """``-18.6 us [-21.5, -15.6]`` (and ``; one run: [lo, hi]`` where the paper's number is
    one run)."""
    u = _unit(row)
    unit = f" {u.unit}" if u.unit else ""
    s = f"{_fmt(u, row.ours)}{unit} [{_fmt(u, row.ci95_low)}, {_fmt(u, row.ci95_high)}]"
    if isinstance(row.pi95_low, float) and math.isfinite(row.pi95_low):
        s += f"; one run: [{_fmt(u, row.pi95_low)}, {_fmt(u, row.pi95_high)}]"
    return s


def paper_text(row: Any) -> str:
    """The paper's number as it states it, else in our unit."""
    if isinstance(row.paper_text, str) and row.paper_text:
        return row.paper_text
    u = _unit(row)
    return f"{_fmt(u, row.paper_value)} {u.unit}".strip() if math.isfinite(float(row.paper_value)) else "-"


def wording(row: Any) -> str:
    """The verdict in words, with where the paper's number lies against our interval and the
    flag: "holds, but the paper's number is outside our CI"."""
    v = str(row.verdict)
    parts = [v]
    if row.paper_in_pi in ("yes", "no"):
        parts = [
            f"{v}: the paper's run is {'inside' if row.paper_in_pi == 'yes' else 'outside'} our 95 % PI of one run"
        ]
    elif row.paper_in_ci == "yes":
        parts = [f"{v}, the paper's number inside our CI"]
    elif row.paper_in_ci == "no" and v != "does not hold":
        parts = [f"{v}, but the paper's number is outside our CI"]
    if isinstance(row.flag, str) and row.flag:
        parts.append(row.flag)
    return "; ".join(parts)


def _rows(table: pd.DataFrame) -> list[Any]:
    return list(table.itertuples())


def write_html(
    paper: Paper, scale_name: str, scale: Scale, table: pd.DataFrame, command: str, path: Path, plot: str | None = None
) -> None:
    """The page: one row per claim, one column per reading (ours [CI] in its unit, n and the
    statistic, the verdict in words), and the plot of the claims."""
    readings = list(dict.fromkeys(table["reading"]))
    esc = html.escape
    head = "".join(f"<th>{esc(r)}</th>" for r in readings)
    body = []
    for cid, g in table.groupby("claim", sort=False):
        first = next(iter(g.itertuples()))
        cells = []
        for rd in readings:
            row = g[g["reading"] == rd]
            if not len(row):
                cells.append("<td></td>")
                continue
            x = next(iter(row.itertuples()))
            cls = {"holds": "ok", "does not hold": "no", "inconclusive": "tie"}.get(str(x.verdict), "")
            cells.append(
                f'<td class="{cls}">{esc(ours_text(x))}<br><small>{esc(short_statistic(x.kind, x.statistic_of_runs, x.n, x.reduce))}'
                f"</small><br>{esc(wording(x))}</td>"
            )
        body.append(
            f"<tr><td><b>{esc(str(cid))}</b> ({esc(str(first.figure))})<br>{esc(str(first.text))}"
            f"<br><small>{esc(str(first.statistic))}</small></td><td>{esc(paper_text(first))}</td>{''.join(cells)}</tr>"
        )
    rdesc = "".join(f"<li><b>{esc(r.name)}</b>: {esc(r.description)}</li>" for r in paper.readings)
    img = f'<p><img src="{esc(plot)}" alt="the claims: the paper\'s number and ours with its CI"></p>' if plot else ""
    page = f"""<!doctype html>
<html><head><meta charset="utf-8"><title>{esc(paper.title)}: reproduction ({scale_name})</title>
<style>
body {{ font-family: sans-serif; margin: 2em; max-width: 90em; }}
table {{ border-collapse: collapse; }} td, th {{ border: 1px solid #bbb; padding: 0.4em; vertical-align: top; }}
td.ok {{ background: #e3f6e3; }} td.no {{ background: #f8e0e0; }} td.tie {{ background: #f4f1dc; }}
</style></head><body>
<h1>{esc(paper.title)}</h1>
<p>Scale: <b>{esc(scale_name)}</b>, {scale.runs} seeds per quantity. {esc(scale.note)}</p>
<p>Made by: <code>{esc(command)}</code></p>
<p>{esc(RULES)} The project's reconstruction of the paper: {esc(paper.doc)}.</p>
<h2>Readings</h2><ul>{rdesc}</ul>
{img}
<table><tr><th>claim</th><th>paper</th>{head}</tr>
{"".join(body)}
</table></body></html>
"""
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(page, encoding="utf-8")
    tmp.replace(path)


RULES = (
    "Ours: the statistic over seeds with its 95 % confidence interval. An ordering holds when the CI "
    "of the paired difference excludes 0 on the paper's side; a number holds when the CI lies within "
    f"+-{REL_TOL:.0%} of the paper's, does not when it lies wholly outside, and is inconclusive otherwise; "
    "where the paper's number is one example run, it holds inside our 95 % prediction interval of one run. "
    f"Fewer than {MIN_RUNS} runs give no verdict (too few runs)."
)


def markdown(table: pd.DataFrame) -> str:
    """The claims as a markdown table (one row per claim and reading), for the docs."""
    lines = [
        "| claim | where | reading | paper | ours [95 % CI] | statistic | verdict |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in _rows(table):
        verdict = wording(r)
        if r.verdict in ("holds", "does not hold"):
            verdict = f"**{r.verdict}**" + verdict[len(str(r.verdict)) :]
        stat_text = short_statistic(r.kind, r.statistic_of_runs, r.n, r.reduce)
        lines.append(
            f"| {r.claim}: {r.text} | {r.figure} | {r.reading} | {paper_text(r)} | {ours_text(r)} | {stat_text} | {verdict} |"
        )
    return "\n".join(lines) + "\n"
