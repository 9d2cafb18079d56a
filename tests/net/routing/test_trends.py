"""The routing papers' published trends on shortened sweeps of the shipped scenarios (slow: about
ten minutes of two cores; the sweeps behind the documented verdicts: docs/routing.md, "The published trends")."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

from aquasim_py import cli

ROOT = Path(__file__).resolve().parents[3]


def _trends():
    spec = importlib.util.spec_from_file_location("routing_trends", ROOT / "tools" / "routing_trends.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["routing_trends"] = mod
    spec.loader.exec_module(mod)
    return mod


SHORT = ["--set", "simulation.duration_s=1200", "--set", "nodes.2.params.stop_s=1000", "--set", "sweep.runs=2"]


@pytest.mark.slow
def test_dbr_rises_with_density_and_flooding_sends_the_most_copies(tmp_path):
    out = tmp_path / "compare"
    grid = 'sweep.grid={variant=["flooding", "dbr"], "nodes.1.count"=[86, 286, 486]}'
    rc = cli.main(
        ["sweep", str(ROOT / "scenarios/routing_compare.toml"), *SHORT, "--set", grid, "--out", str(out), "--quiet"]
    )
    assert rc == 0
    verdicts = {v.claim: v.verdict for v in _trends().check(out, None)}
    assert verdicts["DBR's delivery ratio rises with node density"] == "agrees"
    assert verdicts["flooding sends the most copies per delivered packet"] == "agrees"
    assert verdicts["flooding costs the most energy per delivered packet"] in ("agrees", "disagrees")


@pytest.mark.slow
def test_vbf_delivers_more_through_a_wider_pipe(tmp_path):
    out = tmp_path / "radius"
    grid = 'sweep.grid={variant=["vbf"], "nodes.2.routing_params.radius_m"=[25.0, 100.0, 200.0]}'
    rc = cli.main(
        ["sweep", str(ROOT / "scenarios/vbf_radius.toml"), *SHORT, "--set", grid, "--out", str(out), "--quiet"]
    )
    assert rc == 0
    trends = _trends()
    import pandas as pd

    runs = pd.read_csv(out / "sweep.csv")
    up, _ = trends.rises(trends.points(runs, trends.RADIUS, "net.pdr"), "vbf", trends.RADIUS)
    assert up
