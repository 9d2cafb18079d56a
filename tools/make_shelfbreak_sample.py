"""Write aquasim_py/channel/data/shelfbreak.nc: an idealised summer shelf-break front over a
continental slope, built from published climatological values of the Middle Atlantic Bight.

What it is: a smooth analytic reconstruction (no measured casts are shipped), on a grid across the
shelf break (x, 1 km spacing, -30 km on the shelf to +30 km over the slope; y, two columns 100 km
apart, identical: the front is uniform along-shelf), 0-2000 m deep:

* bathymetry: a 60 m deep shelf deepening to 100 m at the shelf break (x = 0, the ~100 m isobath
  where the front's foot sits), then a 3 % continental slope (about 1.7 deg; the MAB slope is
  2-4 deg between the 100 and 2000 m isobaths) down to 2000 m;
* shelf water: a warm, fresh surface layer over the "cold pool": 22 deg C and 32.6 PSU in a
  15 m mixed layer, a thermocline to 9.5 deg C and 32.9 PSU at 30 m, 9 deg C and 33.2 PSU at the
  bottom;
* slope water: 23 deg C and 34.2 PSU at the surface, 14 deg C and 35.3 PSU at 100 m, 12 deg C
  and 35.4 PSU at 200 m, then North Atlantic Central Water cooling to 6 deg C (35.0 PSU) at
  500 m, 4.2 deg C (34.97 PSU) at 1000 m and 3.5 deg C (34.96 PSU) at 2000 m;
* the front: the boundary between the two (the 34.5 PSU isohaline) meets the bottom at the
  shelf break and rises seaward with a slope of 3e-3 (100 m over 33 km), shelf water lying over
  slope water; across it the properties blend as tanh(distance / 3 km).

Sources of the values (rounded): Linder, C. A. and Gawarkiewicz, G. (1998), "A climatology of
the shelfbreak front in the Middle Atlantic Bight", J. Geophys. Res. 103(C9), 18405-18423 (the
foot of the front at the 80-100 m isobaths, the front's slope of order 1e-3 to 5e-3, summer
shelf and slope water temperatures and salinities, the cold pool); Houghton, R. W. et al.
(1982), "The Middle Atlantic Bight cold pool", J. Phys. Oceanogr. 12, 1019-1029 (cold-pool
temperatures 8-10 deg C below a summer thermocline at 20-30 m); the deep slope-water values are
the standard North Atlantic Central / Deep Water T-S relation. The sound speed follows through
TEOS-10 (gsw) when the package reads the file (latitude 40 N, longitude 70 W).

Run: ``python tools/make_shelfbreak_sample.py`` (needs xarray and scipy; writes netCDF3 with the
scipy engine, about 80 kB). The output is deterministic (no random values).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parents[1] / "aquasim_py" / "channel" / "data" / "shelfbreak.nc"

# (depth m, temperature deg C, salinity PSU)
SHELF = np.array(
    [[0, 22.0, 32.6], [15, 21.5, 32.6], [30, 9.5, 32.9], [60, 9.0, 33.1], [100, 9.0, 33.2], [2000, 9.0, 33.2]]
)
SLOPE = np.array(
    [
        [0, 23.0, 34.2],
        [15, 22.5, 34.3],
        [50, 16.0, 35.0],
        [100, 14.0, 35.3],
        [200, 12.0, 35.4],
        [500, 6.0, 35.0],
        [1000, 4.2, 34.97],
        [2000, 3.5, 34.96],
    ]
)
FRONT_SLOPE = 3e-3  # rise of the front per metre seaward
FRONT_WIDTH_M = 3000.0


def depth_of_floor(x: np.ndarray) -> np.ndarray:
    shelf = 100.0 + 40.0 * x / 30000.0  # 60 m at -30 km, 100 m at the break
    slope = 100.0 + 0.03 * x
    return np.where(x < 0.0, shelf, np.minimum(slope, 2000.0))


def fields(x: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Temperature and salinity (len(x), len(z))."""
    X, Z = np.meshgrid(x, z, indexing="ij")
    # seaward distance of each point from the front (shelf water where negative): the front
    # passes through (0, 100 m) and rises seaward, depth 100 - FRONT_SLOPE * x
    front_depth = 100.0 - FRONT_SLOPE * X
    dist = X - (100.0 - Z) / FRONT_SLOPE  # horizontal distance from the front at this depth
    dist = np.where(front_depth > 0.0, dist, X + 1e9)  # seaward of the outcrop: slope water
    w = 0.5 * (1.0 + np.tanh(dist / FRONT_WIDTH_M))  # 0 shelf water, 1 slope water
    t_shelf = np.interp(Z, SHELF[:, 0], SHELF[:, 1])
    s_shelf = np.interp(Z, SHELF[:, 0], SHELF[:, 2])
    t_slope = np.interp(Z, SLOPE[:, 0], SLOPE[:, 1])
    s_slope = np.interp(Z, SLOPE[:, 0], SLOPE[:, 2])
    return t_shelf + w * (t_slope - t_shelf), s_shelf + w * (s_slope - s_shelf)


def build():  # -> xarray.Dataset
    import xarray as xr

    x = np.arange(-30000.0, 30000.0 + 1.0, 1000.0)
    y = np.array([-50000.0, 50000.0])
    z = np.concatenate([np.arange(0.0, 100.0, 10.0), np.arange(100.0, 300.0, 25.0), np.arange(300.0, 2001.0, 100.0)])
    T, S = fields(x, z)
    T3 = np.repeat(T[:, None, :], y.size, axis=1)
    S3 = np.repeat(S[:, None, :], y.size, axis=1)
    floor = np.repeat(depth_of_floor(x)[:, None], y.size, axis=1)
    ds = xr.Dataset(
        {
            "temperature": (("x", "y", "depth"), T3, {"units": "degC", "long_name": "in-situ temperature (ITS-90)"}),
            "salinity": (("x", "y", "depth"), S3, {"units": "1", "long_name": "practical salinity (PSS-78)"}),
            "bathymetry": (("x", "y"), floor, {"units": "m", "positive": "down"}),
        },
        coords={
            "x": ("x", x, {"units": "m", "long_name": "across-shelf distance from the shelf break, seaward"}),
            "y": ("y", y, {"units": "m", "long_name": "along-shelf distance"}),
            "depth": ("depth", z, {"units": "m", "positive": "down"}),
        },
        attrs={
            "title": "Idealised summer shelf-break front, Middle Atlantic Bight (aquasim-py sample)",
            "source": "tools/make_shelfbreak_sample.py: analytic reconstruction from published climatological values",
            "references": "Linder & Gawarkiewicz 1998 JGR 103(C9) 18405; Houghton et al. 1982 JPO 12 1019",
            "latitude": 40.0,
            "longitude": -70.0,
        },
    )
    return ds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    build().to_netcdf(args.out, engine="scipy", format="NETCDF3_64BIT")
    print(f"{args.out} ({args.out.stat().st_size} bytes)")


if __name__ == "__main__":
    main()
