"""The sweep report's routing page: a panel per routing metric the sweep has, against its first
numeric key, a line per protocol; none for a sweep without routing metrics."""

from __future__ import annotations

import pandas as pd
import pytest

from aquasim_py import cli
from aquasim_py.reporting import routing
from aquasim_py.reporting import sweep as report_sweep


def _sweep(tmp_path, metrics):
    rows = [
        {
            "variant": v,
            "nodes.1.count": c,
            "run": r,
            "seed": r,
            "key": f"{v}{c}{r}",
            "error": "",
            **dict.fromkeys(metrics, c / 500 * (1.0 if v == "flooding" else 0.8) + 0.01 * r),
        }
        for v in ("flooding", "dbr")
        for c in (86, 286, 486)
        for r in range(3)
    ]
    pd.DataFrame(rows).to_csv(tmp_path / "sweep.csv", index=False)
    return report_sweep.load(tmp_path)


def test_a_panel_per_routing_metric_and_a_line_per_protocol(tmp_path, monkeypatch):
    data = _sweep(tmp_path, ["net.pdr", "net.delay_s", "energy.per_delivered_j"])
    drawn = []
    real = routing.plt.subplots

    def spy(*a, **kw):  # keep the axes the page draws on
        fig, axes = real(*a, **kw)
        drawn.append(axes)
        return fig, axes

    monkeypatch.setattr(routing.plt, "subplots", spy)
    p = routing.routing_plot(data, tmp_path / "r.png")
    assert p is not None and p.is_file()
    axes = drawn[0][0]
    assert [ax.get_ylabel() for ax in axes] == [label for _, label in routing.PANELS]
    assert all(ax.get_xlabel() == "nodes.1.count" for ax in axes)
    for ax in axes:
        assert ax.get_legend_handles_labels()[1] == ["flooding", "dbr"]


def test_no_page_without_routing_metrics_and_the_report_links_it(tmp_path):
    data = _sweep(tmp_path, ["net.throughput"])
    assert routing.routing_plot(data, tmp_path / "r.png") is None
    _sweep(tmp_path, ["net.pdr", "net.delay_s"])
    assert cli.main(["report", str(tmp_path)]) == 0
    assert (tmp_path / "sweep_net_routing_vs_density.png").is_file()
    assert "sweep_net_routing_vs_density.png" in (tmp_path / "report.html").read_text()


def test_only_the_panels_the_sweep_has(tmp_path, monkeypatch):
    data = _sweep(tmp_path, ["net.pdr"])
    drawn = []
    real = routing.plt.subplots
    monkeypatch.setattr(routing.plt, "subplots", lambda *a, **kw: drawn.append(kw) or real(*a, **kw))
    assert routing.routing_plot(data, tmp_path / "r.png") is not None
    assert drawn[0]["figsize"][0] == pytest.approx(4.6)  # one panel


def test_a_point_of_few_runs_does_not_flatten_the_lines(tmp_path, monkeypatch):
    data = _sweep(tmp_path, ["net.pdr", "net.delay_s"])
    runs = data.runs
    # one sparse run that delivered one packet after a long wait: its point's interval is huge
    runs.loc[(runs["variant"] == "dbr") & (runs["nodes.1.count"] == 86) & (runs["run"] == 0), "net.delay_s"] = 500.0
    drawn = []
    real = routing.plt.subplots
    monkeypatch.setattr(routing.plt, "subplots", lambda *a, **kw: drawn.append(real(*a, **kw)) or drawn[-1])
    routing.routing_plot(data, tmp_path / "r.png")
    pdr_ax, delay_ax = drawn[0][1][0]
    assert pdr_ax.get_ylim() == (0.0, 1.05)
    means = runs.groupby(["variant", "nodes.1.count"])["net.delay_s"].mean()
    # the axis holds every mean, and the outlying point's bar runs off it (at most 2 x the top mean)
    assert delay_ax.get_ylim()[0] == 0.0
    assert means.max() < delay_ax.get_ylim()[1] <= 1.05 * 2 * means.max() + 1e-9
