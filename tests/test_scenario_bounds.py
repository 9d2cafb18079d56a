"""Bounds on scenario inputs (issue 20 item 4) and metric failures that keep the run (item 5):
exact one-line errors with exit status 2, warnings for implausible values, cross-field checks."""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from aquasim_py import cli, scenario
from aquasim_py.channel import loss

BASE = """\
[simulation]
duration_s = 30.0
seed = 3

[environment]
volume = { lo = [0.0, 0.0, 0.0], hi = [1000.0, 1000.0, 100.0] }
sound_speed = { model = "constant", speed_mps = 1500.0 }

[[nodes]]
name = "anchors"
role = "anchor"
protocol = "beacon"
placement = { kind = "explicit", positions = [[0.0, 0.0, 10.0], [1000.0, 0.0, 10.0], [0.0, 1000.0, 10.0]] }
params = { period_s = 5.0 }

[[nodes]]
name = "sensors"
role = "ordinary"
count = 2
protocol = "beacon"
placement = { kind = "uniform", lo = [100.0, 100.0, 20.0], hi = [900.0, 900.0, 90.0] }
mobility = { model = "random_walk", speed_min = 0.0, speed_max = 0.5, leg_duration = 10.0 }
"""

RAMEZANI = """\
[simulation]
duration_s = 30.0

[environment]
volume = { lo = [0.0, 0.0, 0.0], hi = [1000.0, 1000.0, 100.0] }

[[nodes]]
name = "anchors"
role = "anchor"
protocol = "ramezani"
placement = { kind = "explicit", positions = [[0.0, 0.0, 10.0], [1000.0, 0.0, 10.0], [0.0, 1000.0, 10.0], [500.0, 500.0, 90.0]] }
params = { anchor_positions = [[0.0, 0.0, 10.0], [1000.0, 0.0, 10.0], [0.0, 1000.0, 10.0], [500.0, 500.0, 90.0]] }

[[nodes]]
name = "target"
role = "target"
protocol = "ramezani"
placement = { kind = "explicit", positions = [[400.0, 400.0, 50.0]] }
params = { anchor_positions = [[0.0, 0.0, 10.0], [1000.0, 0.0, 10.0], [0.0, 1000.0, 10.0], [500.0, 500.0, 90.0]] }
"""


@pytest.fixture
def base(tmp_path: Path) -> Path:
    p = tmp_path / "s.toml"
    p.write_text(BASE)
    return p


def cli_error(capsys: pytest.CaptureFixture[str], path: Path, *sets: str) -> str:
    """Run the CLI with ``--set`` overrides; assert exit 2, one line, nothing written."""
    out = path.parent / "out"
    argv = [str(path), "--quiet", "--out", str(out)]
    for s in sets:
        argv += ["--set", s]
    rc = cli.main(argv)
    err = capsys.readouterr().err
    assert rc == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {path}: "), err
    assert "Traceback" not in err and not out.exists()
    return lines[0][len(f"error: {path}: ") :]


# --------------------------------------------------------------------------- resources
@pytest.mark.parametrize(
    ("sets", "expected"),
    [
        (
            ["nodes.1.count=1000000000"],
            "nodes[1].count: 1e+09 nodes in all groups (limit: 1e+05 nodes, docs/scenarios.md)",
        ),
        (
            ['environment.sound_speed={model="munk", n_layers=1000000000}'],
            "environment.sound_speed.n_layers: 1e+09 layers (limit: 1e+04 layers, docs/scenarios.md)",
        ),
        (
            ["trace.position_interval_s=1e-6"],
            "trace.position_interval_s: 1.5e+08 position rows (5 nodes every 1e-06 s for 30 s, ~9.6 GB) "
            "(limit: 5e+07 position rows, docs/scenarios.md)",
        ),
        (
            ['nodes.1.placement={kind="grid", shape=[2097152, 2097152, 2097152]}', "nodes.1.count=8"],
            "nodes[1].placement.shape: 9.22e+18 nodes (limit: 1e+05 nodes, docs/scenarios.md)",
        ),
        (
            ["sweep.runs=100000", 'sweep.grid={"channel.jitter_std_s" = [0.0, 1e-4]}'],
            "sweep: 2e+05 runs (100000 runs x 2 grid points) (limit: 1e+05 runs, docs/scenarios.md)",
        ),
        (
            ["nodes.1.clock.drift_std_ppm=1.0", "nodes.1.clock.drift_interval_s=1e-9"],
            "nodes[1].clock.drift_interval_s: 6e+10 clock drift steps (limit: 5e+07 clock drift steps, docs/scenarios.md)",
        ),
    ],
)
def test_resource_limits(capsys: pytest.CaptureFixture[str], base: Path, sets: list[str], expected: str) -> None:
    assert cli_error(capsys, base, *sets) == expected


# --------------------------------------------------------------------------- physics
@pytest.mark.parametrize(
    ("sets", "expected"),
    [
        (
            ["nodes.1.clock.skew_ppm=-1e6"],
            "nodes[1].clock.skew_ppm: must be > -1e6 ppm (a skew <= -1 stops or reverses the clock; got -1e+06)",
        ),
        (
            ['environment.sound_speed={model="isogradient", surface_speed_mps=1500.0, gradient_per_s=-20.0}'],
            "environment.sound_speed: sound speed -500 m/s at depth 100 m (must be > 0 in the water column 0-100 m)",
        ),
        (
            ["nodes.1.mobility.speed_max=1600.0"],
            "nodes[1].mobility.speed_max: a node speed of 1600 m/s is not below the slowest sound speed 1500 m/s "
            "(a node would outrun its own signals)",
        ),
        (
            ['nodes.1.mobility={model="constant_velocity", velocity=[1500.0, 0.0, 0.0]}'],
            "nodes[1].mobility.velocity: a node speed of 1500 m/s is not below the slowest sound speed 1500 m/s "
            "(a node would outrun its own signals)",
        ),
        (["channel.follow_radius_m=-1.0"], "channel.follow_radius_m: must be >= 0.0 (got -1.0)"),
    ],
)
def test_physically_impossible(capsys: pytest.CaptureFixture[str], base: Path, sets: list[str], expected: str) -> None:
    assert cli_error(capsys, base, *sets) == expected


@pytest.mark.parametrize(
    ("sets", "expected"),
    [
        (
            ['environment.sound_speed={model="isogradient", surface_speed_mps=1580.0, gradient_per_s=0.5}'],
            "environment.sound_speed (fastest in the water column): value 1630 is outside",
        ),
        (
            ['environment.sound_speed={model="isogradient", surface_speed_mps=1500.0, gradient_per_s=17.0}'],
            "environment.sound_speed.gradient_per_s: value 17 is outside the plausible range [-1, 1]",
        ),
        (
            ["nodes.1.clock.skew_ppm=1e6"],
            "nodes[1].clock.skew_ppm: value 1e+06 is outside the plausible range [-1000, 1000]",
        ),
        (["environment.sound_speed.speed_mps=1300.0"], "environment.sound_speed.speed_mps: value 1300 is outside"),
        (["channel.follow_radius_m=30.0"], "channel.follow_radius_m: value 30 is outside the plausible range [0, 10]"),
    ],
)
def test_implausible_values_warn(base: Path, sets: list[str], expected: str) -> None:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scenario.load(base, overrides=sets)
    msgs = [str(w.message) for w in caught if issubclass(w.category, scenario.ScenarioWarning)]
    hits = [m for m in msgs if m.startswith(f"{base}: {expected}")]
    assert hits, msgs


def test_plausible_scenario_does_not_warn(base: Path) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error", scenario.ScenarioWarning)
        scenario.load(base)


def test_warning_is_one_line_on_stderr_and_the_run_proceeds(capsys: pytest.CaptureFixture[str], base: Path) -> None:
    out = base.parent / "out"
    rc = cli.main([str(base), "--quiet", "--out", str(out), "--set", "nodes.1.clock.skew_ppm=2000.0"])
    err = capsys.readouterr().err
    assert rc == 0
    assert err.strip().splitlines() == [
        f"warning: {base}: nodes[1].clock.skew_ppm: value 2000 is outside the plausible range [-1000, 1000] "
        "(modem clocks drift by tens of ppm)"
    ]
    assert (out / "summary.json").exists()


def test_a_warning_line_is_printed_once_per_command(capsys: pytest.CaptureFixture[str]) -> None:
    """The CLI prints each warning line once, though the scenario is validated again (a variants
    run, once per variant) after something changed the warning filters in between (any
    ``warnings.catch_warnings()``, which makes the "default" filter forget what it showed)."""
    from aquasim_py.cli import _one_line_warnings
    from aquasim_py.errors import ScenarioWarning

    with _one_line_warnings():
        for _variant in range(3):
            warnings.warn(
                "s.toml: x: value 2 is outside the plausible range [0, 1] (why)", ScenarioWarning, stacklevel=1
            )
            with warnings.catch_warnings():
                pass
    assert capsys.readouterr().err.splitlines() == [
        "warning: s.toml: x: value 2 is outside the plausible range [0, 1] (why)"
    ]


# --------------------------------------------------------------------------- types
def test_quoted_numbers_are_errors(capsys: pytest.CaptureFixture[str], base: Path) -> None:
    assert cli_error(capsys, base, 'nodes.1.mobility.speed_max="0.5"') == (
        "nodes[1].mobility.speed_max: expected a number (got string '0.5'; no conversion)"
    )
    assert cli_error(capsys, base, 'nodes.0.params.period_s="5"') == (
        "nodes[0].params.period_s: expected a number (got string '5')"
    )


# --------------------------------------------------------------------------- cross-field
@pytest.mark.parametrize(
    ("sets", "expected"),
    [
        (
            ["nodes.1.params.anchor_ids=[0, 1, 2, 9]"],
            "nodes[1].params.anchor_ids[3]: node id 9 is not a node (ids 0..4)",
        ),
        (
            ["nodes.1.params.anchor_ids=[0, 1, 2, 2]"],
            "nodes[1].params.anchor_ids[3]: node id 2 appears twice (also anchor_ids[2])",
        ),
        (
            ["nodes.1.params.min_anchors=5"],
            "nodes[1].params.min_anchors: 5 is more than the 4 anchors of anchor_positions",
        ),
        (
            ["nodes.0.params.anchor_ids=[0, 1, 2, 4]"],
            "nodes[0].params.anchor_ids: anchor node 3 of this group has no slot (anchor_ids [0, 1, 2, 4])",
        ),
    ],
)
def test_ramezani_cross_checks(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, sets: list[str], expected: str
) -> None:
    p = tmp_path / "r.toml"
    p.write_text(RAMEZANI)
    scenario.load(p)  # the scenario as written is fine
    assert cli_error(capsys, p, *sets) == expected


def test_reference_count_must_fit_the_network(capsys: pytest.CaptureFixture[str], base: Path) -> None:
    sets = ['nodes.1.protocol="stvf"', "nodes.1.params={n_ref = 5}", 'nodes.0.protocol="stvf"', "nodes.0.params={}"]
    assert cli_error(capsys, base, *sets) == (
        "nodes[1].params.n_ref: 5 is more than the 4 other nodes of the network (it could never act)"
    )


# --------------------------------------------------------------------------- item 5
def test_failed_protocol_metric_keeps_the_run(
    capsys: pytest.CaptureFixture[str], base: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from aquasim_py import registry

    cls = registry.get("beacon")

    def boom(c: type, tables: object) -> dict[str, float]:
        raise np.linalg.LinAlgError("Singular matrix")

    monkeypatch.setattr(cls, "metrics", classmethod(boom))
    out = base.parent / "out"
    rc = cli.main([str(base), "--quiet", "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 0
    assert "metrics 'beacon' failed (LinAlgError: Singular matrix)" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["metric_errors"] == {"beacon": "LinAlgError: Singular matrix"}
    assert summary["metrics"]["packets.sent"] > 0
    assert (out / "packets.csv").exists()


def test_path_loss_is_finite_for_colocated_nodes() -> None:
    a = loss.path_loss_db([0.0, 0.5, 1.0, 2.0], 10.0)
    assert np.all(np.isfinite(a))
    # inside the 1 m reference the loss is that at 1 m (0 dB); beyond it unchanged
    assert a[:3].tolist() == [0.0, 0.0, 0.0]
    assert a[3] == pytest.approx(15.0 * math.log10(2.0) + 1e-3 * float(loss.thorp_absorption_db_per_km(10.0)))


def test_infinite_protocol_metric_becomes_nan_with_its_reason() -> None:
    import pandas as pd

    from aquasim_py import metrics

    class Fake:
        name = "fake"

        @classmethod
        def metrics(cls, tables: object) -> dict[str, float]:
            return {"ratio": math.inf, "ok": 1.0}

    errors: dict[str, str] = {}
    m = metrics.summarize({"packets": pd.DataFrame(columns=["event"])}, [Fake], errors=errors)
    assert math.isnan(m["fake.ratio"]) and m["fake.ok"] == 1.0
    assert errors == {"fake.ratio": "non-finite value inf"}
