"""Every PNG of the reports a user makes first, at full scale (slow): ``aquasim-py
scenarios/itmtl.toml --report`` (seven variants, 600 s), a sweep of itmtl.toml over three grid
keys and ``report --link`` on slope.toml. conftest.py checks each figure as it is saved: every
labelled series visible (identical data noted "coincides with"), no legend over data or
titles, no tick labels over each other. The default suite checks the same on shorter runs
(test_tables, test_sweep_report, test_environment_plot)."""

from __future__ import annotations

from pathlib import Path

import pytest

from aquasim_py import cli

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"

pytestmark = pytest.mark.slow

GRID = """
[sweep]
runs = 3
grid = { variant = ["itmtl", "wsc", "tshl", "mu_sync"], "channel.jitter_std_s" = [2e-6, 2e-5, 2e-4], "nodes.1.sensors.depth_noise_std_m" = [0.1, 1.0] }
"""


def test_the_itmtl_report(tmp_path: Path, checked_figures: list[str]) -> None:
    out = tmp_path / "itmtl"
    assert cli.main([str(SCENARIOS / "itmtl.toml"), "--out", str(out), "--quiet", "--report"]) == 0
    names = {Path(p).name for p in checked_figures}
    assert {"variants_error_cdf.png", "variants_sync_cdf.png", "map.png", "packets.png"} <= names
    assert len(checked_figures) == 2 + 7 * 5  # the two CDFs, five plots per variant


def test_a_three_key_sweep_report(tmp_path: Path, checked_figures: list[str]) -> None:
    scen = tmp_path / "itmtl_grid.toml"
    scen.write_text((SCENARIOS / "itmtl.toml").read_text().replace("duration_s = 600.0", "duration_s = 300.0") + GRID)
    out = tmp_path / "sweep"
    assert cli.main(["sweep", str(scen), "--out", str(out), "--quiet", "--workers", "2", "--report"]) == 0
    assert len(checked_figures) >= 2 * 10  # each metric against both numeric keys


def test_report_link_on_slope(tmp_path: Path, checked_figures: list[str]) -> None:
    out = tmp_path / "slope"
    assert cli.main([str(SCENARIOS / "slope.toml"), "--out", str(out), "--quiet"]) == 0
    assert cli.main(["report", str(out), "--link", "4,6"]) == 0
    assert sum(Path(p).name == "environment.png" for p in checked_figures) == 2  # one per variant
