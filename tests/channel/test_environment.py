"""Environments (aquasim_py.channel.environment, fields, bathymetry, data) and their optional
dependencies."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from aquasim_py.channel import ssp
from aquasim_py.channel.bathymetry import Flat, GriddedBathymetry, Plane, Seamount
from aquasim_py.channel.data import sample_path, shelfbreak
from aquasim_py.channel.environment import Environment
from aquasim_py.channel.fields import DepthProfile, GriddedField, RangeProfiles

ROOT = Path(__file__).resolve().parents[2]


def test_range_independent_runs_do_not_import_the_ocean_extras() -> None:
    """A shipped range-independent scenario runs without importing gsw, xarray, pyproj, h5netcdf or pelagic."""
    code = (
        "import sys, aquasim_py\n"
        f"aquasim_py.run_scenario({str(ROOT / 'scenarios' / 'beacon.toml')!r}, out=None)\n"
        "print(sorted(m for m in ('gsw', 'xarray', 'pyproj', 'h5netcdf', 'pelagic') if m in sys.modules))\n"
    )
    r = subprocess.run([sys.executable, "-c", code], check=False, capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip().splitlines()[-1] == "[]"


def test_from_profile_is_range_independent() -> None:
    p = ssp.Layered([0, 100, 300], [1500, 1490, 1495], bottom=300.0)
    env = Environment.from_profile(p)
    assert env.range_independent and env.profile() is p
    assert not Environment(DepthProfile(p), Plane(300.0, slope_x=0.01)).range_independent
    with pytest.raises(ValueError, match="range-dependent"):
        Environment(DepthProfile(p), Plane(300.0, slope_x=0.01)).profile()


def test_range_profiles_interpolate_along_their_line() -> None:
    f = RangeProfiles(
        [0.0, 1000.0], [0.0, 100.0], [[1500.0, 1490.0], [1510.0, 1480.0]], origin=(100.0, 0.0), azimuth_deg=90.0
    )
    # along the line (+y from x = 100): halfway, the mean profile; across it, the same
    np.testing.assert_allclose(f.speed([100.0, -400.0], [500.0, 500.0], [0.0, 100.0]), [1505.0, 1485.0])
    np.testing.assert_allclose(f.speed(0.0, -50.0, 0.0), 1500.0)  # clamped before the first profile
    np.testing.assert_allclose(f.speed(0.0, 0.0, 150.0), 1485.0)  # last gradient continues down


def test_gridded_field_bilinear_and_teos10() -> None:
    x, y, z = np.array([0.0, 10.0]), np.array([0.0, 10.0]), np.array([0.0, 100.0])
    c = np.zeros((2, 2, 2))
    c[..., 0] = [[1500.0, 1502.0], [1504.0, 1506.0]]
    c[..., 1] = c[..., 0] - 10.0
    g = GriddedField(x, y, z, c)
    np.testing.assert_allclose(g.speed(5.0, 5.0, 0.0), 1503.0)
    np.testing.assert_allclose(g.speed(5.0, 5.0, 50.0), 1498.0)
    t = GriddedField.from_ts(x, y, z, np.full((2, 2, 2), 10.0), np.full((2, 2, 2), 35.0))
    np.testing.assert_allclose(t.speed(0.0, 0.0, 0.0), ssp.teos10_speed(0.0, 10.0, 35.0, 40.0, -70.0))


def test_teos10_close_to_mackenzie() -> None:
    """TEOS-10 and Mackenzie 1981 agree within Mackenzie's stated accuracy range over a cast
    (standard error 0.07 m/s; differences of a few tenths of a m/s are documented between them)."""
    z = np.array([0.0, 50.0, 200.0, 1000.0])
    T = np.array([20.0, 15.0, 10.0, 4.0])
    S = np.array([35.0, 35.1, 35.0, 34.9])
    lay = ssp.from_ts(z, T, S)
    assert np.max(np.abs(lay.speeds - ssp.mackenzie(z, T, S))) < 0.5


def test_bathymetries() -> None:
    assert Flat(100.0).depth(3.0, 4.0) == 100.0
    np.testing.assert_allclose(Plane(200.0, slope_x=-0.05).depth([0.0, 2000.0, 5000.0], 0.0), [200.0, 100.0, 0.0])
    m = Seamount(3000.0, 2000.0, 1000.0, x0=500.0)
    assert m.depth(500.0, 0.0) == pytest.approx(1000.0)
    g = GriddedBathymetry([0.0, 10.0], [0.0, 10.0], [[100.0, 200.0], [300.0, 400.0]])
    assert float(g.depth(5.0, 5.0)) == pytest.approx(250.0)
    assert g.depth(np.zeros((3, 2)), np.zeros((3, 2))).shape == (3, 2)


def test_seamount_samples_do_not_move_with_the_source() -> None:
    """The seamount's polyline samples are fixed points of a line: sliding the source along the
    line shifts their distances by the same amount."""
    m = Seamount(3000.0, 2000.0, 1000.0, x0=500.0, resolution_m=50.0)
    a = m.section_ranges(np.array([0.0]), np.array([0.0]), np.array([1.0]), np.array([0.0]), np.array([2000.0]))
    b = m.section_ranges(np.array([13.0]), np.array([0.0]), np.array([1.0]), np.array([0.0]), np.array([2000.0]))
    pa = np.sort(a[np.isfinite(a)])
    pb = np.sort(b[np.isfinite(b)]) + 13.0
    common = np.intersect1d(np.round(pa, 9), np.round(pb, 9))
    assert common.size >= 20


def test_shelfbreak_sample() -> None:
    """The bundled sample: small, found as package data, a front (the speed at 40 m rises by more
    than 15 m/s from shelf to slope water) over a slope (60 m to 2000 m)."""
    p = sample_path("shelfbreak")
    assert p.is_file() and p.stat().st_size <= 2_000_000
    env = shelfbreak()
    c = env.speed(np.array([-20000.0, 20000.0]), 0.0, 40.0)
    assert c[1] - c[0] > 15.0
    d = env.depth(np.array([-30000.0, 0.0, 30000.0]), 0.0)
    np.testing.assert_allclose(d, [60.0, 100.0, 1000.0])
    with pytest.raises(KeyError, match="available"):
        sample_path("nowhere")
