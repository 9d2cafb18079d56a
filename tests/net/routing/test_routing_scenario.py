"""Routing chosen in a scenario: resolved with every parameter, built, validated (one line naming
the key, exit 2), left out of a scenario that does not name it; the shipped comparison's sweep
gives the same rows on one worker, two, and Dask."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from aquasim_py import run_scenario, scenario, sweep
from aquasim_py.scenario import ScenarioError

ROOT = Path(__file__).resolve().parents[3]

BASE = """\
[simulation]
duration_s = 120.0
seed = 3

[environment]
volume = { lo = [0.0, 0.0, 0.0], hi = [200.0, 200.0, 300.0] }

[channel]
max_range_m = 100.0
bitrate_bps = 10000.0
loss_model = "none"

[[nodes]]
name = "sink"
role = "sink"
protocol = "traffic"
placement = { kind = "explicit", positions = [[100.0, 100.0, 0.0]] }
routing = "flooding"

[[nodes]]
name = "relays"
role = "ordinary"
count = 30
protocol = "traffic"
placement = { kind = "uniform" }
params = { rate_pps = 0.0 }
routing = "flooding"

[[nodes]]
name = "sources"
role = "ordinary"
count = 3
protocol = "traffic"
placement = { kind = "uniform", lo = [0.0, 0.0, 250.0], hi = [200.0, 200.0, 300.0] }
params = { rate_pps = 0.05, bits = 300, destination = "any_sink", stop_s = 100.0 }
routing = "flooding"
"""


@pytest.fixture
def scen(tmp_path: Path) -> Path:
    p = tmp_path / "routed.toml"
    p.write_text(BASE)
    return p


def err_of(path: Path, *overrides: str) -> ScenarioError:
    with pytest.raises(ScenarioError) as ei:
        scenario.load(path, overrides=list(overrides))
    return ei.value


def test_routing_resolves_with_every_parameter_and_is_absent_where_unset(scen):
    d = scenario.load(scen, overrides=["nodes.1.routing_params={jitter_max_s=0.5}"]).to_dict()
    assert d["nodes"][1]["routing"] == "flooding"
    assert d["nodes"][1]["routing_params"] == {
        "jitter_max_s": 0.5,
        "max_hops": None,
        "history_length": 4096,
        "header_bits": None,
    }
    plain = scenario.load(ROOT / "scenarios" / "beacon.toml").to_dict()
    assert all("routing" not in g and "routing_params" not in g for g in plain["nodes"])


ALL = ("nodes.0.routing={r}", "nodes.1.routing={r}", "nodes.2.routing={r}")


@pytest.mark.parametrize(
    "overrides, key, pattern",
    [
        ([a.format(r="dbrr") for a in ALL], "nodes[0].routing", r"unknown routing protocol 'dbrr' \(available: flooding, vbf"),
        (["nodes.1.routing_params={jitter_max=1.0}"], "nodes[1].routing_params.jitter_max", "did you mean 'jitter_max_s'"),
        ([*(a.format(r="dbr") for a in ALL), "nodes.1.routing_params={depth_threshold_m=-5.0}"],
         "nodes[1].routing_params.depth_threshold_m", ">= 0"),
        ([a.format(r="vbf") for a in ALL], "nodes[0].sensors.position_fix", "needs the nodes' position fixes"),
        (["nodes.1.routing=dbr"], "nodes[1].routing", "'dbr', but nodes\\[0\\] routes with 'flooding'"),
        (["nodes.0.role=ordinary", "nodes.2.params.destination=broadcast"], "nodes[0].routing", "no group of role sink"),
    ],
)  # fmt: skip
def test_bad_routing_input_names_the_key(scen, overrides, key, pattern):
    e = err_of(scen, *overrides)
    assert e.key_path == key
    assert re.search(pattern, str(e)), str(e)
    assert "\n" not in str(e)


@pytest.mark.parametrize(
    "edit, key, pattern",
    [
        (('routing = "flooding"\n\n[[nodes]]\nname = "relays"', '\n[[nodes]]\nname = "relays"'), "nodes[0].routing",
         "the sinks must run"),
        (('count = 3\n', 'count = 3\nrouting_params = { max_hops = 3 }\n'), None, None),
    ],
)  # fmt: skip
def test_a_sink_without_routing_or_parameters_without_one(tmp_path, edit, key, pattern):
    text = BASE.replace(*edit)
    if key is None:  # routing_params of a group with no routing
        text = text.replace(
            'params = { rate_pps = 0.05, bits = 300, destination = "any_sink", stop_s = 100.0 }\nrouting = "flooding"',
            'params = { rate_pps = 0.05, bits = 300, destination = "any_sink", stop_s = 100.0 }',
        )
        key, pattern = "nodes[2].routing_params", "without routing"
    p = tmp_path / "x.toml"
    p.write_text(text)
    e = err_of(p)
    assert e.key_path == key and re.search(pattern, str(e)), str(e)


def test_the_cli_says_it_in_one_line_and_exits_2(scen, tmp_path):
    exe = Path(sys.executable).parent / "aquasim-py"
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "aquasim_py.cli"]
    bad = subprocess.run(
        [*cmd, str(scen), "--set", "nodes.1.routing=vfb", "--out", str(tmp_path / "x")],
        capture_output=True,
        text=True,
        env={**os.environ, "COLUMNS": "200"},
        timeout=120,
        check=False,
    )
    assert bad.returncode == 2
    assert len(bad.stderr.splitlines()) == 1 and "nodes[1].routing: unknown routing protocol 'vfb'" in bad.stderr
    assert not (tmp_path / "x").exists()


def test_a_routed_run_reports_the_end_to_end_metrics(scen, tmp_path):
    out = tmp_path / "out"
    res = run_scenario(scen, out=out)
    m = res.metrics
    assert m["net.packets_originated"] > 0 and 0.0 < m["net.pdr"] <= 1.0
    assert m["net.hops_mean"] >= 1.0 and m["net.copies_per_delivered"] >= m["net.hops_mean"]
    assert m["net.delay_s"] > 0.0 and m["net.frame_delay_s"] > 0.0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["scenario"]["nodes"][1]["routing"] == "flooding"
    assert (out / "routes.csv").is_file()


def test_the_routing_sweep_gives_the_same_rows_on_any_number_of_workers_and_on_dask():
    over = [
        "simulation.duration_s=20.0",
        "nodes.2.params.start_s=1.0",
        "nodes.2.params.stop_s=15.0",
        "nodes.2.params.rate_pps=0.1",
        "sweep.runs=1",
        # a 250 m cube, two sinks, four sources: 20-40 relays connect it (in the shipped 500 m
        # cube they would not, and every row would read no delivery)
        "environment.volume={lo=[0.0, 0.0, 0.0], hi=[250.0, 250.0, 250.0]}",
        "nodes.0.placement.positions=[[62.5, 62.5, 0.0], [187.5, 187.5, 0.0]]",
        "nodes.2.count=4",
        "nodes.2.placement.lo=[0.0, 0.0, 200.0]",
        "nodes.2.placement.hi=[250.0, 250.0, 250.0]",
        'sweep.grid={variant=["flooding", "vbf", "hh_vbf", "dbr", "eedbr"], "nodes.1.count"=[20, 40]}',
    ]
    sc = scenario.load(ROOT / "scenarios" / "routing_compare.toml", overrides=over)
    jobs = sweep.plan(sc)
    one = sweep.run_jobs(sc, jobs, workers=1)
    two = sweep.run_jobs(sc, jobs, workers=2)
    assert json.dumps(one) == json.dumps(two)
    assert {r["variant"] for r in one} == {"flooding", "vbf", "hh_vbf", "dbr", "eedbr"}
    assert all(r["net.packets_originated"] > 0 for r in one)
    # every protocol delivers, over several hops
    for v in ("flooding", "vbf", "hh_vbf", "dbr", "eedbr"):
        assert max(r["net.pdr"] for r in one if r["variant"] == v) > 0.0
        assert max(r["net.hops_mean"] for r in one if r["variant"] == v) > 2.0
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False) as cluster:
        remote = sweep.run_jobs(sc, jobs, scheduler=cluster.scheduler_address)
    assert json.dumps(one) == json.dumps(remote)
