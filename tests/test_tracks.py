"""Trackers' tracks as Stone Soup tracks and ground truth, OSPA / GOSPA beside our RMSE (issue 35 item 9)."""

from __future__ import annotations

import builtins
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from aquasim_py import cli, trace, tracks

ROOT = Path(__file__).resolve().parents[1]


def _mswpf_tables(errors: list[float], missed: tuple[int, ...] = ()) -> dict[str, pd.DataFrame]:
    """An MSWPF-like run: the target moves along x at 1 m/s; step k at t = 10 + k s is logged
    ``errors[k]`` m off in y, except the ``missed`` steps."""
    t = np.arange(0.0, 40.0, 1.0)
    pos = pd.DataFrame({"time": t, "node": 2, "x": t, "y": 0.0, "z": 50.0, "vx": 1.0, "vy": 0.0, "vz": 0.0})
    steps = [
        {
            "time": 10.5 + k,
            "node": 1,
            "protocol": "mswpf",
            "step": k,
            "t_step": 10.0 + k,
            "x": 10.0 + k,
            "y": e,
            "z": 50.0,
        }
        for k, e in enumerate(errors)
        if k not in missed
    ]
    nodes = pd.DataFrame({"node": [0, 1, 2], "role": ["ordinary", "sink", "target"], "protocol": "mswpf", "group": "g"})
    return {"positions": pos, "mswpf_steps": pd.DataFrame(steps), "nodes": nodes}


def test_track_data_keeps_the_missed_steps():
    (tr,) = tracks.track_data(_mswpf_tables([1.0, 2.0, 30.0, 3.0], missed=(1,)))
    assert tr.name == "mswpf" and list(tr.time) == [10.0, 11.0, 12.0, 13.0]
    assert list(tr.logged) == [True, False, True, True]
    assert np.allclose(tr.truth, [[10, 0, 50], [11, 0, 50], [12, 0, 50], [13, 0, 50]])
    assert tr.rmse() == pytest.approx(math.sqrt((1 + 900 + 9) / 3))


def test_stonesoup_scores_match_the_closed_form():
    pytest.importorskip("stonesoup")
    errors = [1.0, 2.0, 30.0, 3.0]
    (tr,) = tracks.track_data(_mswpf_tables(errors, missed=(1,)))
    track, truth = tracks.to_stonesoup(tr)
    assert len(track) == 3 and len(truth) == 4
    assert truth[0].timestamp == tracks.EPOCH + pd.Timedelta(seconds=10).to_pytimedelta()
    s = tracks.scores([tr], c=10.0, p=2).iloc[0]
    # one target, one track: OSPA per step is min(d, c), and c for a missed step
    assert s["ospa_mean_m"] == pytest.approx(np.mean([1.0, 10.0, 10.0, 3.0]))
    # GOSPA (alpha = 2): d when d < c, else (c^p / 2 + c^p / 2)^(1/p) = c; a missed step c / 2^(1/p)
    assert s["gospa_mean_m"] == pytest.approx(np.mean([1.0, 10.0 / math.sqrt(2), 10.0, 3.0]))
    assert (s["steps"], s["missed"]) == (4, 1) and s["rmse_m"] == pytest.approx(tr.rmse())


def _scored_by_stonesoup(run: Path) -> None:
    """A run's report has OSPA and GOSPA from Stone Soup beside our RMSE of the same estimates."""
    page = (run / "report.html").read_text()
    assert "Tracks scored by Stone Soup" in page and "ospa_mean_m" in page and "gospa_mean_m" in page
    (tr,) = tracks.track_data(trace.load(run))
    ours = json.loads((run / "summary.json").read_text())["metrics"]["mswpf.rmse_m"]
    assert tr.rmse() == pytest.approx(ours, rel=1e-12)  # the same estimates and truth as the protocol's metric
    assert f"mswpf.rmse_m = {ours:.4g}" in page


def test_mswpf_2d_report_has_ospa_and_gospa(tmp_path):
    pytest.importorskip("stonesoup")
    out = tmp_path / "mswpf"
    argv = [str(ROOT / "scenarios" / "mswpf_2d.toml"), "--variant", "gw", "--out", str(out), "--quiet", "--report"]
    assert cli.main([*argv, "--set", "simulation.duration_s=50"]) == 0  # steps from 45 s on
    _scored_by_stonesoup(out)


@pytest.mark.slow  # the paper's 2-D set-up, every variant (83 nodes each), with reports
def test_mswpf_2d_variants_report_has_ospa_and_gospa_of_every_variant(tmp_path):
    pytest.importorskip("stonesoup")
    out = tmp_path / "mswpf"
    argv = [str(ROOT / "scenarios" / "mswpf_2d.toml"), "--out", str(out), "--quiet", "--report"]
    assert cli.main([*argv, "--set", "simulation.duration_s=50"]) == 0
    assert "Tracks scored by Stone Soup, every variant" in (out / "report.html").read_text()
    for v in ("gw", "ew", "bw"):
        _scored_by_stonesoup(out / v)


def test_without_stonesoup_the_report_says_how_to_get_it(monkeypatch):
    real = builtins.__import__

    def no_stonesoup(name, *a, **kw):
        if name.startswith("stonesoup"):
            raise ImportError("No module named 'stonesoup'")
        return real(name, *a, **kw)

    monkeypatch.setattr(builtins, "__import__", no_stonesoup)
    html = tracks.report_section(_mswpf_tables([1.0, 2.0]), {})
    assert "pip install 'aquasim-py[stonesoup]'" in html
    assert tracks.report_section({"nodes": _mswpf_tables([1.0])["nodes"]}, {}) == ""  # no steps table: no section


def test_svlpf_and_ramezani_tracks_agree_with_their_protocols(tmp_path):
    # SVL-PF: truth at the request's true send time (packets tx row); the same errors as its metrics
    sv = tmp_path / "svlpf"
    argv = [str(ROOT / "scenarios" / "svlpf.toml"), "--variant", "svlpf", "--out", str(sv), "--quiet"]
    assert cli.main([*argv, "--set", "simulation.duration_s=30"]) == 0
    (tr,) = tracks.track_data(trace.load(sv))
    d = np.linalg.norm(tr.est[tr.logged] - tr.truth[tr.logged], axis=1)
    ours = json.loads((sv / "summary.json").read_text())["metrics"]
    assert tr.name == "svlpf algorithm=svlpf" and d.mean() == pytest.approx(ours["svlpf.mean_error_m"], rel=1e-12)
    # Ramezani tracking: each target tracks itself (one track per node and model), truth the kernel's
    ra = tmp_path / "ramezani"
    argv = [str(ROOT / "scenarios" / "ramezani_tracking.toml"), "--out", str(ra), "--quiet"]
    assert cli.main([*argv, "--set", "simulation.duration_s=200"]) == 0
    found = tracks.track_data(trace.load(ra))
    assert [t.name for t in found] == ["ramezani node=4 model=essp", "ramezani node=5 model=assp"]
    est = trace.load(ra)["estimates"]
    for t, node in zip(found, (4, 5)):
        err = est[est["node"] == node].sort_values("frame")["error"].to_numpy(float)
        assert np.allclose(np.linalg.norm(t.est[t.logged] - t.truth[t.logged], axis=1), err, rtol=1e-12, atol=1e-9)
