"""Sweeps: job order, seeds, identical rows whatever the number of workers."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from aquasim_py import cli, scenario, sweep

SCENARIO = """\
[simulation]
duration_s = 40.0
seed = 21

[environment]
volume = { lo = [0.0, 0.0, 0.0], hi = [800.0, 800.0, 60.0] }

[[nodes]]
role = "anchor"
protocol = "beacon"
placement = { kind = "explicit", positions = [[0.0, 0.0, 5.0], [800.0, 800.0, 5.0]] }
params = { period_s = 4.0 }

[[nodes]]
role = "ordinary"
count = 3
protocol = "beacon"
placement = { kind = "uniform" }
clock = { skew_std_ppm = 30.0 }

[sweep]
runs = 3
grid = { "channel.jitter_std_s" = [0.0, 1e-3], "nodes.1.count" = [2, 4] }
"""


@pytest.fixture
def scen(tmp_path: Path) -> Path:
    p = tmp_path / "sw.toml"
    p.write_text(SCENARIO)
    return p


def test_run_seed_is_deterministic_and_distinct():
    seeds = [sweep.run_seed(21, r) for r in range(100)]
    assert seeds == [sweep.run_seed(21, r) for r in range(100)]
    assert len(set(seeds)) == 100
    assert all(0 <= s < 2**63 for s in seeds)
    assert sweep.run_seed(22, 0) != sweep.run_seed(21, 0)


def test_plan_order(scen):
    jobs = sweep.plan(scenario.load(scen))
    assert [j.index for j in jobs] == list(range(12))
    # grid keys in file order, later keys faster, runs fastest
    points = [tuple(v for _, v in j.point) for j in jobs]
    assert points == [(a, b) for a in (0.0, 1e-3) for b in (2, 4) for _ in range(3)]
    assert [j.run for j in jobs] == [0, 1, 2] * 4
    # common random numbers: run r has the same seed at every grid point
    assert {j.seed for j in jobs if j.run == 1} == {sweep.run_seed(21, 1)}


def test_rows_depend_on_swept_values(scen):
    sc = scenario.load(scen)
    jobs = [j for j in sweep.plan(sc) if j.run == 0]
    rows = sweep.run_jobs(sc, jobs, workers=1)
    assert [r["nodes.1.count"] for r in rows] == [2, 4, 2, 4]
    # 2 anchors, 4 s period, 40 s: 10 beacons each -> 20 sent whatever the listeners
    assert all(r["packets.sent"] == 20 for r in rows)
    # more listeners, more ranges (same seed, same anchors)
    assert rows[1]["beacon.ranges"] > rows[0]["beacon.ranges"]
    # a run row equals a direct single run with the same seed and values
    direct = scenario.load_dict(
        sc.to_dict(),
        scen,
        overrides=[(["nodes", 1, "count"], 4), (["channel", "jitter_std_s"], 0.0)],
        seed=jobs[1].seed,
    )
    sim = scenario.build(direct)
    sim.run(direct.simulation.duration_s)
    from aquasim_py import metrics

    m = metrics.summarize(sim.trace.frames(), direct.protocols())
    for k, v in m.items():
        assert rows[1][k] == v or (math.isnan(v) and math.isnan(rows[1][k])), k


def test_two_workers_give_the_same_csv_as_one(scen, tmp_path, capsys):
    a, b = tmp_path / "w1", tmp_path / "w2"
    assert cli.main(["sweep", str(scen), "--workers", "1", "--out", str(a), "--quiet"]) == 0
    assert cli.main(["sweep", str(scen), "--workers", "2", "--out", str(b), "--quiet"]) == 0
    assert (a / "sweep.csv").read_bytes() == (b / "sweep.csv").read_bytes()
    with open(a / "sweep.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 12
    head = list(rows[0])
    assert head[:4] == ["channel.jitter_std_s", "nodes.1.count", "run", "seed"]
    assert "beacon.range_rmse_m" in head and "packets.sent" in head
    info = json.loads((b / "sweep.json").read_text())
    assert info["runs"] == 12 and info["workers"] == 2 and info["scenario"]["sweep"]["runs"] == 3


def test_sweep_prints_summary(scen, tmp_path, capsys):
    rc = cli.main(["sweep", str(scen), "--workers", "1", "--out", str(tmp_path / "o"), "--set", "sweep.runs=1"])
    out, err = capsys.readouterr()
    assert rc == 0 and err == ""
    assert "4 runs" in out and "beacon.range_rmse_m" in out


def test_sweep_without_sweep_table(tmp_path, capsys):
    p = tmp_path / "nosweep.toml"
    p.write_text(SCENARIO[: SCENARIO.index("[sweep]")])
    rc = cli.main(["sweep", str(p), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and err.strip() == f"error: {p}: sweep: no [sweep] table: add one with runs and grid to run a sweep"
    assert not (tmp_path / "o").exists()


def test_sweep_grid_value_rejected_by_physics_fails_before_running(scen, tmp_path, capsys):
    rc = cli.main(
        [
            "sweep",
            str(scen),
            "--out",
            str(tmp_path / "o"),
            "--set",
            'sweep.grid={"nodes.1.mobility"=[{model="random_walk", speed_min=3.0, speed_max=1.0}]}',
        ]
    )
    err = capsys.readouterr().err
    assert rc == 2 and len(err.splitlines()) == 1 and "nodes[1].mobility" in err
    assert not (tmp_path / "o").exists()


def test_scheduler_without_dask_is_a_clear_error(scen, tmp_path, capsys, monkeypatch):
    import builtins

    real_import = builtins.__import__

    def no_dask(name, *a, **kw):
        if name.startswith("dask"):
            raise ImportError("No module named 'dask'")
        return real_import(name, *a, **kw)

    monkeypatch.setattr(builtins, "__import__", no_dask)
    rc = cli.main(["sweep", str(scen), "--scheduler", "tcp://127.0.0.1:1", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and err.strip() == "error: --scheduler needs dask.distributed: pip install 'aquasim-py[dask]'"


def test_dask_rows_equal_local_rows(scen):
    distributed = pytest.importorskip("dask.distributed")
    sc = scenario.load(scen, overrides=["sweep.runs=1"])
    jobs = sweep.plan(sc)
    local = sweep.run_jobs(sc, jobs, workers=1)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False) as cluster:
        remote = sweep.run_jobs(sc, jobs, scheduler=cluster.scheduler_address)
    assert json.dumps(local) == json.dumps(remote)


def test_csv_cells_round_trip_floats(tmp_path):
    rows = [{"a": 0.1 + 0.2, "run": 0, "seed": 1, "m": float("nan"), "v": [1, 2]}]
    job = sweep.Job(0, (("a", 0.3),), 0, 1)
    cols = sweep.columns(rows, [job])
    assert cols == ["a", "run", "seed", "m", "v"]
    sweep.rows_to_csv(rows, cols, tmp_path / "x.csv")
    with open(tmp_path / "x.csv") as fh:
        back = next(iter(csv.DictReader(fh)))
    assert float(back["a"]) == 0.1 + 0.2 and np.isnan(float(back["m"])) and json.loads(back["v"]) == [1, 2]
