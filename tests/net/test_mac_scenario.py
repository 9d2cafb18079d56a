"""A MAC chosen in a scenario: resolved, built, validated (one line naming the key, exit 2),
and left out of a scenario that does not name one."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from aquasim_py import run_scenario, scenario
from aquasim_py.scenario import ScenarioError

BASE = """\
[simulation]
duration_s = 200.0
seed = 2

[environment]
volume = { lo = [0.0, 0.0, 0.0], hi = [2000.0, 2000.0, 100.0] }

[channel]
max_range_m = 1500.0
loss_model = "none"

[[nodes]]
name = "sink"
role = "sink"
protocol = "traffic"
placement = { kind = "explicit", positions = [[1000.0, 1000.0, 50.0]] }

[[nodes]]
name = "sources"
role = "ordinary"
count = 8
protocol = "traffic"
placement = { kind = "ring", center = [1000.0, 1000.0, 50.0], radius_m = 600.0 }
params = { rate_pps = 0.02, bits = 500 }
"""


@pytest.fixture
def scen(tmp_path: Path) -> Path:
    p = tmp_path / "net.toml"
    p.write_text(BASE)
    return p


def err_of(path: Path, *overrides: str) -> ScenarioError:
    with pytest.raises(ScenarioError) as ei:
        scenario.load(path, overrides=list(overrides))
    return ei.value


def test_a_group_without_a_mac_resolves_as_before(scen):
    d = scenario.load(scen).to_dict()
    assert all("mac" not in g and "mac_params" not in g for g in d["nodes"])


def test_a_named_mac_resolves_with_every_parameter(scen):
    sc = scenario.load(scen, overrides=["nodes.1.mac=csma", "nodes.1.mac_params={max_attempts=4}"])
    g = sc.to_dict()["nodes"][1]
    assert g["mac"] == "csma" and g["mac_params"]["max_attempts"] == 4
    assert g["mac_params"]["queue_length"] == 1 and g["mac_params"]["ack"] is False
    again = scenario.load(scen, overrides=["nodes.1.mac=csma"])
    assert again.to_dict()["nodes"][1]["mac_params"]["max_attempts"] is None


@pytest.mark.parametrize(
    "overrides, key, pattern",
    [
        (["nodes.1.mac=alhoa"], "nodes[1].mac", r"unknown MAC 'alhoa' \(available: direct, aloha, .*tdma\)"),
        (
            ["nodes.1.mac=aloha", "nodes.1.mac_params={queue_lenght=3}"],
            "nodes[1].mac_params.queue_lenght",
            "did you mean 'queue_length'",
        ),
        (["nodes.1.mac=tdma", "nodes.1.mac_params={guard_s=-1.0}"], "nodes[1].mac_params.guard_s", ">= 0"),
        (["nodes.1.mac=aloha", "nodes.1.mac_params={queue_length=0}"], "nodes[1].mac_params.queue_length", ">= 1"),
        (["nodes.1.mac=csma", "nodes.1.mac_params={backoff_max_s='2'}"], "nodes[1].mac_params.backoff_max_s", "number"),
        (["nodes.1.mac_params={queue_length=3}"], "nodes[1].mac_params.queue_length", "MAC 'direct'.*takes none"),
        (["nodes.1.params.destination=99"], "nodes[1].params.destination", "not a node"),
    ],
)
def test_bad_mac_input_names_the_key(scen, overrides, key, pattern):
    e = err_of(scen, *overrides)
    assert e.key_path == key
    assert re.search(pattern, str(e)), str(e)
    assert "\n" not in str(e)


def test_the_cli_says_it_in_one_line_and_exits_2(scen, tmp_path):
    exe = Path(sys.executable).parent / "aquasim-py"
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "aquasim_py.cli"]
    bad = subprocess.run(
        [*cmd, str(scen), "--set", "nodes.0.mac=fama", "--out", str(tmp_path / "x")],
        capture_output=True,
        text=True,
        env={**os.environ, "COLUMNS": "200"},
        timeout=120,
        check=False,
    )
    assert bad.returncode == 2
    assert len(bad.stderr.splitlines()) == 1 and "nodes[0].mac: unknown MAC 'fama'" in bad.stderr
    assert not (tmp_path / "x").exists()


def test_net_metrics_only_where_a_group_names_a_mac_or_runs_traffic(scen, tmp_path):
    res = run_scenario(scen)
    assert res.metrics["net.frames"] > 0  # traffic asks for them, over the default MAC
    p = tmp_path / "beacons.toml"
    beacons = BASE.replace('protocol = "traffic"', 'protocol = "beacon"').replace('role = "sink"', 'role = "anchor"')
    p.write_text(beacons.replace("params = { rate_pps = 0.02, bits = 500 }", ""))
    assert not any(k.startswith("net.") for k in run_scenario(p).metrics)
    named = run_scenario(p, overrides=["nodes.0.mac=direct"])
    assert named.metrics["net.frames"] > 0


def test_a_run_writes_offer_rows_and_keeps_its_mac_in_the_summary(scen, tmp_path):
    out = tmp_path / "out"
    res = run_scenario(scen, overrides=["nodes.0.mac=aloha", "nodes.1.mac=aloha"])
    pk = res.tables["packets"]
    offers = pk[pk["event"] == "offer"]
    assert len(offers) == res.metrics["net.frames"]
    res2 = run_scenario(scen, overrides=["nodes.1.mac=aloha"], out=out)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["scenario"]["nodes"][1]["mac"] == "aloha"
    assert res2.metrics["net.frames"] == pytest.approx(len(res2.tables["packets"].query("event == 'offer'")))
