"""Write the geographic samples: small files in the formats of the World Ocean Atlas 2023 and of
GEBCO, over a continental slope south of New England (around 40 N, 70 W), for the tests, the
tutorial and scenarios/geographic.toml (the machines that run them cannot download the real
ones; docs/channel.md says how to fetch those).

The values are SYNTHETIC: no WOA or GEBCO data is shipped. Only the formats are theirs:

* ``woa23_sample_t08.nc`` / ``woa23_sample_s08.nc``: as WOA23 distributes its 1/4-degree monthly
  means (here August), one netCDF4 file per variable, cut to 4 x 4 cells (lat 39.625 ...
  40.375 N, lon 70.375 ... 69.625 W, cell centres) and WOA's 57 standard depth levels of a
  month (0-1500 m): ``t_an`` (in-situ temperature, degrees_celsius) / ``s_an`` (practical
  salinity) on (time, depth, lat, lon), float32 with WOA's fill value below the sea floor, the
  coordinates with their bounds (``lat_bnds``, ``lon_bnds``, ``depth_bnds``), ``time`` in
  "months since 1955-01-01 00:00:00" with ``climatology_bounds``, ``crs``, CF-1.6 attributes.
  What ``ncks -d lat,39.5,40.5 -d lon,-70.5,-69.5 -v t_an woa23_decav_t08_04.nc`` keeps.
* ``gebco_sample.nc``: as GEBCO's download application writes a subset of its 15 arc-second
  grid (netCDF3 classic): ``elevation`` (int16, m above sea level, negative below) on ``lat`` /
  ``lon`` (cell centres, every 1/240 deg), lat 39.85 ... 40.25 N, lon 70.2 ... 69.8 W.

The ocean they describe (the local frame about 40 N, 70 W: x east, y north, m, through pyproj):

* the floor: a shelf break running east-north-east (azimuth 75 deg) through (0, 5 km), its line
  meandering 400 m either way over 12 km; a shelf deepening 1.3 m per km seaward to 100 m at the
  break, rounded over ~1 km into a 3 % slope (about 1.7 deg, as the Middle Atlantic Bight's slope
  between the 100 and 2000 m isobaths), cut by gullies 24 m deep every 3 km along the slope;
  depths rounded to whole metres, as GEBCO stores them;
* the water: August's shelf and slope water masses of tools/make_shelfbreak_sample.py (its
  docstring cites the climatologies), blended across the shelf-break front (its foot at the
  break, rising seaward at 3e-3) over 10 km, about what a 1/4-degree climatology's smoothing
  leaves of a front a few km wide. WOA's cells below the sea floor at a cell's centre are empty.

Run: ``python tools/make_geographic_sample.py`` (needs xarray, h5netcdf, pyproj, scipy). The
output is deterministic; tests/channel/test_oceanfiles.py checks that it matches the shipped
files.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from make_shelfbreak_sample import SHELF, SLOPE  # tools/, beside this script

DATA = Path(__file__).resolve().parents[1] / "aquasim_py" / "channel" / "data"
ORIGIN = (40.0, -70.0)  # lat, lon of the local frame's origin (deg)
MONTH = 8

BREAK_POINT_M = np.array([0.0, 5000.0])
BREAK_AZIMUTH_DEG = 75.0  # the break line's direction, clockwise from north (east-north-east)
MEANDER_M, MEANDER_WAVELENGTH_M = 400.0, 12000.0
SHELF_GRADIENT, SLOPE_GRADIENT, ROUNDING_M = 0.0013, 0.03, 800.0
GULLY_DEPTH_M, GULLY_SPACING_M = 12.0, 3000.0
FRONT_SLOPE, FRONT_WIDTH_M = 3e-3, 10000.0

# WOA's standard depth levels of a monthly field (57, 0-1500 m)
WOA_DEPTHS = np.concatenate([np.arange(0.0, 100.0, 5.0), np.arange(100.0, 500.0, 25.0), np.arange(500.0, 1501.0, 50.0)])
WOA_LAT = np.array([39.625, 39.875, 40.125, 40.375])
WOA_LON = np.array([-70.375, -70.125, -69.875, -69.625])
WOA_FILL = np.float32(9.96921e36)
GEBCO_STEP = 1.0 / 240.0  # 15 arc seconds
GEBCO_LAT = (39.85, 40.25)
GEBCO_LON = (-70.2, -69.8)


def slope_coordinates(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(seaward distance from the meandering break line, distance along it) in m."""
    az = np.radians(BREAK_AZIMUTH_DEG)
    along_u = np.array([np.sin(az), np.cos(az)])  # east, north components
    seaward_u = np.array([np.cos(az), -np.sin(az)])  # 90 deg clockwise of the line
    dx, dy = x - BREAK_POINT_M[0], y - BREAK_POINT_M[1]
    a = dx * along_u[0] + dy * along_u[1]
    d = dx * seaward_u[0] + dy * seaward_u[1] - MEANDER_M * np.sin(2.0 * np.pi * a / MEANDER_WAVELENGTH_M)
    return d, a


def floor_depth(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Sea-floor depth (m) at frame points."""
    d, a = slope_coordinates(x, y)
    w = ROUNDING_M
    softplus = np.logaddexp(0.0, d / w) - np.log(2.0)
    h = 100.0 + SHELF_GRADIENT * d + (SLOPE_GRADIENT - SHELF_GRADIENT) * w * softplus
    on_slope = 0.5 * (1.0 + np.tanh((d - 1500.0) / 1000.0))
    h = h + GULLY_DEPTH_M * (1.0 - np.cos(2.0 * np.pi * a / GULLY_SPACING_M)) * on_slope
    return np.clip(h, 5.0, 2000.0)


def water(x: np.ndarray, y: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """In-situ temperature (deg C) and practical salinity at frame points (x, y) and depths z (broadcast)."""
    d, _ = slope_coordinates(x, y)
    front = (100.0 - z) / FRONT_SLOPE  # seaward distance of the front at depth z (the foot at the break)
    w = 0.5 * (1.0 + np.tanh((d - front) / FRONT_WIDTH_M))  # 0 shelf water, 1 slope water
    t_shelf, s_shelf = np.interp(z, SHELF[:, 0], SHELF[:, 1]), np.interp(z, SHELF[:, 0], SHELF[:, 2])
    t_slope, s_slope = np.interp(z, SLOPE[:, 0], SLOPE[:, 1]), np.interp(z, SLOPE[:, 0], SLOPE[:, 2])
    return t_shelf + w * (t_slope - t_shelf), s_shelf + w * (s_slope - s_shelf)


def frame():  # -> aquasim_py.channel.geographic.LocalFrame
    from aquasim_py.channel.geographic import LocalFrame

    return LocalFrame(*ORIGIN)


def _bounds(centres: np.ndarray, half: float) -> np.ndarray:
    return np.stack([centres - half, centres + half], axis=1).astype(np.float32)


def woa(variable: str):  # -> xarray.Dataset
    """The WOA23-format sample of ``variable`` ("t" or "s")."""
    import xarray as xr

    fr = frame()
    x, y = fr.to_xy(WOA_LAT[:, None], WOA_LON[None, :])
    t, s = water(x[None], y[None], WOA_DEPTHS[:, None, None])
    values = t if variable == "t" else s
    floor = floor_depth(x, y)
    values = np.where(WOA_DEPTHS[:, None, None] <= floor[None], values, np.nan)[None].astype(np.float32)
    edges = np.concatenate([[0.0], 0.5 * (WOA_DEPTHS[1:] + WOA_DEPTHS[:-1]), [WOA_DEPTHS[-1] + 25.0]])
    name = "sea_water_temperature" if variable == "t" else "sea_water_salinity"
    var_attrs = {
        "standard_name": name,
        "long_name": f"Objectively analyzed mean fields for {name} at standard depth levels.",
        "cell_methods": "area: mean depth: mean time: mean within years time: mean over years",
        "grid_mapping": "crs",
        "units": "degrees_celsius" if variable == "t" else "1",
    }
    first = MONTH - 1  # months since 1955-01 of the first August
    ds = xr.Dataset(
        {
            "crs": (
                (),
                np.int32(-2147483647),
                {
                    "grid_mapping_name": "latitude_longitude",
                    "epsg_code": "EPSG:4326",
                    "longitude_of_prime_meridian": 0.0,
                    "semi_major_axis": 6378137.0,
                    "inverse_flattening": 298.25722356,
                },
            ),
            "lat_bnds": (("lat", "nbounds"), _bounds(WOA_LAT, 0.125)),
            "lon_bnds": (("lon", "nbounds"), _bounds(WOA_LON, 0.125)),
            "depth_bnds": (("depth", "nbounds"), np.stack([edges[:-1], edges[1:]], axis=1).astype(np.float32)),
            "climatology_bounds": (("time", "nbounds"), np.array([[first, first + 805]], np.float32)),
            f"{variable}_an": (("time", "depth", "lat", "lon"), values, var_attrs),
        },
        coords={
            "lat": (
                "lat",
                WOA_LAT.astype(np.float32),
                {
                    "standard_name": "latitude",
                    "long_name": "latitude",
                    "units": "degrees_north",
                    "axis": "Y",
                    "bounds": "lat_bnds",
                },
            ),
            "lon": (
                "lon",
                WOA_LON.astype(np.float32),
                {
                    "standard_name": "longitude",
                    "long_name": "longitude",
                    "units": "degrees_east",
                    "axis": "X",
                    "bounds": "lon_bnds",
                },
            ),
            "depth": (
                "depth",
                WOA_DEPTHS.astype(np.float32),
                {
                    "standard_name": "depth",
                    "bounds": "depth_bnds",
                    "positive": "down",
                    "units": "meters",
                    "axis": "Z",
                },
            ),
            "time": (
                "time",
                np.array([396.5 + first], np.float32),
                {
                    "standard_name": "time",
                    "long_name": "time",
                    "units": "months since 1955-01-01 00:00:00",
                    "axis": "T",
                    "climatology": "climatology_bounds",
                },
            ),
        },
        attrs={
            "Conventions": "CF-1.6, ACDD-1.3",
            "title": f"SYNTHETIC sample in the World Ocean Atlas 2023 format (not WOA data): {name}, August",
            "summary": "Made by aquasim-py's tools/make_geographic_sample.py from an idealised shelf-break front "
            "over a continental slope near 40 N, 70 W; only the file format is WOA23's.",
            "references": "Linder & Gawarkiewicz 1998 JGR 103(C9) 18405; Houghton et al. 1982 JPO 12 1019",
            "geospatial_lat_min": 39.5,
            "geospatial_lat_max": 40.5,
            "geospatial_lon_min": -70.5,
            "geospatial_lon_max": -69.5,
        },
    )
    encoding: dict[str, dict[str, object]] = {f"{variable}_an": {"_FillValue": WOA_FILL}}
    for v in ("lat", "lon", "depth", "time", "lat_bnds", "lon_bnds", "depth_bnds", "climatology_bounds"):
        encoding[v] = {"_FillValue": None}
    return ds, encoding


def gebco():  # -> xarray.Dataset
    """The GEBCO-format bathymetry sample."""
    import xarray as xr

    i0, i1 = (int(round(v / GEBCO_STEP)) for v in GEBCO_LAT)
    j0, j1 = (int(round(v / GEBCO_STEP)) for v in GEBCO_LON)
    lat = (np.arange(i0, i1) + 0.5) * GEBCO_STEP
    lon = (np.arange(j0, j1) + 0.5) * GEBCO_STEP
    x, y = frame().to_xy(lat[:, None], lon[None, :])
    elevation = (-np.round(floor_depth(x, y))).astype(np.int16)
    ds = xr.Dataset(
        {
            "elevation": (
                ("lat", "lon"),
                elevation,
                {
                    "standard_name": "height_above_mean_sea_level",
                    "long_name": "Elevation relative to sea level",
                    "units": "m",
                    "sdn_parameter_urn": "SDN:P01::BATHHGHT",
                    "sdn_parameter_name": "Sea floor height (above mean sea level) {bathymetric height}",
                    "sdn_uom_urn": "SDN:P06::ULAA",
                    "sdn_uom_name": "Metres",
                },
            )
        },
        coords={
            "lat": (
                "lat",
                lat,
                {
                    "standard_name": "latitude",
                    "long_name": "latitude",
                    "units": "degrees_north",
                    "axis": "Y",
                    "sdn_parameter_urn": "SDN:P01::ALATZZ01",
                    "sdn_parameter_name": "Latitude north",
                    "sdn_uom_urn": "SDN:P06::DEGN",
                    "sdn_uom_name": "Degrees north",
                },
            ),
            "lon": (
                "lon",
                lon,
                {
                    "standard_name": "longitude",
                    "long_name": "longitude",
                    "units": "degrees_east",
                    "axis": "X",
                    "sdn_parameter_urn": "SDN:P01::ALONZZ01",
                    "sdn_parameter_name": "Longitude east",
                    "sdn_uom_urn": "SDN:P06::DEGE",
                    "sdn_uom_name": "Degrees east",
                },
            ),
        },
        attrs={
            "Conventions": "CF-1.6",
            "title": "SYNTHETIC sample in the format of a GEBCO grid subset (not GEBCO data)",
            "institution": "aquasim-py (tools/make_geographic_sample.py)",
            "source": "an idealised continental slope near 40 N, 70 W; only the file format is GEBCO's",
            "node_offset": np.int32(1),
        },
    )
    return ds, {v: {"_FillValue": None} for v in ("lat", "lon", "elevation")}


def write(out: Path) -> list[Path]:
    """Write the three files into ``out``; their paths."""
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for variable in ("t", "s"):
        ds, enc = woa(variable)
        p = out / f"woa23_sample_{variable}{MONTH:02d}.nc"
        ds.to_netcdf(p, engine="h5netcdf", encoding=enc)
        paths.append(p)
    ds, enc = gebco()
    p = out / "gebco_sample.nc"
    ds.to_netcdf(p, engine="scipy", format="NETCDF3_CLASSIC", encoding=enc)
    paths.append(p)
    return paths


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=DATA, help="folder (default: the package's data folder)")
    args = ap.parse_args()
    for p in write(args.out):
        print(f"{p} ({p.stat().st_size} bytes)")


if __name__ == "__main__":
    main()
