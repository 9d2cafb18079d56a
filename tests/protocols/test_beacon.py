"""Beacon ranging against closed forms computed here from the scenario's own geometry."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from aquasim_protocols.beacon import BeaconNode, range_errors
from aquasim_py import cli, metrics, scenario, trace

ANCHORS = np.array([[0.0, 0.0, 10.0], [1500.0, 0.0, 30.0], [0.0, 1200.0, 50.0]])
SENSORS = np.array([[400.0, 300.0, 80.0], [1100.0, 900.0, 20.0]])
C = 1500.0


def toml_vec(a: np.ndarray) -> str:
    return "[" + ", ".join("[" + ", ".join(repr(float(v)) for v in row) + "]" for row in a) + "]"


def make(
    tmp_path: Path, *, speed=C, sensor_clock="", channel="", mobility="", duration=60.0, interval=1.0
) -> scenario.Scenario:
    text = f"""
[simulation]
duration_s = {duration}
seed = 4

[environment]
volume = {{ lo = [0.0, 0.0, 0.0], hi = [1500.0, 1500.0, 100.0] }}
sound_speed = {{ model = "constant", speed_mps = {speed} }}

[channel]
loss_model = "none"
collision = "none"
{channel}

[trace]
position_interval_s = {interval}

[[nodes]]
role = "anchor"
protocol = "beacon"
placement = {{ kind = "explicit", positions = {toml_vec(ANCHORS)} }}
params = {{ period_s = 5.0, nominal_speed_mps = {C} }}

[[nodes]]
role = "ordinary"
protocol = "beacon"
placement = {{ kind = "explicit", positions = {toml_vec(SENSORS)} }}
params = {{ nominal_speed_mps = {C} }}
{sensor_clock}
{mobility}
"""
    p = tmp_path / "b.toml"
    p.write_text(text)
    return scenario.load(p)


def run(sc: scenario.Scenario) -> dict:
    sim = scenario.build(sc)
    sim.run(sc.simulation.duration_s)
    return sim.trace.frames()


def geometric(ranges) -> np.ndarray:
    """True distances from this file's coordinates (node ids: anchors 0-2, sensors 3-4)."""
    a = ANCHORS[ranges["anchor"].to_numpy()]
    s = SENSORS[ranges["node"].to_numpy() - len(ANCHORS)]
    return np.linalg.norm(s - a, axis=1)


def test_every_listener_hears_every_beacon(tmp_path):
    fr = run(make(tmp_path))
    r = fr["ranges"]
    # 3 anchors x 12 beacons (period 5 s in 60 s) x 2 listeners, minus beacons still in flight at the end
    assert 60 <= len(r) <= 72
    assert set(r["node"]) == {3, 4} and set(r["anchor"]) == {0, 1, 2}
    assert (r.groupby("anchor").size() >= 20).all()


def test_perfect_clocks_and_nominal_speed_give_exact_ranges(tmp_path):
    fr = run(make(tmp_path))
    r = fr["ranges"]
    np.testing.assert_allclose(r["range_m"], geometric(r), rtol=0, atol=1e-6)
    m = BeaconNode.metrics(fr)
    assert abs(m["range_error_mean_m"]) < 1e-6 and m["range_rmse_m"] < 1e-6


def test_listener_clock_offset_adds_offset_times_speed(tmp_path):
    fr = run(make(tmp_path, sensor_clock="clock = { offset_s = 0.002 }"))
    r = fr["ranges"]
    np.testing.assert_allclose(r["range_m"] - geometric(r), 0.002 * C, rtol=0, atol=1e-6)
    assert BeaconNode.metrics(fr)["range_error_mean_m"] == pytest.approx(3.0, abs=1e-6)


def test_listener_clock_skew_grows_with_time(tmp_path):
    skew = 50e-6
    fr = run(make(tmp_path, sensor_clock="clock = { skew_ppm = 50.0 }"))
    r = fr["ranges"]
    d = geometric(r)
    # anchors keep true time, so tx_local is the true send time; local rx = (1 + skew) t_rx
    t_rx = r["tx_local"].to_numpy() + d / C
    np.testing.assert_allclose(r["range_m"] - d, skew * t_rx * C, rtol=0, atol=1e-6)
    e = range_errors(fr)["error_m"].to_numpy()
    np.testing.assert_allclose(e, skew * t_rx * C, rtol=0, atol=1e-6)


def test_sound_speed_mismatch_scales_ranges(tmp_path):
    fr = run(make(tmp_path, speed=1520.0))
    r = fr["ranges"]
    d = geometric(r)
    np.testing.assert_allclose(r["range_m"], d * C / 1520.0, rtol=1e-12, atol=1e-7)


def test_metrics_are_the_statistics_of_the_errors(tmp_path):
    fr = run(
        make(
            tmp_path, sensor_clock="clock = { skew_std_ppm = 40.0, offset_std_s = 1e-3 }", channel="jitter_std_s = 1e-4"
        )
    )
    e = fr["ranges"]["range_m"].to_numpy() - geometric(fr["ranges"])
    m = BeaconNode.metrics(fr)
    assert m["ranges"] == len(e)
    assert m["range_error_mean_m"] == pytest.approx(e.mean(), abs=1e-9)
    assert m["range_error_std_m"] == pytest.approx(e.std(ddof=1), abs=1e-9)
    assert m["range_rmse_m"] == pytest.approx(np.sqrt(np.mean(e**2)), abs=1e-9)
    assert m["range_error_max_abs_m"] == pytest.approx(np.abs(e).max(), abs=1e-9)


def test_moving_listeners_truth_from_trace(tmp_path):
    # straight lines that stay inside the box for the whole run: the positions table is then
    # linear between samples and the interpolated truth is exact
    fr = run(
        make(tmp_path, mobility='mobility = { model = "constant_velocity", velocity = [1.5, -0.5, 0.2] }', interval=2.0)
    )
    r = range_errors(fr)
    assert len(r) > 40
    np.testing.assert_allclose(r["error_m"], 0.0, atol=1e-6)


def test_anchor_position_in_beacon(tmp_path):
    r = run(make(tmp_path))["ranges"]
    got = r[["anchor_x", "anchor_y", "anchor_z"]].to_numpy()
    np.testing.assert_array_equal(got, ANCHORS[r["anchor"].to_numpy()])


def test_anchor_without_position_fix_sends_none(tmp_path):
    sc = make(tmp_path)
    sc = scenario.load_dict(sc.to_dict(), sc.path, overrides=["nodes.0.sensors.position_fix=false"])
    r = run(sc)["ranges"]
    assert len(r) > 0 and np.isnan(r[["anchor_x", "anchor_y", "anchor_z"]].to_numpy()).all()
    # the ranges themselves do not depend on it
    np.testing.assert_allclose(r["range_m"], geometric(r), rtol=0, atol=1e-6)


def test_metrics_from_csv_equal_in_memory(tmp_path):
    fr = run(make(tmp_path, sensor_clock="clock = { skew_std_ppm = 40.0 }", channel="jitter_std_s = 1e-4"))
    trace.write_frames(fr, tmp_path / "t")
    back = trace.load(tmp_path / "t")
    a, b = BeaconNode.metrics(fr), BeaconNode.metrics(back)
    assert a == pytest.approx(b, rel=1e-12)
    assert metrics.summarize(back)["beacon.range_rmse_m"] == pytest.approx(a["range_rmse_m"], rel=1e-12)


def test_shipped_scenario_runs_in_seconds(tmp_path, capsys):
    scen = Path(__file__).resolve().parents[2] / "scenarios" / "beacon.toml"
    t0 = time.process_time()
    rc = cli.main([str(scen), "--out", str(tmp_path / "o"), "--quiet"])
    cpu = time.process_time() - t0
    assert rc == 0, capsys.readouterr().err
    # "a few seconds": CPU time, so a machine loaded by other jobs does not make it flaky
    assert cpu < 10.0
    m = trace.read_summary(tmp_path / "o")["metrics"]
    assert m["beacon.ranges"] > 1000


def test_range_errors_of_a_runs_files_are_shared_and_a_callers_change_stays_its_own(tmp_path):
    """The metrics, the derived table and the report of a run share one range-error frame:
    each caller gets a copy (changing it changes no other's), equal to the frame computed
    afresh from the same tables read as an analyst reads them."""
    from aquasim_py import run_scenario

    sc = make(tmp_path, sensor_clock="clock = { skew_std_ppm = 40.0 }", channel="jitter_std_s = 1e-4")
    res = run_scenario(sc, out=tmp_path / "out", progress=False)
    first = range_errors(res.tables)
    first["error_m"] = 0.0
    again = range_errors(res.tables)
    fresh = range_errors(trace.load(tmp_path / "out"))
    assert len(fresh) and fresh["error_m"].abs().max() > 0.0
    np.testing.assert_array_equal(again.to_numpy(), fresh.to_numpy())
    assert BeaconNode.metrics(res.tables) == BeaconNode.metrics(trace.load(tmp_path / "out"))
