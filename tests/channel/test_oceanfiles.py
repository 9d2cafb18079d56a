"""Reading the World Ocean Atlas and GEBCO / ETOPO files as distributed (aquasim_py.channel.oceanfiles),
on the bundled samples in their formats and on variants of them written here."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("xarray")
pytest.importorskip("gsw")
pytest.importorskip("pyproj")
pytest.importorskip("h5netcdf")

import gsw
import xarray as xr

from aquasim_py.channel.data import sample_path
from aquasim_py.channel.geographic import LocalFrame
from aquasim_py.channel.oceanfiles import DataFileError, period_months, read_gebco, read_woa

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tools"))
import make_geographic_sample as sample

FRAME = LocalFrame(*sample.ORIGIN)
WOA = [sample_path("woa23_t08"), sample_path("woa23_s08")]
BOX = FRAME.footprint([-3000, 1000], [3000, 9000])


def test_shipped_samples_are_what_the_tool_writes(tmp_path: Path) -> None:
    """tools/make_geographic_sample.py makes the package's files (values and attributes)."""
    for p in sample.write(tmp_path):
        with (
            xr.open_dataset(p, decode_times=False) as new,
            xr.open_dataset(sample.DATA / p.name, decode_times=False) as old,
        ):
            assert new.identical(old), p.name


def test_sound_speed_at_grid_nodes_is_gsw_of_the_files_t_and_s() -> None:
    """Acceptance: at every wet node of the WOA grid (over the volume and two cells around), the
    environment's sound speed at that node's place in the frame equals TEOS-10's from the file's
    own t_an and s_an there (read here with xarray alone): pressure from depth and latitude,
    Absolute Salinity, Conservative Temperature, gsw.sound_speed; to 1e-9 m/s (the frame's round
    trip moves a node by ~4e-9 m, where the field changes by < 1e-3 m/s per m)."""
    field = read_woa(WOA, FRAME, month=8, box=BOX)
    with xr.open_dataset(WOA[0], decode_times=False) as t, xr.open_dataset(WOA[1], decode_times=False) as s:
        T = t["t_an"].isel(time=0).values.astype(float)  # (depth, lat, lon)
        S = s["s_an"].isel(time=0).values.astype(float)
        lat, lon, z = (t[k].values.astype(float) for k in ("lat", "lon", "depth"))
    checked = 0
    for i, la in enumerate(lat):
        for j, lo in enumerate(lon):
            if la not in field.grid.latitude or lo not in field.grid.longitude:
                continue
            wet = np.isfinite(T[:, i, j])
            p = gsw.p_from_z(-z[wet], la)
            sa = gsw.SA_from_SP(S[wet, i, j], p, lo, la)
            ct = gsw.CT_from_t(sa, T[wet, i, j], p)
            want = gsw.sound_speed(sa, ct, p)
            x, y = FRAME.to_xy(la, lo)
            got = field.speed(np.full(wet.sum(), x), np.full(wet.sum(), y), z[wet])
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
            checked += wet.sum()
    assert checked > 100


def test_cells_below_the_woa_floor_take_the_water_above() -> None:
    """A column WOA leaves empty below its floor continues with the deepest T, S above: the
    speed there is TEOS-10's of those at the deeper level's pressure."""
    field = read_woa(WOA, FRAME, month=8)
    with xr.open_dataset(WOA[0], decode_times=False) as t, xr.open_dataset(WOA[1], decode_times=False) as s:
        T = t["t_an"].isel(time=0).values.astype(float)
        S = s["s_an"].isel(time=0).values.astype(float)
        lat, lon, z = (t[k].values.astype(float) for k in ("lat", "lon", "depth"))
    i, j = 3, 0  # the northernmost, western column: the shelf, empty below ~60 m
    wet = np.isfinite(T[:, i, j])
    assert 0 < wet.sum() < z.size
    last = np.flatnonzero(wet)[-1]
    deep = z[last + 1 :]
    p = gsw.p_from_z(-deep, lat[i])
    sa = gsw.SA_from_SP(np.full(deep.size, S[last, i, j]), p, lon[j], lat[i])
    want = gsw.sound_speed(sa, gsw.CT_from_t(sa, np.full(deep.size, T[last, i, j]), p), p)
    np.testing.assert_allclose(field.speeds[i, j, last + 1 :], want, rtol=0, atol=1e-9)


def test_gebco_depth_is_minus_the_elevation() -> None:
    bathy = read_gebco(sample_path("gebco"), FRAME)
    with xr.open_dataset(sample_path("gebco")) as ds:
        el = ds["elevation"].values.astype(float)
        lat, lon = ds["lat"].values, ds["lon"].values
    np.testing.assert_array_equal(bathy.depths, -el)
    x, y = FRAME.to_xy(lat[10], lon[20])
    assert float(bathy.depth(x, y)) == pytest.approx(-el[10, 20], abs=1e-6)


def _woa_variant(tmp_path: Path, change, only: str | None = None) -> list[Path]:
    """The two WOA samples rewritten into tmp_path, each (or the one holding ``only``) changed
    by ``change(ds, name) -> ds`` (name: its t_an or s_an)."""
    out = []
    for p in WOA:
        with xr.open_dataset(p, decode_times=False) as ds:
            ds = ds.load()
        name = "t_an" if "t_an" in ds else "s_an"
        if only in (None, name):
            ds = change(ds, name)
        q = tmp_path / p.name
        ds.to_netcdf(q, engine="h5netcdf")
        out.append(q)
    return out


def test_a_missing_variable_names_the_file_and_the_variable(tmp_path: Path) -> None:
    paths = _woa_variant(tmp_path, lambda ds, name: ds.drop_vars(name), only="s_an")
    with pytest.raises(DataFileError) as e:
        read_woa(paths, FRAME, month=8)
    assert e.value.variable == "s_an" and str(paths[1]) in str(e.value) and "no such variable" in str(e.value)
    with pytest.raises(DataFileError) as e:
        read_gebco(WOA[0], FRAME)
    assert e.value.variable == "elevation" and str(WOA[0]) in str(e.value)


def test_temperatures_in_kelvin_are_refused(tmp_path: Path) -> None:
    paths = _woa_variant(tmp_path, lambda ds, name: ds.assign({name: ds[name] + 273.15}), only="t_an")
    with pytest.raises(DataFileError, match=r"not an in-situ temperature in deg C \(-5 .. 45\)") as e:
        read_woa(paths, FRAME, month=8)
    assert e.value.variable == "t_an"


def test_a_volume_outside_the_files_names_the_file_and_the_variable() -> None:
    far = LocalFrame(40.3, -70.0)  # the volume north of the GEBCO sample's 40.25 N
    box = far.footprint([-3000, 1000], [3000, 5000])
    read_woa(WOA, far, month=8, box=box)  # WOA's sample reaches 40.375 N
    with pytest.raises(DataFileError) as e:
        read_gebco(sample_path("gebco"), far, box=box)
    assert e.value.variable == "elevation" and str(sample_path("gebco")) in str(e.value)
    assert "not the scenario's volume" in str(e.value) and "lat 39.8521..40.2479" in str(e.value)
    with pytest.raises(DataFileError) as e:
        read_woa(WOA, LocalFrame(45.0, -70.0), month=8, box=LocalFrame(45.0, -70.0).footprint([0, 0], [10, 10]))
    assert e.value.variable == "t_an" and str(WOA[0]) in str(e.value)


def test_the_period_is_checked_and_chosen(tmp_path: Path) -> None:
    """August's files serve month = 8 and nothing else; twelve months in one file (concatenated
    along time) serve each month; the period comes from CF's climatology bounds."""
    read_woa(WOA, FRAME, month=8)
    read_woa(WOA, FRAME)  # the files' one period
    for kw, want in (({"month": 1}, "not January"), ({"season": "summer"}, r"not summer \(Jul-Sep\)")):
        with pytest.raises(DataFileError, match=want) as e:
            read_woa(WOA, FRAME, **kw)
        assert "holds August" in str(e.value) and e.value.variable == "t_an"

    def twelve(ds, name):
        steps = []
        for m in range(12):  # month m + 1: August's values + (m - 7)
            d = ds.copy(deep=True)
            d[name] = d[name] + (m - 7)
            d["time"] = ("time", np.array([396.5 + m], np.float32), ds["time"].attrs)
            d["climatology_bounds"] = (("time", "nbounds"), np.array([[m, m + 805]], np.float32))
            steps.append(d)
        return xr.concat(steps, dim="time", data_vars="minimal", coords="minimal", compat="override")

    paths = _woa_variant(tmp_path, twelve)
    with pytest.raises(DataFileError, match="holds 12 periods"):
        read_woa(paths, FRAME)
    t3 = read_woa(paths, FRAME, month=3)
    t8 = read_woa(paths, FRAME, month=8)
    assert not np.array_equal(t3.speeds, t8.speeds)
    np.testing.assert_array_equal(t8.speeds, read_woa(WOA, FRAME, month=8).speeds)


@pytest.mark.parametrize(
    ("time", "bounds", "months"),
    [
        (396.5, (0.0, 805.0), {1}),  # WOA23 January (as distributed: months since 1955-01-01)
        (403.5, (7.0, 812.0), {8}),  # August
        (397.5, (0.0, 807.0), {1, 2, 3}),  # winter: January to March
        (4614.0, (4212.0, 5028.0), set(range(1, 13))),  # the annual mean
        (403.5, None, {8}),  # no bounds: the month of the time value
    ],
)
def test_period_months(time: float, bounds, months: set[int]) -> None:
    attrs = {"units": "months since 1955-01-01 00:00:00"}
    data = {}
    if bounds is not None:
        attrs["climatology"] = "climatology_bounds"
        data["climatology_bounds"] = (("time", "nbounds"), np.array([bounds]))
    ds = xr.Dataset(data, coords={"time": ("time", [time], attrs)})
    assert period_months(ds, "x.nc", "time") == [frozenset(months)]


def test_period_months_in_days() -> None:
    """A time axis in days (Gregorian): a climatological July from its bounds."""
    attrs = {"units": "days since 1900-01-01", "climatology": "cb"}
    b0 = (np.datetime64("1991-07-01") - np.datetime64("1900-01-01")).astype(float)
    b1 = (np.datetime64("2020-08-01") - np.datetime64("1900-01-01")).astype(float)
    ds = xr.Dataset({"cb": (("time", "nb"), [[b0, b1]])}, coords={"time": ("time", [b0 + 15.0], attrs)})
    assert period_months(ds, "x.nc", "time") == [frozenset({7})]


def test_netcdf3_and_north_to_south_files_read_the_same(tmp_path: Path) -> None:
    """The same WOA data as netCDF3 (scipy) with latitudes north to south; ETOPO's z."""
    out = []
    for p in WOA:
        with xr.open_dataset(p, decode_times=False) as ds:
            ds = ds.load().isel(lat=slice(None, None, -1))
        q = tmp_path / p.name
        ds.to_netcdf(q, engine="scipy", format="NETCDF3_64BIT")
        out.append(q)
    a, b = read_woa(WOA, FRAME, month=8), read_woa(out, FRAME, month=8)
    np.testing.assert_array_equal(a.grid.latitude, b.grid.latitude)
    np.testing.assert_array_equal(a.speeds, b.speeds)
    with xr.open_dataset(sample_path("gebco")) as ds:
        ds = ds.load().rename({"elevation": "z"})
    q = tmp_path / "etopo.nc"
    ds.to_netcdf(q, engine="scipy")
    np.testing.assert_array_equal(read_gebco(q, FRAME).depths, read_gebco(sample_path("gebco"), FRAME).depths)


def test_land_is_depth_zero_and_empty_woa_columns_take_the_nearest(tmp_path: Path) -> None:
    with xr.open_dataset(sample_path("gebco")) as ds:
        ds = ds.load()
    ds["elevation"][:5, :5] = 12  # an island in the south-west corner
    q = tmp_path / "g.nc"
    ds.to_netcdf(q, engine="scipy")
    assert np.all(read_gebco(q, FRAME).depths[:5, :5] == 0.0)

    def land(ds, name):
        ds[name][:, :, 3, 3] = np.nan  # the north-east column is land in WOA's mask
        return ds

    field = read_woa(_woa_variant(tmp_path, land), FRAME, month=8)
    with xr.open_dataset(WOA[0], decode_times=False) as t, xr.open_dataset(WOA[1], decode_times=False) as s:
        T = t["t_an"].isel(time=0).values.astype(float)
        S = s["s_an"].isel(time=0).values.astype(float)
        lat, lon, z = (t[k].values.astype(float) for k in ("lat", "lon", "depth"))
    p = gsw.p_from_z(-z, lat[3])

    def speed(i: int, j: int) -> np.ndarray:  # the column (i, j)'s water at the node (3, 3)
        col_t = T[:, i, j].copy()
        col_s = S[:, i, j].copy()
        last = np.flatnonzero(np.isfinite(col_t))[-1]
        col_t[last + 1 :], col_s[last + 1 :] = col_t[last], col_s[last]
        sa = gsw.SA_from_SP(col_s, p, lon[3], lat[3])
        return gsw.sound_speed(sa, gsw.CT_from_t(sa, col_t, p), p)

    assert any(np.allclose(field.speeds[3, 3], speed(i, j), rtol=0, atol=1e-9) for i, j in ((2, 3), (3, 2)))
