"""scenarios/geographic.toml and the [environment] keys origin / woa / gebco / month / season:
runs, `aquasim-py arrivals`, `aquasim-py report --link`, and one-line errors for bad files."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("xarray")
pytest.importorskip("pyproj")
pytest.importorskip("h5netcdf")

import xarray as xr

from aquasim_py import run_scenario
from aquasim_py.channel.arrivals import arrivals
from aquasim_py.channel.data import sample_path
from aquasim_py.channel.geographic import GeographicBathymetry, GeographicField
from aquasim_py.cli import main
from aquasim_py.scenario import load
from aquasim_py.scenario.ocean import make_environment

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "geographic.toml"
TEXT = SCENARIO.read_text()
FILES = 'woa = ["package:woa23_t08", "package:woa23_s08"]\ngebco = "package:gebco"\n'


def _run(capsys, argv: list[str]) -> tuple[int, str, str]:
    rc = main(argv)
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, object]:
    """20 s of the scenario, written to a run directory."""
    out = tmp_path_factory.mktemp("geographic") / "run"
    return out, run_scenario(SCENARIO, overrides=["simulation.duration_s=20"], out=out, progress=False)


def test_geographic_scenario_runs_on_the_files(run) -> None:
    """Every anchor is heard, over refracted and bottom-reflected arrivals; the resolved
    scenario keeps the file keys (and no sound_speed)."""
    out, res = run
    p = res.tables["packets"]
    rx = p[p.event == "rx"]
    assert set(rx.src) == {0, 1, 2, 3}
    assert {"bottom", "refracted"} <= set(rx.path)
    env = json.loads((out / "summary.json").read_text())["scenario"]["environment"]
    assert env["origin"] == [40.0, -70.0] and env["month"] == 8 and "sound_speed" not in env
    assert env["woa"] == ["package:woa23_t08", "package:woa23_s08"] and env["gebco"] == "package:gebco"
    assert res.metrics["beacon.ranges"] > 30


def test_report_link(run, capsys) -> None:
    """`aquasim-py report --link` on a run of the scenario draws that link's section and rays."""
    out, _ = run
    rc, _, err = _run(capsys, ["report", str(out), "--link", "0,9"])
    assert rc == 0, err
    assert (out / "environment.png").stat().st_size > 10_000
    assert "environment.png" in (out / "report.html").read_text()


def test_the_environment_is_the_files(tmp_path: Path) -> None:
    """The scenario's environment is the files' grids placed by the origin; a copy of the files
    beside a scenario file, named by relative paths, gives the same sound speed and floor."""
    env = make_environment(load(SCENARIO))
    assert isinstance(env.field, GeographicField) and isinstance(env.bathymetry, GeographicBathymetry)
    assert not env.range_independent
    for name in ("woa23_t08", "woa23_s08", "gebco"):
        shutil.copy(sample_path(name), tmp_path / sample_path(name).name)
    f = tmp_path / "mine.toml"
    f.write_text(
        TEXT.replace(FILES, 'woa = ["woa23_sample_t08.nc", "woa23_sample_s08.nc"]\ngebco = "gebco_sample.nc"\n')
    )
    other = make_environment(load(f))
    pts = np.array([[0.0, 5000.0, 40.0], [-2000.0, 2500.0, 120.0], [2400.0, 7900.0, 10.0]])
    np.testing.assert_array_equal(other.speed(*pts.T), env.speed(*pts.T))
    np.testing.assert_array_equal(other.depth(*pts[:, :2].T), env.depth(*pts[:, :2].T))


def test_arrivals_command(capsys) -> None:
    """`aquasim-py arrivals` on the scenario: the arrivals of arrivals() on its environment."""
    rc, out, _ = _run(capsys, ["arrivals", str(SCENARIO), "--from", "-2000,7500,40", "--to", "600,3900,90", "--json"])
    assert rc == 0
    doc = json.loads(out)
    assert doc["range_independent"] is False
    arr = arrivals(make_environment(load(SCENARIO)), [-2000, 7500, 40], [600, 3900, 90], max_bounces=2)
    np.testing.assert_allclose([a["delay_s"] for a in doc["arrivals"]], arr.delay, rtol=0, atol=1e-12)
    assert any(a["path"] == "bottom" for a in doc["arrivals"])


def _write(tmp_path: Path, text: str) -> Path:
    f = tmp_path / "bad.toml"
    f.write_text(text)
    return f


def _one_line_error(capsys, f: Path, *needles: str) -> str:
    out_dir = f.parent / "out"
    rc, out, err = _run(capsys, [str(f), "--out", str(out_dir), "--quiet"])
    assert rc == 2 and out == "", (rc, out, err)
    assert err.startswith("error: ") and len(err.strip().splitlines()) == 1, err
    assert str(f) in err and all(n in err for n in needles), err
    assert not out_dir.exists()
    return err


def test_missing_variable_is_one_line(tmp_path: Path, capsys) -> None:
    """Acceptance: a WOA file without s_an: one line naming the file and the variable, exit 2."""
    with xr.open_dataset(sample_path("woa23_s08"), decode_times=False) as ds:
        ds.load().rename({"s_an": "salinity"}).to_netcdf(tmp_path / "s.nc", engine="h5netcdf")
    shutil.copy(sample_path("woa23_t08"), tmp_path / "t.nc")
    f = _write(tmp_path, TEXT.replace('"package:woa23_s08"', '"s.nc"').replace('"package:woa23_t08"', '"t.nc"'))
    _one_line_error(capsys, f, "environment.woa", str(tmp_path / "s.nc"), "s_an", "no such variable")


def test_point_outside_the_files_is_one_line(tmp_path: Path, capsys) -> None:
    """Acceptance: the volume north of the GEBCO sample: one line naming the file and the
    variable, exit 2; south of the WOA sample too."""
    f = _write(tmp_path, TEXT.replace("origin = [40.0, -70.0]", "origin = [40.2, -70.0]"))
    _one_line_error(capsys, f, "environment.gebco", str(sample_path("gebco")), "elevation", "not the scenario's volume")
    f = _write(tmp_path, TEXT.replace("origin = [40.0, -70.0]", "origin = [39.5, -70.0]"))
    _one_line_error(capsys, f, "environment.woa", str(sample_path("woa23_t08")), "t_an", "not the scenario's volume")


@pytest.mark.parametrize(
    ("old", "new", "needle"),
    [
        ("origin = [40.0, -70.0]\n", "", "need origin"),
        ("month = 8", "month = 1", "not January"),
        ("month = 8", 'month = 8\nseason = "summer"', "month or season, not both"),
        ("month = 8", "month = 8\nbottom_m = 200.0", "gebco"),
        ("month = 8", 'month = 8\nsound_speed = { model = "constant" }', "sound_speed or woa"),
        ('gebco = "package:gebco"', 'gebco = "nowhere.nc"', "no such file"),
        ("origin = [40.0, -70.0]", "origin = [95.0, -70.0]", "latitude"),
    ],
)
def test_bad_geographic_keys(tmp_path: Path, capsys, old: str, new: str, needle: str) -> None:
    assert old in TEXT
    _one_line_error(capsys, _write(tmp_path, TEXT.replace(old, new)), needle)
