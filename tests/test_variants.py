"""Scenario variants: loading and its errors, ``aquasim-py FILE`` (every variant),
``--variant NAME`` (one, as a plain run), ``--set`` on top, sweeps over ``variant``."""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import pytest

from aquasim_py import cli, registry, scenario, sweep
from aquasim_py.scenario import ScenarioError

BASE = """\
[simulation]
duration_s = 20.0
seed = 3

[environment]
volume = { lo = [0.0, 0.0, 0.0], hi = [1000.0, 1000.0, 100.0] }

[channel]
max_range_m = 3000.0
jitter_std_s = 1e-5

[[nodes]]
name = "anchors"
role = "anchor"
protocol = "beacon"
placement = { kind = "explicit", positions = [[0.0, 0.0, 10.0], [1000.0, 0.0, 10.0], [0.0, 1000.0, 10.0]] }
params = { period_s = 5.0 }

[[nodes]]
name = "sensors"
role = "ordinary"
count = 3
protocol = "beacon"
placement = { kind = "uniform", lo = [100.0, 100.0, 20.0], hi = [900.0, 900.0, 90.0] }
mobility = { model = "random_walk", speed_min = 0.0, speed_max = 1.0, leg_duration = 10.0 }
clock = { skew_std_ppm = 10.0, offset_std_s = 1e-4 }
"""

VARIANTS = """
[variants.asis]

[variants.slow]
"nodes.0.params.period_s" = 8.0
"channel.jitter_std_s" = 0.0

[variants.more]
"nodes.1.count" = 5
"""

# a run's outputs: the trace tables, the table behind the beacon report, summary.json
TABLES = [
    "beacon_range_errors.csv",
    "clocks.csv",
    "estimates.csv",
    "nodes.csv",
    "packets.csv",
    "positions.csv",
    "ranges.csv",
    "summary.json",
]


@pytest.fixture
def scen(tmp_path: Path) -> Path:
    p = tmp_path / "var.toml"
    p.write_text(BASE + VARIANTS)
    return p


def write(tmp_path: Path, text: str, name: str = "bad.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def run(capsys: pytest.CaptureFixture[str], *argv: object) -> tuple[int, str, str]:
    rc = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def assert_user_error(rc: int, err: str, key: str, problem: str, out_dir: Path) -> None:
    assert rc == 2
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert key in lines[0] and re.search(problem, lines[0]), lines[0]
    assert not out_dir.exists()
    assert not [p for p in out_dir.parent.iterdir() if p.name.startswith(f".{out_dir.name}.")]


# --------------------------------------------------------------------------- loading
def test_variant_overrides_only_what_it_names(scen):
    base = scenario.load(scen)
    assert base.variant is None and base.variant_names == ["asis", "slow", "more"]
    slow = scenario.load(scen, variant="slow")
    assert slow.variant == "slow" and slow.variants is None and slow.sweep is None
    assert slow.nodes[0].params["period_s"] == 8.0 and slow.channel.jitter_std_s == 0.0
    a, b = base.to_dict(), slow.to_dict()
    a.pop("variants")
    a["nodes"][0]["params"]["period_s"] = 8.0
    a["channel"]["jitter_std_s"] = 0.0
    assert a == b
    # the empty variant is the file as written
    asis = scenario.load(scen, variant="asis").to_dict()
    assert asis == {k: v for k, v in base.to_dict().items() if k != "variants"}


def test_set_and_seed_apply_on_top_of_the_variant(scen):
    sc = scenario.load(scen, overrides=["nodes.0.params.period_s=2"], seed=9, variant="slow")
    assert sc.nodes[0].params["period_s"] == 2.0 and sc.simulation.seed == 9
    assert sc.channel.jitter_std_s == 0.0  # the variant's other override stays


def test_resolved_variant_loads_back_as_is(scen):
    sc = scenario.load(scen, variant="more")
    again = scenario.load_dict(sc.to_dict(), sc.path)
    assert again.to_dict() == sc.to_dict()


def test_variant_replaces_a_protocol_and_its_params(tmp_path):
    other = "tshl"  # a protocol whose parameters differ from the beacon's
    p = write(tmp_path, BASE + f'[variants.swap]\n"nodes.1.protocol" = "{other}"\n"nodes.1.params" = {{}}\n')
    sc = scenario.load(p, variant="swap")
    assert sc.nodes[1].protocol == other
    assert sc.nodes[1].params == registry.get(other).Params().model_dump(mode="json")  # its defaults
    assert sc.nodes[0].protocol == "beacon"


@pytest.mark.parametrize(
    ("variants", "key", "problem"),
    [
        ('[variants.v]\n"nodes.1.params.x" = 1\n', 'variants.v."nodes.1.params.x"', r"unknown parameter"),
        ('[variants.v]\n"nodes.1.params" = { x = 1 }\n', 'variants.v."nodes.1.params".x', r"unknown parameter"),
        ('[variants.v]\n"nodes.1.count" = -2\n', 'variants.v."nodes.1.count"', r"must be >= 1 \(got -2\)"),
        ('[variants.v]\n"nodes.7.count" = 2\n', 'variants.v."nodes.7.count"', r"index 7 out of range"),
        ('[variants.v]\n"simulation.durration_s" = 2\n', 'variants.v."simulation.durration_s"', r"did you mean"),
        ('[variants.v]\n"simulation.seed" = 2\n', 'variants.v."simulation.seed"', r"same seed"),
        ('[variants.v]\n"sweep.runs" = 2\n', 'variants.v."sweep.runs"', r"cannot change the \[sweep\]"),
        ('[variants.v]\n"nodes..count" = 2\n', 'variants.v."nodes..count"', r"malformed key path"),
        ("[variants.v]\nnodes.1.count = 2\n", 'variants.v."nodes"', r"expected an array.*quoted"),
        (
            '[variants.v]\n"nodes.0.protocol" = "itmtl"\n',
            "variants.v",
            r"nodes\[0\]\.params\.period_s.*\"nodes\.0\.params\"",
        ),
        ('[variants."a b"]\n', 'variants."a b"', r"directory name"),
        ("variants = 3\n", "variants", r"expected \[variants.NAME\] tables"),
        ("[variants]\nv = 3\n", "variants.v", r"expected a table"),
    ],
)
def test_bad_variant_is_a_one_line_error(tmp_path, capsys, variants, key, problem):
    # top-level keys before the first table, tables after the scenario's
    p = write(tmp_path, variants + BASE if variants.startswith("variants =") else BASE + variants)
    out = tmp_path / "out"
    rc, _, err = run(capsys, p, "--out", out)
    assert_user_error(rc, err, key, problem, out)
    # the same error from Python, whatever variant is asked for
    with pytest.raises(ScenarioError) as e:
        scenario.load(p)
    assert key in str(e.value)


def test_variant_only_the_physics_rejects_fails_before_anything_runs(tmp_path, capsys, monkeypatch):
    from aquasim_py import kernel

    ran: list[float] = []
    monkeypatch.setattr(kernel.Simulation, "run", lambda self, until, progress=None: ran.append(until))
    bad = '[variants.ok]\n[variants.v]\n"nodes.1.mobility.speed_min" = 3.0\n'
    p = write(tmp_path, BASE + bad)
    out = tmp_path / "out"
    rc, _, err = run(capsys, p, "--out", out)
    assert_user_error(rc, err, 'variants.v."nodes.1.mobility.speed_min"', r"speed_min", out)
    assert ran == []


def test_unknown_variant(scen, tmp_path, capsys):
    out = tmp_path / "out"
    rc, _, err = run(capsys, scen, "--variant", "slwo", "--out", out)
    assert_user_error(rc, err, "variants", r"no variant 'slwo' \(did you mean 'slow'\?\)", out)
    plain = write(tmp_path, BASE, "plain.toml")
    rc, _, err = run(capsys, plain, "--variant", "slow", "--out", out)
    assert_user_error(rc, err, "variants", r"declares no \[variants.NAME\]", out)


def test_set_cannot_edit_the_variants(scen, tmp_path, capsys):
    out = tmp_path / "out"
    rc, _, err = run(capsys, scen, "--out", out, "--set", "variants.slow.x=1")
    assert_user_error(rc, err, "--set", r"on top of every variant", out)


# --------------------------------------------------------------------------- running
def test_every_variant_from_one_command_and_one_by_one(scen, tmp_path, capsys):
    out = tmp_path / "all"
    rc, stdout, err = run(capsys, scen, "--out", out)
    assert rc == 0, err
    assert sorted(p.name for p in out.iterdir()) == [".aquasim-output.json", "asis", "more", "slow", "variants.csv"]
    # one comparison table: a row per variant
    assert "variants (seed 3" in stdout and all(v in stdout for v in ("asis", "slow", "more"))
    assert stdout.count("metrics (seed") == 0  # no per-run tables
    with open(out / "variants.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["variant"] for r in rows] == ["asis", "slow", "more"]
    for name, row in zip(["asis", "slow", "more"], rows):
        assert sorted(p.name for p in (out / name).iterdir()) == [".aquasim-output.json", *TABLES]
        summary = json.loads((out / name / "summary.json").read_text())
        assert summary["variant"] == name and summary["seed"] == 3
        assert summary["scenario"]["output"]["directory"] == str(out / name)
        assert float(row["packets.sent"]) == summary["metrics"]["packets.sent"]
    # same network and seed: a variant that changes only the protocol timing moves nobody
    assert (out / "asis" / "positions.csv").read_bytes() == (out / "slow" / "positions.csv").read_bytes()
    assert (out / "asis" / "packets.csv").read_bytes() != (out / "slow" / "packets.csv").read_bytes()
    # --variant NAME writes exactly what a plain run writes, byte for byte the same traces
    one = tmp_path / "one"
    rc, stdout, _ = run(capsys, scen, "--variant", "slow", "--out", one)
    assert rc == 0 and "var/slow: metrics (seed 3" in stdout and "range error per anchor" in stdout
    assert sorted(p.name for p in one.iterdir()) == [".aquasim-output.json", *TABLES]
    for name in TABLES[:-1]:
        assert (one / name).read_bytes() == (out / "slow" / name).read_bytes(), name
    a = json.loads((one / "summary.json").read_text())
    b = json.loads((out / "slow" / "summary.json").read_text())
    assert a["metrics"] == b["metrics"] and a["variant"] == b["variant"] == "slow"


def test_variant_default_output_directory(scen, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert run(capsys, scen, "--variant", "more", "--quiet")[0] == 0
    assert (tmp_path / "out" / "var" / "more" / "summary.json").is_file()


def test_set_applies_to_every_variant(scen, tmp_path, capsys):
    out = tmp_path / "o"
    assert run(capsys, scen, "--out", out, "--quiet", "--set", "nodes.0.params.period_s=4")[0] == 0
    for name in ("asis", "slow", "more"):
        sc = json.loads((out / name / "summary.json").read_text())["scenario"]
        assert sc["nodes"][0]["params"]["period_s"] == 4.0
    sc = json.loads((out / "more" / "summary.json").read_text())["scenario"]
    assert sc["nodes"][1]["count"] == 5


# --------------------------------------------------------------------------- sweeps
SWEEP = '\n[sweep]\nruns = 1\ngrid = { variant = ["slow", "asis"], "nodes.1.count" = [2, 3] }\n'


def test_sweep_over_variants(tmp_path, capsys):
    import aquasim_py

    p = write(tmp_path, BASE.replace("duration_s = 20.0", "duration_s = 10.0") + VARIANTS + SWEEP, "sw.toml")
    a, b = tmp_path / "a", tmp_path / "b"
    assert cli.main(["sweep", str(p), "--workers", "1", "--out", str(a), "--quiet"]) == 0
    assert cli.main(["sweep", str(p), "--workers", "2", "--out", str(b), "--quiet"]) == 0
    assert (a / "sweep.csv").read_bytes() == (b / "sweep.csv").read_bytes()
    with open(a / "sweep.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0])[:4] == ["variant", "nodes.1.count", "run", "seed"]
    assert [(r["variant"], r["nodes.1.count"], r["run"]) for r in rows] == [
        (v, c, "0") for v in ("slow", "asis") for c in ("2", "3")
    ]
    # a row is the variant run with the grid value on top, at the run's seed
    sc = scenario.load(p)
    job = next(j for j in sweep.plan(sc) if dict(j.point) == {"variant": "slow", "nodes.1.count": 3})
    direct = aquasim_py.run_scenario(p, variant="slow", seed=job.seed, overrides={"nodes.1.count": 3})
    row = rows[job.index]
    assert float(row["beacon.range_rmse_m"]) == direct.metrics["beacon.range_rmse_m"]
    assert int(row["packets.sent"]) == direct.metrics["packets.sent"]


def test_sweep_grid_variant_errors(tmp_path, capsys):
    p = write(tmp_path, BASE + VARIANTS + SWEEP.replace('"asis"', '"asiss"'), "sw.toml")
    out = tmp_path / "o"
    rc, _, err = run(capsys, "sweep", p, "--out", out)
    assert_user_error(rc, err, "sweep.grid.variant", r"no variant 'asiss' \(did you mean 'asis'\?\)", out)
    # a grid value checked in every swept variant
    p = write(tmp_path, BASE + VARIANTS + '\n[sweep]\ngrid = { variant = ["more"], "nodes.1.params.x" = [1] }\n')
    rc, _, err = run(capsys, "sweep", p, "--out", out)
    assert_user_error(rc, err, 'sweep.grid."nodes.1.params.x"', r"value 1: variants.more: .*unknown parameter", out)
