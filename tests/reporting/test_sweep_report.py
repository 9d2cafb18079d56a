"""Sweep reports keep every comparison (issue 35 item 1)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from aquasim_py import cli
from aquasim_py.reporting import sweep as report_sweep

ROOT = Path(__file__).resolve().parents[2]
MODEL, SIGMA = "nodes.1.params.model", "nodes.1.params.sigma_t_s"


@pytest.fixture(scope="module")
def ramezani(tmp_path_factory) -> Path:
    """The README's Ramezani sweep (grid: model x sigma_t), two runs per point, 60 s each."""
    out = tmp_path_factory.mktemp("ram") / "sweep"
    argv = ["sweep", str(ROOT / "scenarios" / "ramezani_localization_sweep.toml"), "--out", str(out)]
    assert (
        cli.main([*argv, "--quiet", "--workers", "2", "--set", "sweep.runs=2", "--set", "simulation.duration_s=60"])
        == 0
    )
    return out


def test_essp_and_assp_are_drawn_apart(ramezani):
    data = report_sweep.load(ramezani)
    assert data.grid == {MODEL: ["essp", "assp"], SIGMA: ["1e-05", "0.0001", "0.001"]}  # scenario order
    assert report_sweep.x_keys(data) == [SIGMA]  # the numeric key along x, the other one as lines
    lines = report_sweep.lines(data, SIGMA, "localization.rmse_m")
    assert [ln.label(data) for ln in lines] == ["model=essp", "model=assp"]
    runs = data.runs
    for ln in lines:
        ((_, model),) = ln.fixed
        assert ln.x == ["1e-05", "0.0001", "0.001"] and list(ln.n) == [2, 2, 2]
        for x, center, lo, hi in zip(ln.x, ln.center, ln.low, ln.high):
            v = runs[(runs[MODEL] == model) & (runs[SIGMA] == x)]["localization.rmse_m"].to_numpy(float)
            assert center == pytest.approx(np.exp(np.log(v).mean()))  # geometric mean of its own two runs
            assert 0 < lo <= center <= hi  # an error's interval stays positive
    essp, assp = lines
    # the paper's comparison: at small timing noise the approximate profile's bias dominates
    assert assp.center[0] > 5 * essp.center[0]
    assert report_sweep.is_log_spaced([1e-5, 1e-4, 1e-3])


def test_the_report_draws_the_chosen_metrics_only(ramezani, capsys):
    assert cli.main(["report", str(ramezani), "--metrics", "localization.rmse_m,*.sqrt_mean_crb_m"]) == 0
    pngs = sorted(p.name for p in ramezani.glob("sweep_*.png"))
    assert pngs == [
        f"sweep_localization.rmse_m__{SIGMA}.png",
        f"sweep_ramezani.localization_assp.sqrt_mean_crb_m__{SIGMA}.png",
        f"sweep_ramezani.localization_essp.sqrt_mean_crb_m__{SIGMA}.png",
    ]
    html = (ramezani / "report.html").read_text()
    assert "n = 2 runs per grid point" in html and "model=assp<br>sigma_t=10 us" in html
    # other metrics: the earlier plots are replaced, not left beside the new ones
    assert cli.main(["report", str(ramezani), "--metrics", "packets.sent"]) == 0
    names = {p.name for p in ramezani.glob("sweep_*.png")}
    assert names == {f"sweep_packets.sent__{SIGMA}.png"}
    assert len(re.findall(r'src="data:image/png', (ramezani / "report.html").read_text())) == 1
    # by default every metric but the packet counts
    data = report_sweep.load(ramezani)
    assert "localization.coverage" in report_sweep.select(data.metrics)
    assert not any(m.startswith("packets.") for m in report_sweep.select(data.metrics))


def test_lines_follow_every_other_key(tmp_path):
    # three keys: x = count, a line per (variant, jitter) pair, in grid order
    rows = [
        {
            "variant": v,
            "channel.jitter_std_s": j,
            "nodes.1.count": c,
            "run": 0,
            "seed": 1,
            "key": "k",
            "error": "",
            "m": c * (2 if v == "b" else 1) + j,
        }
        for v in ("b", "a")
        for j in (0.0, 0.001)
        for c in (2, 4, 8)
    ]
    pd.DataFrame(rows).to_csv(tmp_path / "sweep.csv", index=False)
    data = report_sweep.load(tmp_path)
    assert report_sweep.x_keys(data) == ["channel.jitter_std_s", "nodes.1.count"]
    lines = report_sweep.lines(data, "nodes.1.count", "m")
    assert [ln.label(data) for ln in lines] == [
        "b, jitter_std=0 ms",
        "b, jitter_std=1 ms",
        "a, jitter_std=0 ms",
        "a, jitter_std=1 ms",
    ]
    assert list(lines[0].center) == pytest.approx([4, 8, 16])
    assert report_sweep.plot(data, "nodes.1.count", "m", tmp_path / "m.png") is not None
