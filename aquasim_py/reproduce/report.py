"""``claims.csv`` and the HTML page of a reproduction: claim | paper | ours [95 % CI] under each
reading | verdict."""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from .claims import REL_TOL, Paper, Scale
from .runner import ClaimResult

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["claims_table", "markdown", "write_csv", "write_html"]

COLUMNS = [
    "paper",
    "claim",
    "figure",
    "text",
    "kind",
    "reading",
    "paper_value",
    "paper_text",
    "ours",
    "ci95_low",
    "ci95_high",
    "n",
    "a",
    "a_value",
    "b",
    "b_value",
    "statistic",
    "verdict",
]


def claims_table(paper: Paper, results: Sequence[ClaimResult]) -> pd.DataFrame:
    """One row per (claim, reading): the paper's value, ours with its CI, the verdict."""
    import pandas as pd

    rows = []
    for r in results:
        c, o = r.claim, r.outcome
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
                "ours": o.ours,
                "ci95_low": o.low,
                "ci95_high": o.high,
                "n": o.n,
                "a": c.a.name,
                "a_value": r.a_value,
                "b": c.b.name if c.b is not None else "",
                "b_value": r.b_value,
                "statistic": c.statistic,
                "verdict": o.verdict,
            }
        )
    return pd.DataFrame(rows, columns=COLUMNS)


def write_csv(table: pd.DataFrame, path: Path) -> None:
    """Write atomically (float text exact: repr round-trips)."""
    tmp = path.with_name(f".{path.name}.tmp")
    table.to_csv(tmp, index=False, lineterminator="\n", float_format=None)
    tmp.replace(path)


def _num(v: float) -> str:
    if v is None or not math.isfinite(v):
        return "-"
    return f"{v:.4g}"


def write_html(paper: Paper, scale_name: str, scale: Scale, table: pd.DataFrame, command: str, path: Path) -> None:
    """The page: one row per claim, one column per reading (ours [CI], verdict)."""
    readings = list(dict.fromkeys(table["reading"]))
    esc = html.escape
    head = "".join(f"<th>{esc(r)}</th>" for r in readings)
    body = []
    for cid, g in table.groupby("claim", sort=False):
        first = g.iloc[0]
        cells = []
        for rd in readings:
            row = g[g["reading"] == rd]
            if not len(row):
                cells.append("<td></td>")
                continue
            x = row.iloc[0]
            cls = {"holds": "ok", "does not hold": "no", "tie": "tie"}.get(str(x["verdict"]), "")
            cells.append(
                f'<td class="{cls}">{_num(x["ours"])} [{_num(x["ci95_low"])}, {_num(x["ci95_high"])}]'
                f"<br><small>{esc(str(x['verdict']))}, n = {int(x['n'])}</small></td>"
            )
        paper_cell = esc(str(first["paper_text"]) or _num(first["paper_value"]))
        body.append(
            f"<tr><td><b>{esc(str(cid))}</b> ({esc(str(first['figure']))})<br>{esc(str(first['text']))}"
            f"<br><small>{esc(str(first['statistic']))}</small></td><td>{paper_cell}</td>{''.join(cells)}</tr>"
        )
    rdesc = "".join(f"<li><b>{esc(r.name)}</b>: {esc(r.description)}</li>" for r in paper.readings)
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
<p>Ours: the statistic over seeds with its 95 % confidence interval. Verdicts: an ordering
holds when the CI of the paired difference excludes 0 on the paper's side; a number holds when
the CI lies within +-{REL_TOL:.0%} of the paper's, does not when it lies wholly outside, tie otherwise.
The project's reconstruction of the paper: {esc(paper.doc)}.</p>
<h2>Readings</h2><ul>{rdesc}</ul>
<table><tr><th>claim</th><th>paper</th>{head}</tr>
{"".join(body)}
</table></body></html>
"""
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(page, encoding="utf-8")
    tmp.replace(path)


def markdown(table: pd.DataFrame) -> str:
    """The claims as a markdown table (one row per claim and reading), for the docs."""
    lines = [
        "| claim | where | reading | paper | ours [95 % CI] | n | verdict |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in table.itertuples():
        paper = str(r.paper_text) if isinstance(r.paper_text, str) and r.paper_text else _num(float(r.paper_value))
        ours = f"{_num(float(r.ours))} [{_num(float(r.ci95_low))}, {_num(float(r.ci95_high))}]"
        verdict = f"**{r.verdict}**" if r.verdict in ("holds", "does not hold") else str(r.verdict)
        lines.append(f"| {r.claim}: {r.text} | {r.figure} | {r.reading} | {paper} | {ours} | {r.n} | {verdict} |")
    return "\n".join(lines) + "\n"
