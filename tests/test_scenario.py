"""Scenario loading, overrides, validation messages and building."""

from __future__ import annotations

import dataclasses
import math
import re
import tomllib
from pathlib import Path

import numpy as np
import pytest

from aquasim_py import scenario
from aquasim_py.channel import ssp as ssp_mod
from aquasim_py.scenario import ScenarioError

BASE = """\
[simulation]
duration_s = 30.0
seed = 5

[environment]
volume = { lo = [0.0, 0.0, 0.0], hi = [1000.0, 800.0, 100.0] }

[[nodes]]
role = "anchor"
protocol = "beacon"
placement = { kind = "explicit", positions = [[0.0, 0.0, 5.0], [1000.0, 800.0, 5.0]] }

[[nodes]]
name = "field"
role = "ordinary"
count = 50
protocol = "beacon"
placement = { kind = "uniform", lo = [100.0, 100.0, 10.0], hi = [900.0, 700.0, 90.0] }
"""


@pytest.fixture
def base(tmp_path: Path) -> Path:
    p = tmp_path / "s.toml"
    p.write_text(BASE)
    return p


def err_of(path: Path, *overrides: str) -> ScenarioError:
    with pytest.raises(ScenarioError) as ei:
        scenario.load(path, overrides=list(overrides))
    return ei.value


# --------------------------------------------------------------------------- key paths and values
@pytest.mark.parametrize(
    "text, loc",
    [
        ("a.b.c", ["a", "b", "c"]),
        ("nodes.1.count", ["nodes", 1, "count"]),
        ("nodes[1].count", ["nodes", 1, "count"]),
        ("nodes[0].placement.positions[2]", ["nodes", 0, "placement", "positions", 2]),
    ],
)
def test_key_path_parse(text, loc):
    assert scenario.parse_key_path(text) == loc


def test_key_path_format():
    assert scenario.format_key_path(["nodes", 1, "count"]) == "nodes[1].count"
    assert scenario.format_key_path(["simulation", "seed"]) == "simulation.seed"


@pytest.mark.parametrize("bad", ["", "a..b", ".a", "a.", "a[x]"])
def test_key_path_malformed(bad):
    with pytest.raises(ValueError):
        scenario.parse_key_path(bad)


@pytest.mark.parametrize(
    "text, value",
    [
        ("5", 5),
        ("1.5e3", 1500.0),
        ('"x y"', "x y"),
        ("[1, 2]", [1, 2]),
        ("{a = 1}", {"a": 1}),
        ("true", True),
        ("plain words", "plain words"),
        ("constant", "constant"),
    ],
)
def test_override_values_are_toml_with_string_fallback(text, value):
    assert scenario.parse_value(text) == value


def test_override_sets_nested_and_indexed_values():
    data = {"nodes": [{"count": 1}, {"count": 2}]}
    scenario.apply_override(data, "nodes.1.count", 7)
    scenario.apply_override(data, "a.b.c", "x")
    scenario.apply_override(data, "nodes[-1].params.k", 1.5)
    assert data == {"nodes": [{"count": 1}, {"count": 7, "params": {"k": 1.5}}], "a": {"b": {"c": "x"}}}


def test_override_into_a_scalar_is_an_error():
    with pytest.raises(ScenarioError, match=r"cannot set a key inside simulation\.seed"):
        scenario.apply_override({"simulation": {"seed": 1}}, "simulation.seed.x", 1)


# --------------------------------------------------------------------------- valid scenarios
def test_load_fills_defaults_and_resolves(base):
    sc = scenario.load(base)
    assert sc.simulation.seed == 5 and sc.simulation.duration_s == 30.0
    assert sc.nodes[0].count == 2  # from the explicit positions
    assert sc.nodes[0].name == "group0" and sc.nodes[1].name == "field"
    assert sc.nodes[0].params["period_s"] == 10.0  # the protocol's default, resolved
    assert sc.environment.sound_speed.model == "constant"
    assert sc.path == base and sc.name == "s"


def test_resolved_scenario_round_trips(base):
    sc = scenario.load(base, overrides=["nodes.1.count=7"], seed=99)
    d = sc.to_dict()
    assert d["simulation"]["seed"] == 99 and d["nodes"][1]["count"] == 7
    again = scenario.load_dict(d, base)
    assert again.to_dict() == d


def test_channel_defaults_match_the_kernel():
    from aquasim_py.channel.config import ChannelConfig
    from aquasim_py.scenario_schema import ChannelSpec

    spec = ChannelSpec()
    cfg = ChannelConfig()
    for f in dataclasses.fields(cfg):
        if f.name == "obstacles":  # a table in the schema, a dataclass in the kernel; both None
            assert spec.obstacles is None and cfg.obstacles is None
            continue
        mine = getattr(spec.noise, f.name) if f.name in ("shipping", "wind_mps") else getattr(spec, f.name)
        assert mine == getattr(cfg, f.name), f.name


def test_integer_accepted_for_float_but_nothing_else_converted(base):
    assert scenario.load(base, overrides=["simulation.duration_s=20"]).simulation.duration_s == 20.0
    assert "expected a number" in err_of(base, "simulation.duration_s=true").message
    assert "expected an integer" in err_of(base, 'nodes.1.count="5"').message
    assert "expected an integer (got float 2.5)" in err_of(base, "nodes.1.count=2.5").message


# --------------------------------------------------------------------------- errors name the key
@pytest.mark.parametrize(
    "override, key, pattern",
    [
        ("simulation.duration_s=0", "simulation.duration_s", r"must be > 0"),
        ("simulation.duration_s=-inf", "simulation.duration_s", r"finite"),
        ("environment.volume.lo=[0, 0]", "environment.volume.lo", r"at least 3"),
        ("environment.volume.hi=[1000, 800, -1]", "environment.volume", r"lo must be below hi"),
        ("environment.bottom_m=50", "environment", r"shallower than the volume"),
        (
            'environment.sound_speed={model="layered", depths_m=[0, 10, 20], speeds_mps=[1500, 1490]}',
            "environment.sound_speed",
            r"differ in length",
        ),
        (
            'environment.sound_speed={model="layered", depths_m=[5, 10], speeds_mps=[1500, 1501]}',
            "environment.sound_speed",
            r"start at 0",
        ),
        (
            'environment.sound_speed={model="isogradient"}',
            "environment.sound_speed.gradient_per_s",
            "required key missing",
        ),
        ("environment.sound_speed={speed_mps=1500}", "environment.sound_speed.model", "required key missing"),
        ('environment.sound_speed={model="ctd", file="x.csv", depth_m=[0, 1]}', "environment.sound_speed", "not both"),
        ('environment.sound_speed={model="ctd", file="nope.csv"}', "environment.sound_speed.file", "not found"),
        ('nodes.1.placement={kind="grid", shape=[2, 2, 2]}', "nodes[1].count", r"differs from the grid"),
        ('nodes.1.placement={kind="spiral"}', "nodes[1].placement.kind", "unknown placement kind 'spiral'"),
        ("nodes.1.placement.hi=[900, 700, 500]", "nodes[1].placement.hi", "outside the volume"),
        ('nodes.1.name="group0"', "nodes[1].name", r"already the name of nodes\[0\]"),
        ('nodes.1.mobility={model="teleport"}', "nodes[1].mobility.model", "must be one of"),
        (
            'nodes.1.mobility={model="constant_velocity", velocty=[1, 0, 0]}',
            "nodes[1].mobility.velocty",
            "did you mean 'velocity'",
        ),
        (
            'nodes.1.mobility={model="constant_velocity", velocity=[1, nan, 0]}',
            "nodes[1].mobility.velocity[1]",
            "finite",
        ),
        ("nodes.1.clock.skew_std_ppm=-1", "nodes[1].clock.skew_std_ppm", r"must be >= 0"),
        ("nodes.1.sensors.depth_noise=1", "nodes[1].sensors.depth_noise", "did you mean 'depth_noise_std_m'"),
        ('channel.collision="loud"', "channel.collision", "must be one of"),
        ('trace.format="xlsx"', "trace.format", "must be one of"),
        ("sweep.runs=0", "sweep.runs", r"must be >= 1"),
        ('sweep.grid={"channel.bitrate_bps"=[]}', "sweep.grid.channel.bitrate_bps", "at least 1"),
        (
            'sweep.grid={"channel.bitrate_bps"=[100, -5]}',
            'sweep.grid."channel.bitrate_bps"',
            r"value -5: channel.bitrate_bps: must be > 0",
        ),
        ('sweep.grid={"channel.bitrat"=[100]}', 'sweep.grid."channel.bitrat"', "unknown key"),
        ('sweep.grid={"simulation.seed"=[1, 2]}', 'sweep.grid."simulation.seed"', "set sweep.runs instead"),
        ('sweep.grid={"sweep.runs"=[1, 2]}', 'sweep.grid."sweep.runs"', "its own settings"),
        ("metrics.percentiles=[50, 101]", "metrics.percentiles[1]", r"must be <= 100"),
    ],
)
def test_error_names_key_path(base, override, key, pattern):
    e = err_of(base, override)
    assert e.file == str(base)
    assert e.key_path == key, str(e)
    assert re.search(pattern, e.message), str(e)


def test_error_str_is_one_line(base):
    e = err_of(base, "nodes.1.count=-3")
    assert str(e) == f"{base}: nodes[1].count: must be >= 1 (got -3)"
    assert "\n" not in str(e)


# --------------------------------------------------------------------------- CTD profiles
def test_ctd_from_csv_file_relative_to_scenario(tmp_path):
    d = np.array([2.0, 50.0, 100.0, 200.0])
    T = np.array([20.0, 15.0, 10.0, 6.0])
    S = np.array([35.0, 35.1, 35.0, 34.9])
    sub = tmp_path / "casts"
    sub.mkdir()
    rows = "\n".join(f"{a},{b},{c}" for a, b, c in zip(d, T, S))
    (sub / "cast.csv").write_text("depth_m,temperature_c,salinity_psu\n" + rows + "\n")
    scen = tmp_path / "s.toml"
    scen.write_text(
        BASE.replace(
            "hi = [1000.0, 800.0, 100.0] }",
            'hi = [1000.0, 800.0, 100.0] }\nsound_speed = { model = "ctd", file = "casts/cast.csv" }',
        )
    )
    sc = scenario.load(scen)
    prof = scenario.make_ssp(sc)
    inline = ssp_mod.from_ctd(d, T, S)
    z = np.linspace(0, 200, 17)
    np.testing.assert_array_equal(prof.speed(z), inline.speed(z))
    # the CSV is read once at load; the resolved scenario still points at the file
    assert sc.to_dict()["environment"]["sound_speed"]["file"] == "casts/cast.csv"


def test_ctd_file_without_needed_column(tmp_path):
    (tmp_path / "cast.csv").write_text("depth_m,temp\n0,10\n10,9\n")
    scen = tmp_path / "s.toml"
    scen.write_text(
        BASE.replace(
            "hi = [1000.0, 800.0, 100.0] }",
            'hi = [1000.0, 800.0, 100.0] }\nsound_speed = { model = "ctd", file = "cast.csv" }',
        )
    )
    e = err_of(scen)
    assert e.key_path == "environment.sound_speed.file" and "temperature_c" in e.message


@pytest.mark.parametrize(
    "table, cls, attrs",
    [
        ('{model="constant", speed_mps=1490}', ssp_mod.Constant, {"speed_mps": 1490.0}),
        (
            '{model="isogradient", surface_speed_mps=1480, gradient_per_s=0.02}',
            ssp_mod.Isogradient,
            {"surface_speed": 1480.0, "gradient": 0.02},
        ),
        ('{model="munk", axis_depth_m=1000}', ssp_mod.Munk, {"axis_depth": 1000.0}),
    ],
)
def test_profiles_built_from_tables(base, table, cls, attrs):
    prof = scenario.make_ssp(scenario.load(base, overrides=[f"environment.sound_speed={table}"]))
    assert isinstance(prof, cls)
    for k, v in attrs.items():
        assert getattr(prof, k) == v


# --------------------------------------------------------------------------- building
def test_grid_placement_positions():
    g = scenario.load_dict(
        tomllib.loads(BASE),
        None,
        overrides=[
            ("nodes.1.placement", {"kind": "grid", "shape": [3, 2, 1], "lo": [100, 100, 10], "hi": [900, 700, 90]}),
            ("nodes.1.count", 6),
        ],
    ).nodes[1]
    pos = scenario.placement_positions(g, [0, 0, 0], [1000, 800, 100], np.random.default_rng(0))
    expect = [[x, y, 50.0] for x in (100.0, 500.0, 900.0) for y in (100.0, 700.0)]
    np.testing.assert_array_equal(pos, expect)


def test_build_places_nodes_and_draws_clocks(base):
    sc = scenario.load(
        base, overrides=["nodes.1.count=400", "nodes.1.clock={skew_ppm=5, skew_std_ppm=20, offset_std_s=0.01}"]
    )
    sim = scenario.build(sc)
    assert len(sim.nodes) == 402
    p = sim.positions(0.0)
    np.testing.assert_array_equal(p[:2], [[0.0, 0.0, 5.0], [1000.0, 800.0, 5.0]])
    lo, hi = np.array([100.0, 100.0, 10.0]), np.array([900.0, 700.0, 90.0])
    assert np.all(p[2:] >= lo) and np.all(p[2:] <= hi)
    skews = np.array([sim.clock_of(i).skew for i in range(2, 402)])
    offsets = np.array([sim.clock_of(i).offset for i in range(2, 402)])
    # N(5, 20) ppm and N(0, 10 ms), 400 draws: 5-sigma bounds on mean and std
    assert abs(skews.mean() * 1e6 - 5.0) < 5 * 20 / math.sqrt(400)
    assert abs(skews.std() * 1e6 / 20.0 - 1.0) < 5 / math.sqrt(2 * 400)
    assert abs(offsets.mean()) < 5 * 0.01 / math.sqrt(400)
    assert all(sim.clock_of(i).skew == 0.0 and sim.clock_of(i).offset == 0.0 for i in range(2))
    # the default uniform draws are uniform: the mean x within 5 sigma of the middle
    sd = (hi - lo) / math.sqrt(12) / math.sqrt(400)
    assert np.all(np.abs(p[2:].mean(axis=0) - (lo + hi) / 2) < 5 * sd)


def test_groups_draw_from_their_own_streams(base):
    a = scenario.build(scenario.load(base)).positions(0.0)
    extra = (
        'nodes=[{role="anchor", protocol="beacon", placement={kind="explicit", positions=[[0.0, 0.0, 5.0], '
        '[1000.0, 800.0, 5.0]]}}, {name="other", role="ordinary", count=3, protocol="beacon", '
        'placement={kind="uniform"}}, {name="field", role="ordinary", count=50, protocol="beacon", '
        'placement={kind="uniform", lo=[100.0, 100.0, 10.0], hi=[900.0, 700.0, 90.0]}}]'
    )
    b = scenario.build(scenario.load(base, overrides=[extra])).positions(0.0)
    # adding a group before "field" leaves field's draws unchanged (streams keyed by name)
    np.testing.assert_array_equal(a[2:], b[5:])
    c = scenario.build(scenario.load(base, seed=6)).positions(0.0)
    assert not np.array_equal(a[2:], c[2:])


def test_mobility_built_with_params(base):
    sc = scenario.load(
        base,
        overrides=[
            'nodes.1.mobility={model="constant_velocity", velocity=[0.5, 0.0, 0.0]}',
            "nodes.1.placement.hi=[800, 700, 90]",
        ],
    )
    sim = scenario.build(sc)
    np.testing.assert_allclose(sim.positions(10.0)[2:] - sim.positions(0.0)[2:], [[5.0, 0.0, 0.0]] * 50)


def test_mobility_constructor_errors_become_scenario_errors(base):
    sc = scenario.load(base, overrides=['nodes.1.mobility={model="random_walk", speed_min=2.0, speed_max=1.0}'])
    with pytest.raises(ScenarioError) as ei:
        scenario.build(sc)
    assert ei.value.key_path == "nodes[1].mobility" and "speed_min" in ei.value.message


@pytest.mark.parametrize(
    "old, new, key",
    [
        ("duration_s = 30.0", "duraton_s = 30.0", "simulation.duration_s"),  # a key
        ("[environment]", "[environmnt]", "environment"),  # a whole table
        ('placement = { kind = "explicit"', 'placemnt = { kind = "explicit"', "nodes[0].placement"),  # in a list
    ],
)
def test_missing_key_names_the_misspelling_beside_it(tmp_path: Path, old: str, new: str, key: str) -> None:
    p = tmp_path / "m.toml"
    p.write_text(BASE.replace(old, new, 1))
    e = err_of(p)
    misspelled = new.split()[0].strip("[]")
    assert (
        str(e)
        == f"{p}: {key}: required key missing (found {misspelled!r}: did you mean {key.split('.')[-1].split('[')[0]!r}?)"
    )


def test_missing_key_without_a_lookalike_says_only_missing(tmp_path: Path) -> None:
    p = tmp_path / "m.toml"
    p.write_text(BASE.replace("duration_s = 30.0", "").replace("seed = 5", "seed = 5\nnotes = 'x'"))
    assert str(err_of(p)).endswith("simulation.duration_s: required key missing")
