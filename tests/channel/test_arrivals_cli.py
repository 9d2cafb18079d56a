"""``aquasim-py arrivals`` and the range-dependent ``[environment]`` keys of a scenario."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from aquasim_py import channel
from aquasim_py.cli import main
from aquasim_py.scenario import load
from aquasim_py.scenario.build import build, make_ssp

ROOT = Path(__file__).resolve().parents[2]

SLOPE = """
[simulation]
duration_s = 10.0

[environment]
volume = { lo = [-20000.0, -1000.0, 0.0], hi = [20000.0, 1000.0, 1500.0] }

[environment.sound_speed]
model = "grid"
file = "package:shelfbreak"

[environment.bathymetry]
model = "grid"
file = "package:shelfbreak"
variable = "bathymetry"

[environment.sediment]
name = "sand"

[[nodes]]
role = "anchor"
placement = { kind = "explicit", positions = [[0.0, 0.0, 50.0]] }
protocol = "beacon"
"""


def _run(capsys, argv: list[str]) -> tuple[int, str, str]:
    rc = main(argv)
    out, err = capsys.readouterr()
    return rc, out, err


def test_range_independent_first_arrival_is_travel_time(capsys) -> None:
    """Acceptance: for a range-independent scenario the first arrival is travel_time (1e-9 s)."""
    scen = str(ROOT / "scenarios" / "itmtl.toml")
    rc, out, _ = _run(capsys, ["arrivals", scen, "--from", "0,0,50", "--to", "800,300,120", "--json"])
    assert rc == 0
    doc = json.loads(out)
    assert doc["range_independent"] is True
    ssp = make_ssp(load(scen))
    t = float(channel.travel_time(ssp, [0, 0, 50], [800, 300, 120], reflections="all"))
    assert abs(doc["arrivals"][0]["delay_s"] - t) <= 1e-9
    delays = [a["delay_s"] for a in doc["arrivals"]]
    assert delays == sorted(delays) and len(delays) >= 3


def test_shelfbreak_link_across_the_slope(tmp_path, capsys) -> None:
    """A link from the shelf across the front and the slope: a direct or refracted arrival and
    at least one bottom-reflected one, in increasing delay."""
    f = tmp_path / "slope.toml"
    f.write_text(SLOPE)
    rc, out, _ = _run(
        capsys, ["arrivals", str(f), "--from", "-1500,0,40", "--to", "2500,0,150", "--json", "--max-bounces", "4"]
    )
    assert rc == 0
    doc = json.loads(out)
    assert doc["range_independent"] is False
    paths = [a["path"] for a in doc["arrivals"]]
    assert any(p in ("bottom", "surface-bottom") for p in paths)
    delays = [a["delay_s"] for a in doc["arrivals"]]
    assert delays == sorted(delays)
    rc, out, _ = _run(capsys, ["arrivals", str(f), "--from", "-1500,0,40", "--to", "2500,0,150"])
    assert rc == 0 and "delay s" in out.splitlines()[0]


def test_range_dependent_scenario_builds_with_its_arrival_keys(tmp_path) -> None:
    """A range-dependent scenario is simulated (the channel traces its environment) and its
    resolved scenario names the arrival keys it ran with; a range-independent one leaves them
    out unless set."""
    f = tmp_path / "slope.toml"
    f.write_text(SLOPE)
    sc = load(f)
    sim = build(sc)
    assert type(sim.channel.links).__name__ == "ArrivalLinkModel"
    ch = sc.to_dict()["channel"]
    assert ch["max_bounces"] == 2 and ch["detection_threshold_db"] is None
    flat = load(ROOT / "scenarios" / "beacon.toml")
    assert "max_bounces" not in flat.to_dict()["channel"]
    assert "detection_threshold_db" not in flat.to_dict()["channel"]
    assert (
        load(ROOT / "scenarios" / "beacon.toml", overrides=["channel.max_bounces=3"]).to_dict()["channel"][
            "max_bounces"
        ]
        == 3
    )


_BATHY = '[environment.bathymetry]\nmodel = "grid"\nfile = "package:shelfbreak"\nvariable = "bathymetry"\n'
_SEDIMENT = '[environment.sediment]\nname = "sand"\n'


@pytest.mark.parametrize(
    ("old", "new", "key"),
    [
        (_BATHY, "[environment.bathymetry]\nmodel = 'plane'\n", "depth_m"),
        (_BATHY, "[environment.bathymetry]\nmodel = 'grid'\nfile = 'nowhere.nc'\n", "no such file"),
        (_SEDIMENT, "[environment.sediment]\nname = 'mud'\n", "sediment"),
        (_SEDIMENT, "[environment.sediment]\nname = 'sand'\ndensity = 2.0\n", "sediment"),
    ],
)
def test_bad_ocean_keys(tmp_path, capsys, old: str, new: str, key: str) -> None:
    """A mistake in the new keys: one line naming the file and the key, exit 2, nothing on stdout."""
    assert old in SLOPE
    f = tmp_path / "bad.toml"
    f.write_text(SLOPE.replace(old, new))
    rc, out, err = _run(capsys, ["arrivals", str(f), "--from", "0,0,10", "--to", "100,0,10"])
    assert rc == 2 and out == ""
    assert err.startswith("error: ") and key in err and str(f) in err and len(err.strip().splitlines()) == 1


def test_bad_points(capsys) -> None:
    scen = str(ROOT / "scenarios" / "itmtl.toml")
    rc, out, err = _run(capsys, ["arrivals", scen, "--from", "0,0,50", "--to", "800,300,9999"])
    assert rc == 2 and out == "" and "outside the water" in err
    rc, out, err = _run(capsys, ["arrivals", scen, "--from", "0,0", "--to", "800,300,90"])
    assert rc == 2 and "X,Y,Z" in err


def test_unset_ocean_keys_leave_the_resolved_scenario_alone() -> None:
    """Shipped scenarios resolve without the new keys (their summary.json stays the same)."""
    env = load(ROOT / "scenarios" / "itmtl.toml").to_dict()["environment"]
    assert set(env) == {"volume", "sound_speed", "bottom_m"}
    assert np.isfinite(env["bottom_m"])
