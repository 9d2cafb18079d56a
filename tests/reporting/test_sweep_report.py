"""Sweep reports keep every comparison (issue 35 item 1)."""

from __future__ import annotations

import itertools
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from aquasim_py import cli
from aquasim_py.reporting import figures
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


def test_other_keys_become_lines_and_panels(tmp_path):
    """The key with the fewest values (at most three) gives the lines of a panel, the others
    the panels; a key with more values than that is never drawn as lines."""
    grid = {"variant": ["a", "b", "c", "d"], "x_m": ["1", "2", "4"], "noise_s": ["0.0", "0.001"], "count": ["3", "5"]}
    rows = [
        dict(zip(grid, combo), run=0, seed=1, key="k", error="", m=1.0) for combo in itertools.product(*grid.values())
    ]
    pd.DataFrame(rows).to_csv(tmp_path / "sweep.csv", index=False)
    data = report_sweep.load(tmp_path)
    lay = report_sweep.layout(data, "x_m")
    assert (lay.hue, lay.cols, lay.rows) == ("noise_s", "variant", ["count"])
    fig, panels = report_sweep.draw(data, "x_m", "m")
    assert len(panels) == 8 and set(panels) == {(v, n) for v in grid["variant"] for n in grid["count"]}
    ax = panels[("c", "5")]
    assert ax.get_title() == "c, count=5" and len(ax.containers) == 2  # one line per noise value
    # every line is the same here: the second of each panel says so once the figure is finished
    figures.finish(fig)
    assert ax.get_title() == "c, count=5\n1 ms coincides with 0 ms"
    figures.plt.close(fig)
    # four variants and nothing else: no lines of four, one panel per variant
    lay = report_sweep.layout(
        report_sweep.SweepData(data.runs, {"variant": grid["variant"], "x_m": grid["x_m"]}, ["m"]), "x_m"
    )
    assert (lay.hue, lay.cols, lay.rows) == (None, "variant", [])


THREE_KEYS = """\
[simulation]
duration_s = 20.0
seed = 5

[environment]
volume = { lo = [0.0, 0.0, 0.0], hi = [800.0, 800.0, 60.0] }

[[nodes]]
role = "anchor"
protocol = "beacon"
placement = { kind = "explicit", positions = [[0.0, 0.0, 5.0], [800.0, 800.0, 5.0]] }
params = { period_s = 4.0 }

[[nodes]]
role = "ordinary"
count = 2
protocol = "beacon"
placement = { kind = "uniform" }

[sweep]
runs = 2
grid = { "channel.jitter_std_s" = [0.0, 1e-3], "nodes.1.count" = [2, 3], "nodes.0.params.period_s" = [4.0, 8.0] }
"""


def test_a_sweep_of_three_keys_draws_what_summary_csv_holds(tmp_path, checked_figures):
    """A sweep over three grid keys: its report's plots are small multiples (every figure
    checked by conftest: every series visible, no legend over data, no tick labels over each
    other), and each point drawn is summary.csv's centre and interval."""
    scen = tmp_path / "three.toml"
    scen.write_text(THREE_KEYS)
    out = tmp_path / "sweep"
    assert cli.main(["sweep", str(scen), "--workers", "1", "--quiet", "--out", str(out)]) == 0
    assert cli.main(["report", str(out), "--metrics", "beacon.range_rmse_m,packets.received"]) == 0
    data = report_sweep.load(out)
    assert len(data.grid) == 3 and len(report_sweep.x_keys(data)) == 3
    pngs = sorted(p for p in checked_figures if p.endswith(".png"))
    assert len(pngs) == 3 * 2  # each metric against each key
    summary = pd.read_csv(out / "summary.csv", dtype=dict.fromkeys(data.grid, str))
    for metric in ("packets.received", "beacon.range_rmse_m"):
        for ln in report_sweep.lines(data, "nodes.1.count", metric):
            at = summary[summary["metric"] == metric]
            for k, v in ln.fixed:
                at = at[at[k].astype(float) == float(v)]
            for x, center, lo, hi, stat in zip(ln.x, ln.center, ln.low, ln.high, itertools.repeat(ln.stat)):
                row = at[at["nodes.1.count"].astype(float) == float(x)].iloc[0]
                assert row["center_stat"] == stat
                assert (center, lo, hi) == pytest.approx(
                    (row["center"], row["center_ci95_low"], row["center_ci95_high"]), rel=1e-12
                )


def test_a_variant_without_the_metric_gets_no_panel(tmp_path):
    """itmtl.coverage exists for ITMTL's variants only: the others draw no empty panel; a
    combination of present values without runs says so."""
    grid = {"variant": ["itmtl", "wsc", "tshl"], "x_m": ["1", "2"], "count": ["3", "5"], "noise": ["a", "b", "c", "d"]}
    rows = []
    for combo in itertools.product(*grid.values()):
        row = dict(zip(grid, combo), run=0, seed=1, key="k", error="")
        if combo[0] != "tshl" and (combo[0], combo[3]) != ("wsc", "d"):
            row["itmtl.coverage"] = 0.8
        rows.append(row)
    pd.DataFrame(rows).to_csv(tmp_path / "sweep.csv", index=False)
    data = report_sweep.load(tmp_path)
    lay = report_sweep.layout(data, "x_m")
    assert (lay.hue, lay.cols, lay.rows) == ("count", "variant", ["noise"])
    fig, panels = report_sweep.draw(data, "x_m", "itmtl.coverage")
    assert set(panels) == {(v, n) for v in ("itmtl", "wsc") for n in grid["noise"]}
    assert [t.get_text() for t in panels[("wsc", "d")].texts] == ["no runs"] and not panels[("wsc", "d")].containers
    assert [t.get_text() for t in panels[("itmtl", "d")].texts] == [] and len(panels[("itmtl", "d")].containers) == 2
    figures.plt.close(fig)
    data.runs.loc[(data.runs["noise"] == "d"), "itmtl.coverage"] = np.nan
    fig, panels = report_sweep.draw(data, "x_m", "itmtl.coverage")
    assert ("wsc", "d") not in panels
    figures.plt.close(fig)
