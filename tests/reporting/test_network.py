"""The sweep report's throughput against offered load: points per grid point, the theory curves."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from aquasim_py.reporting import network
from aquasim_py.reporting import sweep as sweep_report


def test_aloha_throughput_formulas():
    assert network.aloha_throughput(np.array([0.5]))[0] == pytest.approx(0.5 * math.exp(-1.0))
    assert network.aloha_throughput(np.array([1.0]), slotted=True)[0] == pytest.approx(math.exp(-1.0))


def _write_sweep(directory, throughput):
    """A sweep.csv of three runs per grid point: ``throughput`` maps a variant to its (rate, G,
    S) points; run k's throughput is S (1 + 0.001 (k - 1)), so the runs' mean is S."""
    rows = [
        {
            "variant": variant,
            "rate": rate,
            "run": run,
            "seed": run,
            "key": "k",
            "error": "",
            "net.offered_load": g,
            "net.throughput": s * (1 + 0.001 * (run - 1)),
        }
        for variant, points in throughput.items()
        for rate, g, s in points
        for run in range(3)
    ]
    pd.DataFrame(rows).to_csv(directory / "sweep.csv", index=False)


def test_points_are_the_runs_means_and_the_plot_is_written(tmp_path):
    s = network.aloha_throughput
    _write_sweep(
        tmp_path,
        {
            v: [(r, g, s(np.array([g]), slotted=v == "slotted")[0]) for r, g in ((0.001, 0.1), (0.005, 0.5))]
            for v in ("pure", "slotted")
        },
    )
    data = sweep_report.load(tmp_path)
    pts = network.load_points(data)
    assert len(pts) == 4 and (pts["n"] == 3).all()
    pure = pts[(pts["variant"] == "pure") & (pts["rate"] == "0.005")].iloc[0]
    assert pure["s"] == pytest.approx(0.5 * math.exp(-1.0))
    assert pure["s_low"] < pure["s"] < pure["s_high"]
    assert network.throughput_plot(data, tmp_path / "s.png").is_file()


def test_no_network_metrics_no_plot(tmp_path):
    pd.DataFrame(
        {"x": [1, 2], "run": [0, 0], "seed": [0, 0], "key": ["a", "b"], "error": ["", ""], "m": [1.0, 2.0]}
    ).to_csv(tmp_path / "sweep.csv", index=False)
    assert network.throughput_plot(sweep_report.load(tmp_path), tmp_path / "s.png") is None


def test_lines_meeting_at_light_load_each_show(tmp_path, checked_figures):
    """Six MACs whose points share a place at light load (S = G there): each its own hollow
    marker shape, so that every one shows; the figure passes the checks conftest.py runs."""
    macs = ("aloha", "slotted_aloha", "csma", "sfama", "tdma", "direct")
    pure = network.aloha_throughput(np.array([0.5, 2.0]))
    points = {
        m: [(0.001, 0.1, 0.1), (0.005, 0.5, pure[0] * (1 + 0.3 * i)), (0.02, 2.0, pure[1] * (1 + 0.3 * i))]
        for i, m in enumerate(macs)
    }
    _write_sweep(tmp_path, points)
    drawn = []
    save = network.save_figure

    def keep(fig, path):
        drawn.append(fig)
        return save(fig, path)

    with pytest.MonkeyPatch.context() as m:
        m.setattr(network, "save_figure", keep)
        assert network.throughput_plot(sweep_report.load(tmp_path), tmp_path / "s.png").is_file()
    (ax,) = drawn[0].axes
    points = [c.lines[0] for c in ax.containers]
    assert len(points) == 6 and len({p.get_marker() for p in points}) == 6
    assert all(p.get_markerfacecolor() == "none" for p in points)
    assert checked_figures == [str(tmp_path / "s.png")]
