"""End-to-end tests of the ``aquasim-py`` command (in-process via cli.main, plus one subprocess)."""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from console_table import assert_printed

from aquasim_py import cli, metrics, trace

SCENARIO = """\
[simulation]
duration_s = 60.0
seed = 3

[environment]
volume = { lo = [0.0, 0.0, 0.0], hi = [1000.0, 1000.0, 100.0] }
sound_speed = { model = "constant", speed_mps = 1500.0 }

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
count = 4
protocol = "beacon"
placement = { kind = "uniform", lo = [100.0, 100.0, 20.0], hi = [900.0, 900.0, 90.0] }
clock = { skew_std_ppm = 10.0, offset_std_s = 1e-4 }
"""


@pytest.fixture
def scen(tmp_path: Path) -> Path:
    p = tmp_path / "scen.toml"
    p.write_text(SCENARIO)
    return p


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    rc = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def assert_user_error(rc: int, err: str, file: str, key: str, problem: str, out_dir: Path) -> None:
    """Exit 2, exactly one stderr line naming file, key path and problem; nothing written."""
    assert rc == 2
    lines = err.splitlines()
    assert len(lines) == 1, err
    line = lines[0]
    assert line.startswith("error: ")
    assert file in line
    assert key in line, line
    assert re.search(problem, line), line
    assert "Traceback" not in err
    assert not out_dir.exists()
    leftovers = (
        [p.name for p in out_dir.parent.iterdir() if p.name.startswith(f".{out_dir.name}.")]
        if out_dir.parent.is_dir()
        else []
    )
    assert leftovers == []


# --------------------------------------------------------------------------- bad input, one each
def test_toml_syntax_error(tmp_path, capsys):
    p = tmp_path / "bad.toml"
    p.write_text(SCENARIO.replace("duration_s = 60.0", "duration_s = = 60.0"))
    out = tmp_path / "out"
    rc, _, err = run(capsys, p, "--out", out)
    assert_user_error(rc, err, "bad.toml", "line 2, column", "TOML syntax error", out)


def test_unknown_key(tmp_path, capsys):
    p = tmp_path / "bad.toml"
    p.write_text(SCENARIO.replace("seed = 3", "seed = 3\nduraton = 5"))
    out = tmp_path / "out"
    rc, _, err = run(capsys, p, "--out", out)
    assert_user_error(rc, err, "bad.toml", "simulation.duraton", "unknown key", out)


def test_unknown_section(scen, tmp_path, capsys):
    out = tmp_path / "out"
    rc, _, err = run(capsys, scen, "--out", out, "--set", "enviroment.volume=1")
    assert_user_error(rc, err, "scen.toml", "enviroment", r"unknown key.*did you mean 'environment'", out)


def test_wrong_type(tmp_path, capsys):
    p = tmp_path / "bad.toml"
    p.write_text(SCENARIO.replace("duration_s = 60.0", 'duration_s = "long"'))
    out = tmp_path / "out"
    rc, _, err = run(capsys, p, "--out", out)
    assert_user_error(rc, err, "bad.toml", "simulation.duration_s", r"expected a number \(got string 'long'\)", out)


def test_negative_count(tmp_path, capsys):
    p = tmp_path / "bad.toml"
    p.write_text(SCENARIO.replace("count = 4", "count = -3"))
    out = tmp_path / "out"
    rc, _, err = run(capsys, p, "--out", out)
    assert_user_error(rc, err, "bad.toml", "nodes[1].count", r"must be >= 1 \(got -3\)", out)
    assert err.strip() == f"error: {p}: nodes[1].count: must be >= 1 (got -3)"


def test_nan(tmp_path, capsys):
    p = tmp_path / "bad.toml"
    p.write_text(SCENARIO.replace("jitter_std_s = 1e-5", "jitter_std_s = nan"))
    out = tmp_path / "out"
    rc, _, err = run(capsys, p, "--out", out)
    assert_user_error(rc, err, "bad.toml", "channel.jitter_std_s", r"finite number \(got nan\)", out)


def test_nan_in_protocol_params(scen, tmp_path, capsys):
    out = tmp_path / "out"
    rc, _, err = run(capsys, scen, "--out", out, "--set", "nodes.0.params.period_s=nan")
    assert_user_error(rc, err, "scen.toml", "nodes[0].params.period_s", "finite", out)


def test_unknown_protocol(tmp_path, capsys):
    p = tmp_path / "bad.toml"
    p.write_text(
        SCENARIO.replace(
            'protocol = "beacon"\nplacement = { kind = "uniform"', 'protocol = "becon"\nplacement = { kind = "uniform"'
        )
    )
    out = tmp_path / "out"
    rc, _, err = run(capsys, p, "--out", out)
    assert_user_error(rc, err, "bad.toml", "nodes[1].protocol", r"unknown protocol 'becon' \(available: .*beacon", out)


def test_unknown_profile(tmp_path, capsys):
    p = tmp_path / "bad.toml"
    p.write_text(SCENARIO.replace('model = "constant"', 'model = "pekeris"'))
    out = tmp_path / "out"
    rc, _, err = run(capsys, p, "--out", out)
    assert_user_error(
        rc, err, "bad.toml", "environment.sound_speed.model", "unknown sound-speed profile 'pekeris'", out
    )


def test_protocol_parameter_of_wrong_type(tmp_path, capsys):
    p = tmp_path / "bad.toml"
    p.write_text(SCENARIO.replace("params = { period_s = 5.0 }", 'params = { period_s = "often" }'))
    out = tmp_path / "out"
    rc, _, err = run(capsys, p, "--out", out)
    assert_user_error(rc, err, "bad.toml", "nodes[0].params.period_s", "expected a number", out)


def test_unknown_protocol_parameter(scen, tmp_path, capsys):
    out = tmp_path / "out"
    rc, _, err = run(capsys, scen, "--out", out, "--set", "nodes.0.params.perod_s=2")
    assert_user_error(rc, err, "scen.toml", "nodes[0].params.perod_s", "did you mean 'period_s'", out)


def test_no_nodes(tmp_path, capsys):
    p = tmp_path / "bad.toml"
    p.write_text(SCENARIO[: SCENARIO.index("[[nodes]]")])
    out = tmp_path / "out"
    rc, _, err = run(capsys, p, "--out", out)
    assert_user_error(rc, err, "bad.toml", "nodes", "at least one node group", out)


def test_position_outside_volume(tmp_path, capsys):
    p = tmp_path / "bad.toml"
    p.write_text(SCENARIO.replace("[1000.0, 0.0, 10.0]", "[1000.0, 0.0, 150.0]"))
    out = tmp_path / "out"
    rc, _, err = run(capsys, p, "--out", out)
    assert_user_error(rc, err, "bad.toml", "nodes[0].placement.positions[1]", "outside the volume", out)


def test_missing_file(tmp_path, capsys):
    out = tmp_path / "out"
    rc, _, err = run(capsys, tmp_path / "nope.toml", "--out", out)
    assert_user_error(rc, err, "nope.toml", "", "file not found", out)


def test_unwritable_output_directory(scen, tmp_path, capsys):
    blocker = tmp_path / "blocker"
    blocker.write_text("a file where a directory should be")
    out = blocker / "run"
    rc, _, err = run(capsys, scen, "--out", out)
    assert_user_error(rc, err, "scen.toml", "--out", "cannot write to", out)
    assert blocker.read_text().startswith("a file")


def test_unwritable_output_directory_from_scenario(scen, tmp_path, capsys, monkeypatch):
    (tmp_path / "blocker").write_text("x")
    monkeypatch.chdir(tmp_path)
    rc, _, err = run(capsys, scen, "--set", 'output.directory="blocker/deeper/run"')
    assert_user_error(
        rc, err, "scen.toml", "output.directory", "cannot write to", tmp_path / "blocker" / "deeper" / "run"
    )


def test_bad_override_syntax(scen, tmp_path, capsys):
    out = tmp_path / "out"
    rc, _, err = run(capsys, scen, "--out", out, "--set", "simulation.duration_s")
    assert_user_error(rc, err, "scen.toml", "--set", "expected key.path=value", out)


def test_override_index_out_of_range(scen, tmp_path, capsys):
    out = tmp_path / "out"
    rc, _, err = run(capsys, scen, "--out", out, "--set", "nodes.7.count=2")
    assert_user_error(rc, err, "scen.toml", "nodes[7].count", "out of range", out)


def test_unknown_option_is_one_line(scen, capsys):
    rc, _, err = run(capsys, scen, "--frobnicate")
    assert rc == 2 and len(err.splitlines()) == 1 and "--frobnicate" in err


# --------------------------------------------------------------------------- good runs
def test_run_writes_trace_summary_and_prints_metrics(scen, tmp_path, capsys):
    out = tmp_path / "res"
    rc, stdout, err = run(capsys, scen, "--out", out, "--seed", "11", "--set", "nodes.1.count=5")
    assert rc == 0, err
    assert err == ""  # not a terminal: no progress bar
    for name in ("packets.csv", "positions.csv", "ranges.csv", "nodes.csv", "summary.json"):
        assert (out / name).is_file(), name
    summary = json.loads((out / "summary.json").read_text())
    sc = summary["scenario"]
    assert summary["seed"] == 11 and sc["simulation"]["seed"] == 11
    assert sc["nodes"][1]["count"] == 5
    assert sc["nodes"][0]["count"] == 3  # implied by the explicit placement
    assert sc["nodes"][0]["params"]["nominal_speed_mps"] == 1500.0  # defaults resolved
    assert sc["output"]["directory"] == str(out)
    m = summary["metrics"]
    assert m["packets.sent"] > 0 and m["beacon.ranges"] > 0
    # every metric is in the printed table, as printed (see assert_printed)
    for k, v in m.items():
        assert_printed(stdout, k, v)
    assert "range error per anchor" in stdout  # the protocol's report()
    # nothing but the output directory itself appears next to it
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res", "scen.toml"]


def test_csv_trace_reloaded_gives_the_printed_metrics(scen, tmp_path, capsys):
    out = tmp_path / "res"
    rc, stdout, _ = run(capsys, scen, "--out", out)
    assert rc == 0
    printed = json.loads((out / "summary.json").read_text())["metrics"]
    again = metrics.summarize(trace.load(out))
    assert set(again) == set(printed)
    for k, v in printed.items():
        if v is None:
            assert math.isnan(again[k]), k
        else:
            assert again[k] == pytest.approx(v, rel=1e-12, abs=1e-12), k
        assert_printed(stdout, k, again[k])


def test_same_seed_same_trace_bytes(scen, tmp_path, capsys):
    a, b = tmp_path / "a", tmp_path / "b"
    assert run(capsys, scen, "--out", a, "--quiet")[0] == 0
    assert run(capsys, scen, "--out", b, "--quiet")[0] == 0
    for name in ("packets.csv", "ranges.csv", "positions.csv"):
        assert (a / name).read_bytes() == (b / name).read_bytes()


def test_quiet_prints_nothing(scen, tmp_path, capsys):
    rc, out, err = run(capsys, scen, "--out", tmp_path / "q", "--quiet")
    assert rc == 0 and out == "" and err == ""


def test_existing_output_is_replaced(scen, tmp_path, capsys):
    """The files an earlier run wrote (its manifest) go; a foreign directory: see test_outdir."""
    out = tmp_path / "res"
    out.mkdir()
    (out / "stale.csv").write_text("old")
    (out / ".aquasim-output.json").write_text('{"files": ["stale.csv"]}')
    assert run(capsys, scen, "--out", out, "--quiet")[0] == 0
    assert not (out / "stale.csv").exists() and (out / "summary.json").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res", "scen.toml"]


def test_failed_run_leaves_nothing(scen, tmp_path, capsys, monkeypatch):
    from aquasim_py import kernel

    def boom(self, until, progress=None):
        raise RuntimeError("simulated crash")

    monkeypatch.setattr(kernel.Simulation, "run", boom)
    out = tmp_path / "new" / "res"
    with pytest.raises(RuntimeError, match="simulated crash"):
        cli.main([str(scen), "--out", str(out)])
    assert not (tmp_path / "new").exists()  # neither the directory nor the parent made for it


def test_trace_table_selection(scen, tmp_path, capsys):
    out = tmp_path / "res"
    rc, _, _ = run(capsys, scen, "--out", out, "--quiet", "--set", 'trace.tables=["packets", "ranges"]')
    assert rc == 0
    assert sorted(p.name for p in out.iterdir()) == [
        ".aquasim-output.json",
        "beacon_range_errors.csv",  # the table behind the printed report, always written
        "packets.csv",
        "ranges.csv",
        "summary.json",
    ]


def test_version_and_help(capsys):
    rc, out, _ = run(capsys, "--version")
    m = re.fullmatch(r"aquasim-py \S+ \(Python \S+, SimPy \S+; trace CSV writer: (.+)\)\n", out)
    assert rc == 0 and m, out
    from aquasim_py.trace import csvfmt

    assert m.group(1) == ("pure Python" if csvfmt.fastcsv is None else "compiled (aquasim_py._fastcsv)")
    rc, out, _ = run(capsys, "--help")
    assert rc == 0 and "examples:" in out and "aquasim-py sweep" in out and "--set" in out
    rc, out, _ = run(capsys, "sweep", "--help")
    assert rc == 0 and "--workers" in out and "--scheduler" in out and "examples:" in out


def test_help_lists_every_subcommand_and_help_is_one(capsys):
    from aquasim_py.cli import _COMMANDS

    rc, out, _ = run(capsys, "--help")
    assert rc == 0
    for name in (*_COMMANDS, "help"):
        assert re.search(rf"^  aquasim-py {name} ", out, re.M), name
    assert run(capsys, "help")[:2] == (0, out)
    for name in _COMMANDS:
        rc, page, _ = run(capsys, "help", name)
        assert rc == 0 and page.startswith(f"usage: aquasim-py {name}"), name
    rc, _, err = run(capsys, "help", "nosuch")
    assert rc == 2 and err.count("\n") == 1 and "no command 'nosuch'" in err


def test_a_run_that_heard_nothing_warns_naming_the_key(scen, tmp_path, capsys):
    """max_range_m = 3.5 typed for 3.5 km: every packet is sent and none received."""
    rc, _, err = run(capsys, scen, "--out", tmp_path / "o", "--quiet", "--set", "channel.max_range_m=3.5")
    assert rc == 0
    line = next(x for x in err.splitlines() if "none received" in x)
    assert line.startswith("warning: ") and "channel.max_range_m = 3.5 m" in line and "nearest two nodes" in line
    rc, _, err = run(capsys, scen, "--out", tmp_path / "p", "--quiet")
    assert rc == 0 and "none received" not in err


def test_real_subprocess(scen, tmp_path):
    exe = Path(sys.executable).parent / "aquasim-py"
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "aquasim_py.cli"]
    env = {**os.environ, "COLUMNS": "120"}
    bad = subprocess.run(
        cmd + [str(scen), "--set", "nodes.1.count=0", "--out", str(tmp_path / "x")],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
        check=False,
    )
    assert bad.returncode == 2
    assert bad.stderr.splitlines() == [f"error: {scen}: nodes[1].count: must be >= 1 (got 0)"]
    assert not (tmp_path / "x").exists()
    good = subprocess.run(
        cmd + [str(scen), "--out", str(tmp_path / "y")],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
        check=False,
    )
    assert good.returncode == 0, good.stderr
    assert re.search(r"│   range_rmse \(m\) +│", good.stdout) and (tmp_path / "y" / "summary.json").exists()


def test_progress_bar_follows_simulated_time(scen, tmp_path, capsys, monkeypatch):
    from aquasim_py import kernel

    seen: list[tuple[float, float]] = []
    real = kernel.Simulation.run

    def spy(self, until, progress=None):
        def p(t, u):
            seen.append((t, u))
            progress(t, u)

        return real(self, until, progress=p if progress is not None else None)

    monkeypatch.setattr(kernel.Simulation, "run", spy)
    monkeypatch.setattr(cli.common, "_progress_wanted", lambda quiet: not quiet)  # as on a terminal
    assert run(capsys, scen, "--out", tmp_path / "a")[0] == 0
    times = [t for t, _ in seen]
    assert len(times) >= 50 and times == sorted(times) and seen[-1] == (60.0, 60.0)
    seen.clear()
    assert run(capsys, scen, "--out", tmp_path / "b", "--quiet")[0] == 0
    assert seen == []
