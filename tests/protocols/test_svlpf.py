"""SVL-PF as a network: requests, ToA reports, fusion estimators, obstacle diagnosis end to end."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

import aquasim_py
from aquasim_protocols.svlpf.metrics import step_errors
from aquasim_py import metrics, scenario

ROOT = Path(__file__).resolve().parents[2]
SHORT = ["simulation.duration_s=5.9", 'nodes.0.params.cache="memory"']


def _run(path: str, *sets: str, seed: int = 3):
    # the scenario as written (= its empty variant "svlpf"); the [variants] tables are dropped
    # so that this also runs where the loader does not know variants yet
    raw = tomllib.loads((ROOT / path).read_text())
    raw.pop("variants", None)
    sc = scenario.load_dict(raw, ROOT / path, overrides=[*SHORT, *sets], seed=seed)
    sim = scenario.build(sc)
    sim.run(sc.simulation.duration_s)
    frames = sim.trace.frames()
    return frames, metrics.summarize(frames, sc.protocols())


@pytest.mark.slow
def test_every_frame_is_estimated_by_every_algorithm():
    frames, m = _run("scenarios/svlpf.toml", 'nodes.0.params.also=["toa_pf", "lssvr_pf", "consensus"]')
    e = step_errors(frames)
    assert sorted(e["algorithm"].unique()) == ["consensus", "lssvr_pf", "svlpf", "toa_pf"]
    assert (e.groupby("algorithm")["k"].apply(list) == [[1, 2, 3, 4, 5]] * 4).all()
    assert m["svlpf.frames"] == 5 and np.isfinite(m["svlpf.accumulated_error_m"])


@pytest.mark.exact
def test_an_estimator_alone_gives_what_it_gives_beside_others():
    beside, m = _run("scenarios/svlpf.toml", 'nodes.0.params.algorithm="consensus"', 'nodes.0.params.also=["toa_pf"]')
    alone, m2 = _run("scenarios/svlpf.toml", 'nodes.0.params.algorithm="toa_pf"')
    a = step_errors(alone)
    e = step_errors(beside)
    b = e[e["algorithm"] == "toa_pf"].reset_index(drop=True)
    assert len(a) == 5
    np.testing.assert_array_equal(a[["x", "y", "z"]].to_numpy(), b[["x", "y", "z"]].to_numpy())
    assert m2["svlpf.accumulated_error_m"] == m["svlpf.toa_pf.accumulated_error_m"]


def test_same_seed_same_trace_and_sensors_report_every_request():
    f1, _ = _run("scenarios/svlpf_gaussian.toml")
    f2, _ = _run("scenarios/svlpf_gaussian.toml")
    for name in ("svlpf", "packets"):
        assert f1[name].equals(f2[name])
    sv = f1["svlpf"]
    assert (sv["n_reports"] == 20).all()  # the TDMA uplink loses nothing
    pk = f1["packets"]
    assert not (pk["event"] == "drop").any()


def _ids(cell) -> set[int]:
    return {int(i) for i in str(cell).split() if i.isdigit()}


def test_diagnosis_flags_exactly_the_obstructed_selected_links():
    # Scenario 2's obstacles (30 dB, half-normal 25 % excess delay per packet) on three given
    # links; the diagnosis sees them only through the reported (noisy, 1 dB) SNR estimates
    obstructed = {3, 6, 12}
    links = "[" + ", ".join(f"[1, {i}]" for i in sorted(obstructed)) + "]"
    frames, _ = _run(
        "scenarios/svlpf_obstructed.toml",
        "channel.obstacles.probability=0.0",
        f"channel.obstacles.links={links}",
        "simulation.duration_s=30.9",
        'nodes.0.params.diagnosis="excess"',
    )
    sv = frames["svlpf"]
    expect = [obstructed & _ids(s) for s in sv["selected"]]
    assert sum(map(len, expect)) > 0
    assert [_ids(f) for f in sv["flagged"]] == expect
    assert sv["n_flagged"].tolist() == [len(e) for e in expect]


def test_diagnosis_as_printed_flags_every_selected_link():
    frames, _ = _run("scenarios/svlpf.toml")
    sv = frames["svlpf"]
    assert [_ids(f) for f in sv["flagged"]] == [_ids(s) for s in sv["selected"]]


def test_no_obstacles_means_no_flags_and_the_lssvr_observation():
    """With the repaired diagnosis (eq 25 on the excess loss): the printed one flags all."""
    frames, m = _run(
        "scenarios/svlpf_gaussian.toml", 'nodes.0.params.also=["lssvr_pf"]', 'nodes.0.params.diagnosis="excess"'
    )
    assert m["svlpf.mean_flagged"] == 0.0
    sv = frames["svlpf"]
    a, b = sv[sv["algorithm"] == "svlpf"], sv[sv["algorithm"] == "lssvr_pf"]
    assert (a["iterations"] == 1).all()
    cols = ["obs_x", "obs_y", "obs_z"]
    np.testing.assert_array_equal(a[cols].to_numpy(), b[cols].to_numpy())


@pytest.mark.skipif(not hasattr(aquasim_py, "run_scenario"), reason="variants land with run_scenario")
def test_variants_run_each_algorithm():
    for v in ("svlpf", "toa_pf", "lssvr_pf", "consensus_own", "svlpf_repaired"):
        r = aquasim_py.run_scenario(ROOT / "scenarios/svlpf.toml", variant=v, overrides=SHORT)
        assert r.metrics["svlpf.frames"] == 5
