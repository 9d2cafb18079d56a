"""``aquasim_py.run_scenario`` / ``run_variants`` / ``RunResult``: the one way to run, from Python."""

from __future__ import annotations

import io
import json
from pathlib import Path

import pandas as pd
import pytest
from rich.console import Console
from test_variants import BASE, TABLES, VARIANTS  # the same tiny scenario

import aquasim_py
from aquasim_py import cli, metrics, scenario
from aquasim_py.scenario import ScenarioError


@pytest.fixture
def scen(tmp_path: Path) -> Path:
    p = tmp_path / "nb.toml"
    p.write_text(BASE + VARIANTS)
    return p


def same_tables(a: aquasim_py.RunResult, b: aquasim_py.RunResult) -> None:
    assert list(a.tables) == list(b.tables)
    for name in a.tables:
        pd.testing.assert_frame_equal(a.tables[name], b.tables[name], check_exact=True)


def test_run_from_a_path(scen):
    res = aquasim_py.run_scenario(scen)
    assert isinstance(res, aquasim_py.RunResult)
    assert res.variant is None and res.seed == 3 and res.scenario.path == scen
    assert {"packets", "positions", "ranges"} <= set(res.tables)
    assert len(res.tables["ranges"]) > 0
    again = metrics.summarize(res.tables, res.scenario.protocols())
    assert again.keys() == res.metrics.keys()
    assert res.metrics["beacon.ranges"] == len(res.tables["ranges"])
    text = repr(res)
    assert text.startswith("<RunResult nb seed=3 20 s simulated") and "ranges (" in text
    con = Console(file=io.StringIO(), width=120, record=True)
    for r in res.reports():  # the protocol's report(), as the CLI prints it
        con.print(r)
    assert "range error per anchor" in con.export_text()


def test_loaded_scenario_and_path_give_the_same_run(scen):
    sc = scenario.load(scen, variant="slow")
    a = aquasim_py.run_scenario(sc)
    b = aquasim_py.run_scenario(scen, variant="slow")
    assert a.scenario is sc and a.variant == b.variant == "slow"
    same_tables(a, b)
    assert a.metrics == b.metrics


def test_overrides_and_seed_from_python(scen):
    sc = scenario.load(scen)
    res = aquasim_py.run_scenario(sc, seed=11, overrides={"nodes.1.count": 2, "simulation.duration_s": 10})
    assert res.seed == 11 and res.scenario.nodes[1].count == 2 and res.scenario.simulation.duration_s == 10.0
    assert res.tables["nodes"]["node"].nunique() == 3 + 2
    assert sc.nodes[1].count == 3 and sc.simulation.seed == 3  # the loaded scenario is left alone
    # the three spellings of an override are the same override
    by_text = aquasim_py.run_scenario(scen, seed=11, overrides=["nodes.1.count=2", "simulation.duration_s=10"])
    by_pair = aquasim_py.run_scenario(
        scen, seed=11, overrides=[("nodes[1].count", 2), (["simulation", "duration_s"], 10)]
    )
    same_tables(res, by_text)
    same_tables(res, by_pair)
    # overrides apply on top of the variant, also for an already-loaded variant
    slow = aquasim_py.run_scenario(scenario.load(scen, variant="slow"), overrides={"channel.jitter_std_s": 1e-5})
    assert slow.variant == "slow" and slow.scenario.nodes[0].params["period_s"] == 8.0
    assert slow.scenario.channel.jitter_std_s == 1e-5


def test_bad_input_raises_scenario_error(scen):
    with pytest.raises(ScenarioError, match=r"nodes\[1\]\.count: must be >= 1"):
        aquasim_py.run_scenario(scen, overrides={"nodes.1.count": 0})
    with pytest.raises(ScenarioError, match=r"did you mean 'slow'"):
        aquasim_py.run_scenario(scen, variant="sloww")


def test_write_is_what_the_cli_writes(scen, tmp_path, capsys):
    res = aquasim_py.run_scenario(scen, variant="more")
    mine = res.write(tmp_path / "py")
    assert mine == tmp_path / "py" and res.out == mine
    assert cli.main([str(scen), "--variant", "more", "--out", str(tmp_path / "cli"), "--quiet"]) == 0
    assert sorted(p.name for p in mine.iterdir()) == [".aquasim-output.json", *TABLES]
    for name in TABLES[:-1]:
        assert (mine / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    summary = json.loads((mine / "summary.json").read_text())
    assert summary["variant"] == "more" and summary["scenario"]["output"]["directory"] == str(mine)
    # out= writes while running, staged the same way
    again = aquasim_py.run_scenario(scen, variant="more", out=tmp_path / "direct")
    assert (tmp_path / "direct" / "packets.csv").read_bytes() == (mine / "packets.csv").read_bytes()
    assert again.out == tmp_path / "direct"


def test_run_variants(scen, tmp_path):
    out = tmp_path / "all"
    results = aquasim_py.run_variants(scen, out=out, overrides={"simulation.duration_s": 10})
    assert list(results) == ["asis", "slow", "more"]
    assert sorted(p.name for p in out.iterdir()) == [".aquasim-output.json", "asis", "more", "slow", "variants.csv"]
    one = aquasim_py.run_scenario(scen, variant="slow", overrides={"simulation.duration_s": 10})
    same_tables(results["slow"], one)
    table = aquasim_py.runner.compare(results)
    assert list(table.index) == ["asis", "slow", "more"]
    assert table.loc["more", "packets.sent"] == results["more"].metrics["packets.sent"]
    csv = pd.read_csv(out / "variants.csv", index_col="variant")
    assert csv.loc["slow", "beacon.range_rmse_m"] == results["slow"].metrics["beacon.range_rmse_m"]
    # a subset, and a file without variants
    assert list(aquasim_py.run_variants(scen, variants=["more"], overrides={"simulation.duration_s": 5})) == ["more"]
    plain = tmp_path / "plain.toml"
    plain.write_text(BASE.replace("duration_s = 20.0", "duration_s = 5.0"))
    assert list(aquasim_py.run_variants(plain)) == ["default"]


def test_progress_callback_follows_simulated_time(scen):
    seen: list[tuple[float, float]] = []
    aquasim_py.run_scenario(scen, progress=lambda t, until: seen.append((t, until)))
    assert seen and seen[-1] == (20.0, 20.0) and [t for t, _ in seen] == sorted(t for t, _ in seen)
