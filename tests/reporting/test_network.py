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


def test_points_are_the_runs_means_and_the_plot_is_written(tmp_path):
    rows = []
    for variant in ("pure", "slotted"):
        for rate, g in ((0.001, 0.1), (0.005, 0.5)):
            for run in range(3):
                s = network.aloha_throughput(np.array([g]), slotted=variant == "slotted")[0] + 0.001 * (run - 1)
                rows.append(
                    {
                        "variant": variant,
                        "rate": rate,
                        "run": run,
                        "seed": run,
                        "key": "k",
                        "error": "",
                        "net.offered_load": g,
                        "net.throughput": s,
                    }
                )
    pd.DataFrame(rows).to_csv(tmp_path / "sweep.csv", index=False)
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
