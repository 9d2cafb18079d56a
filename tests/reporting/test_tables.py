"""Tables that read right at 80 and 120 columns (issue 35 item 4)."""

from __future__ import annotations

import contextlib
import io
import json
import math
import re
from pathlib import Path

import pandas as pd
import pytest
from rich.console import Console

from aquasim_py import cli
from aquasim_py.reporting import sweep as report_sweep
from aquasim_py.reporting import tables
from aquasim_py.reporting.display import format_row

ROOT = Path(__file__).resolve().parents[2]


def _render(renderable, width: int) -> str:
    con = Console(width=width, record=True, file=io.StringIO())
    con.print(renderable)
    return con.export_text()


def _check_whole(text: str, width: int, table: tables.TextTable) -> None:
    """Every line fits, nothing is cut with an ellipsis, and every value cell of ``table``
    stands whole between two column rules."""
    lines = text.splitlines()
    assert max(map(len, lines)) <= width, max(lines, key=len)
    assert "…" not in text
    for row in table.rows:
        for cell in row[1:]:
            first = cell.split("\n")[0]
            assert re.search(rf"│ +{re.escape(first)} │", text), (row[0], first)


def test_each_variants_own_family_is_aligned_not_hidden():
    results = {
        "itmtl": {"packets.sent": 10, "itmtl.loc_rmse_m": 0.5, "itmtl.promoted_share": 0.8},
        "wsc": {"packets.sent": 11, "itmtl.loc_rmse_m": 2.1, "itmtl.promoted_share": 0.0},
        "tshl": {"packets.sent": 12, "tshl.loc_rmse_m": 2.0},
    }
    rows, own = tables.comparison_rows(results)
    assert own == {"itmtl": "itmtl", "wsc": "itmtl", "tshl": "tshl"}
    assert rows == [
        ("packets.sent", [10, 11, 12]),
        ("<protocol>.loc_rmse_m", [0.5, 2.1, 2.0]),
        ("<protocol>.promoted_share", [0.8, 0.0, None]),
    ]


def test_families_that_cannot_be_aligned_are_shown_whole():
    # two partial families in one variant: no alignment, every metric a row of its own
    results = {"a": {"x.k": 1.0, "y.k": 2.0}, "b": {"z.k": 3.0}}
    rows, own = tables.comparison_rows(results)
    assert own == {} and [r[0] for r in rows] == ["x.k", "y.k", "z.k"]
    assert rows[2] == ("z.k", [None, 3.0])


@pytest.fixture(scope="module")
def itmtl_out(tmp_path_factory):
    """A short ITMTL variants run printed at 120 and then at 80 columns (with its reports)."""
    d = tmp_path_factory.mktemp("itmtl")
    printed = {}
    mp = pytest.MonkeyPatch()
    try:
        for width in (120, 80):
            mp.setenv("COLUMNS", str(width))
            argv = [str(ROOT / "scenarios" / "itmtl.toml"), "--out", str(d / "o"), "--set", "simulation.duration_s=120"]
            argv += ["--report"] if width == 80 else []
            buf = io.StringIO()
            with contextlib.redirect_stdout(buf):
                assert cli.main(argv) == 0
            printed[width] = buf.getvalue()
    finally:
        mp.undo()
    return d / "o", printed


@pytest.mark.parametrize("width", [80, 120])
def test_the_variants_tables_fit_with_every_number_whole(itmtl_out, width):
    out, printed = itmtl_out
    text = printed[width]
    body = text[: text.rindex("output: ")]  # the lines naming paths are unbroken on purpose
    metrics = {
        d.name: json.loads((d / "summary.json").read_text())["metrics"] for d in sorted(out.iterdir()) if d.is_dir()
    }
    order = pd.read_csv(out / "variants.csv")["variant"].tolist()
    table = tables.comparison_table({v: metrics[v] for v in order}, "")
    _check_whole(body, width, table)
    # units in the labels, one value per variant in that unit: sync errors in us, not 3.05e-05 s
    label, _ = format_row("sync.mean_abs_error_s", [metrics[v]["sync.mean_abs_error_s"] for v in order])
    assert label == "sync.mean_abs_error (us)" and "mean_abs_error (us)" in body
    # each protocol's own family is there for every variant, a metric that repeats a generic
    # one printed once and the note saying so
    flat = " ".join(body.split())
    assert "<protocol>" in body and "loc_rmse_fixed (m)" in body
    assert "<protocol>.loc_rmse_m = localization.rmse_m" in flat
    assert flat.count(" rmse (m) ") == flat.count("itmtl: variants (seed")  # once a block
    # the paper table names the network; no word of it is cut
    assert "this run: 10 nodes (4 anchors, 6 ordinary)" in " ".join(body.split())
    paper = pd.read_csv(out / "paper.csv", dtype=str, keep_default_na=False)
    words = set(re.split(r"[\s│┃]+", body))
    for col in paper.columns:
        for cell in paper[col]:
            for word in cell.split():
                assert word in words, (col, word)


def test_a_sweep_table_has_n_and_the_interval_and_no_quoted_names(tmp_path):
    rows = [
        {
            "variant": variant,
            "nodes.1.params.sigma_t_s": repr(sigma),
            "run": run,
            "seed": run,
            "key": f"{variant}{sigma}{run}",
            "error": "",
            "localization.rmse_m": (1 + run) * sigma * 1e4 * (2 if variant == "wsc" else 1),
            "sync.mean_abs_error_s": (3 + run) * 1e-5,
            "packets.sent": 100 + run,
        }
        for variant in ("itmtl", "wsc")
        for sigma in (1e-5, 1e-4)
        for run in range(3)
    ]
    pd.DataFrame(rows).to_csv(tmp_path / "sweep.csv", index=False)
    data = report_sweep.load(tmp_path)
    metrics = report_sweep.select(data.metrics)
    assert metrics == ["localization.rmse_m", "sync.mean_abs_error_s"]  # packet counts only when asked
    t = tables.sweep_table(data, report_sweep.summary(data, metrics), metrics, "sw sweep")
    assert '"' not in "".join(t.header)
    assert t.header[1] == "itmtl\nsigma_t=10 us"
    assert "n = 3 runs per grid point" in t.caption
    assert t.rows[1][0] == "sync.mean_abs_error (us)"
    center, interval = t.rows[1][1].split("\n")
    assert center == "39.15" and re.fullmatch(r"\[\d+\.\d+, \d+\.\d+\]", interval)  # geometric mean of 30, 40, 50
    assert math.isclose(float(center), (30 * 40 * 50) ** (1 / 3), rel_tol=1e-3)
    for width in (80, 120):
        _check_whole(_render(t.rich(width), width), width, t)


def test_a_sweep_without_grid_keys_has_one_column(tmp_path):
    rows = [{"run": r, "seed": r, "key": str(r), "error": "", "x.rmse_m": 1.0 + r} for r in range(3)]
    pd.DataFrame(rows).to_csv(tmp_path / "sweep.csv", index=False)
    data = report_sweep.load(tmp_path)
    t = tables.sweep_table(data, report_sweep.summary(data, ["x.rmse_m"]), ["x.rmse_m"], "s")
    assert t.header == ["metric", "all runs"] and t.rows[0][0] == "x.rmse (m)"
    assert t.rows[0][1].split("\n")[0] == "1.817"  # geometric mean of 1, 2, 3


def test_a_variants_run_gets_a_cross_variant_report(itmtl_out):
    out, _ = itmtl_out
    html = (out / "report.html").read_text()
    assert "the variants side by side" in html and "&lt;protocol&gt;</th>" in html
    assert "10 nodes (4 anchors, 6 ordinary)" in html
    for v in ("itmtl", "wsc", "tshl", "mu_sync", "mobi_sync"):
        assert f'href="{v}/report.html"' in html and (out / v / "report.html").is_file()
    assert (out / "variants_error_cdf.png").is_file() and (out / "variants_sync_cdf.png").is_file()


def test_a_ratio_below_the_bound_is_flagged_and_a_repeated_metric_printed_once():
    low = {
        "localization.rmse_m": 0.4321,
        "localization.rmse_over_crb": 0.5,
        "localization.rmse_over_crb_ci95_high": 0.8,
        "itmtl.loc_rmse_m": 0.4321,
        "packets.sent": 10,
        "packets.received": 10,
    }
    high = {**low, "localization.rmse_over_crb": 0.9, "localization.rmse_over_crb_ci95_high": 1.3}
    t = tables.metrics_table(low, "run")
    rows = {r[0].strip(): r[1:] for r in t.rows}
    assert rows["rmse_over_crb"] == ["0.5000" + tables.BELOW_MARK]
    assert "rmse_over_crb_ci95_high" not in rows and "loc_rmse (m)" not in rows
    assert "received" in rows  # equal counts are not taken for one quantity
    notes = " ".join(t.notes)
    assert tables.BELOW_BOUND in notes and "itmtl.loc_rmse_m = localization.rmse_m" in notes
    c = tables.comparison_table({"a": low, "b": high}, "both")
    ratio = next(r for r in c.rows if r[0].strip() == "rmse_over_crb")
    assert ratio[1:] == ["0.5000" + tables.BELOW_MARK, "0.9000"]
    assert tables.BELOW_BOUND in " ".join(c.notes)
    assert tables.BELOW_BOUND not in " ".join(tables.metrics_table(high, "run").notes)
