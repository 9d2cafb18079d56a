"""Latitude / longitude grids in a scenario's local east-north frame (aquasim_py.channel.geographic):
the frame against geodesics, bilinear interpolation at and between nodes, the kinks the ray
tracer samples against a brute-force root search, and the sections built from them."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("pyproj")
pytest.importorskip("xarray")

from pyproj import Geod
from scipy.optimize import brentq

from aquasim_py.channel import rangedep
from aquasim_py.channel.data import sample_path
from aquasim_py.channel.environment import Environment
from aquasim_py.channel.geographic import (
    GeographicBathymetry,
    GeographicField,
    LatLonGrid,
    LocalFrame,
)
from aquasim_py.channel.oceanfiles import read_gebco, read_woa

FRAME = LocalFrame(40.0, -70.0)
WGS84 = Geod(ellps="WGS84")


def test_frame_distances_and_bearings_from_the_origin_are_geodesic() -> None:
    """The azimuthal equidistant frame: distance and bearing from the origin are the WGS 84
    geodesic's (Karney's algorithm, pyproj.Geod: an independent path through PROJ), to 1e-6 m
    and 1e-9 rad; points go back and forth to 1e-8 m."""
    rng = np.random.default_rng(3)
    lat = 40.0 + rng.uniform(-0.3, 0.3, 200)
    lon = -70.0 + rng.uniform(-0.4, 0.4, 200)
    x, y = FRAME.to_xy(lat, lon)
    az, _, dist = WGS84.inv(np.full(200, -70.0), np.full(200, 40.0), lon, lat)
    np.testing.assert_allclose(np.hypot(x, y), dist, rtol=0, atol=1e-6)
    bearing = np.arctan2(x, y)
    np.testing.assert_allclose(np.angle(np.exp(1j * (bearing - np.radians(az)))), 0.0, atol=1e-9)
    lat2, lon2 = FRAME.to_latlon(x, y)
    x2, y2 = FRAME.to_xy(lat2, lon2)
    assert np.max(np.hypot(x2 - x, y2 - y)) < 1e-8


def test_frame_is_true_to_scale_between_nearby_points() -> None:
    """Within 20 km of the origin (in x and y), the frame's distance between two points is the
    geodesic's to 4e-6 relative: the projection's scale across the radius is theta / sin(theta)
    ~ 1 + theta^2 / 6, theta = r / R, 3.2e-6 at the box's corners (28 km)."""
    rng = np.random.default_rng(4)
    p = rng.uniform(-20000.0, 20000.0, (200, 2, 2))
    lat, lon = FRAME.to_latlon(p[..., 0], p[..., 1])
    _, _, dist = WGS84.inv(lon[:, 0], lat[:, 0], lon[:, 1], lat[:, 1])
    flat = np.hypot(*(p[:, 1] - p[:, 0]).T)
    assert np.max(np.abs(flat - dist) / dist) < 4e-6


def test_frame_pickles() -> None:
    import pickle

    fr = pickle.loads(pickle.dumps(FRAME))
    assert fr == FRAME
    np.testing.assert_array_equal(fr.to_xy(40.1, -70.1), FRAME.to_xy(40.1, -70.1))


def test_bilinear_in_latitude_and_longitude() -> None:
    """A node's value wherever it lands in the frame; the mean of the four corners at a cell's
    centre in latitude / longitude; the edge values beyond the grid."""
    lat = np.array([39.9, 40.0, 40.1])
    lon = np.array([-70.1, -70.0, -69.9, -69.8])
    grid = LatLonGrid(FRAME, lat, lon)
    v = np.arange(12.0).reshape(3, 4) ** 1.5
    x, y = grid.nodes_xy()
    np.testing.assert_allclose(grid.bilinear(v, x, y), v, rtol=0, atol=1e-9)
    cx, cy = FRAME.to_xy(39.95, -69.95)
    assert grid.bilinear(v, cx, cy) == pytest.approx(v[0:2, 1:3].mean(), abs=1e-9)
    fx, fy = FRAME.to_xy(39.0, -71.0)  # south-west of the grid
    assert grid.bilinear(v, fx, fy) == pytest.approx(v[0, 0])


def test_grid_across_the_antimeridian() -> None:
    """A subset stored as 179.5 ... -179.5 (across the antimeridian) is one increasing grid."""
    fr = LocalFrame(10.0, 180.0)
    grid = LatLonGrid(fr, [9.5, 10.5], [179.5, -179.5])
    np.testing.assert_allclose(grid.longitude, [179.5, 180.5])
    v = np.array([[0.0, 1.0], [2.0, 3.0]])
    x, y = fr.to_xy(10.0, 180.0)
    assert grid.bilinear(v, x, y) == pytest.approx(1.5, abs=1e-9)
    assert grid.covers(9.9, 10.1, 179.9, -179.9)


def _true_crossings(grid: LatLonGrid, x0, y0, ux, uy, ra, rb):
    """Brute force: every r in [ra, rb] where the line crosses a grid parallel or meridian, by
    sampling every metre and brentq on the exact projection (column index, r)."""
    r = np.arange(ra, rb + 1.0, 1.0)
    lat, lon = grid.latlon(x0 + r * ux, y0 + r * uy)
    out = []
    for col, (vals, g, which) in enumerate(
        [(lat, v, 0) for v in grid.latitude] + [(lon, v, 1) for v in grid.longitude]
    ):
        f = vals - g
        for i in np.flatnonzero(np.sign(f[:-1]) * np.sign(f[1:]) < 0):

            def h(s: float) -> float:
                return float(grid.latlon(x0 + s * ux, y0 + s * uy)[which] - g)

            out.append((col, brentq(h, r[i], r[i + 1], xtol=1e-12, rtol=1e-15)))
    return out


def test_crossings_against_brute_force() -> None:
    """Every crossing of a grid line within [0, length] is found, at the brute force's distance
    to 1e-6 m; the nearest one before 0 and after length of each link are there too."""
    grid = read_gebco(sample_path("gebco"), FRAME).grid
    rng = np.random.default_rng(7)
    n = 12
    a = rng.uniform([-4000, 0], [4000, 9000], (n, 2))
    b = rng.uniform([-4000, 0], [4000, 9000], (n, 2))
    d = b - a
    length = np.hypot(*d.T)
    ux, uy = d[:, 0] / length, d[:, 1] / length
    got = grid.crossings(a[:, 0], a[:, 1], ux, uy, length)
    pad = 1.5 * grid.cell_m
    for i in range(n):
        truth = _true_crossings(grid, a[i, 0], a[i, 1], ux[i], uy[i], -pad, length[i] + pad)
        inner = [(c, r) for c, r in truth if 0.0 < r < length[i]]
        assert inner, "a link several cells long crosses grid lines"
        for c, r in inner:
            assert got[i, c] == pytest.approx(r, abs=1e-6)
        before = max((r for _, r in truth if r <= 0.0), default=None)
        after = min((r for _, r in truth if r >= length[i]), default=None)
        row = got[i][np.isfinite(got[i])]
        assert before is not None and np.max(row[row <= 0.0]) == pytest.approx(before, abs=1e-6)
        assert after is not None and np.min(row[row >= length[i]]) == pytest.approx(after, abs=1e-6)
        # nothing found that is not a crossing
        for c in np.flatnonzero(np.isfinite(got[i])):
            assert any(cc == c and abs(rr - got[i, c]) < 1e-6 for cc, rr in truth)


def test_crossings_are_geographic_points() -> None:
    """Sliding an end of a link along its line leaves the kinks where they are, to 1e-8 m (the
    projection's own round trip is good to ~4e-9 m: test_frame_distances_...)."""
    grid = read_gebco(sample_path("gebco"), FRAME).grid
    x0, y0 = np.array([-3000.0]), np.array([1500.0])
    ux, uy = np.array([0.6]), np.array([0.8])
    base = grid.crossings(x0, y0, ux, uy, np.array([6000.0]))[0]
    for shift in (0.37, 13.0, 250.0):
        moved = grid.crossings(x0 + shift * ux, y0 + shift * uy, ux, uy, np.array([6000.0 - 2 * shift]))[0]
        both = np.isfinite(base) & np.isfinite(moved)
        inside = both & (base > shift) & (base < 6000.0 - shift)
        assert inside.sum() > 10
        np.testing.assert_allclose(moved[inside] + shift, base[inside], rtol=0, atol=1e-8)


def _environment() -> Environment:
    box = FRAME.footprint([-3000, 1000], [3000, 9000])
    woa = read_woa([sample_path("woa23_t08"), sample_path("woa23_s08")], FRAME, month=8, box=box)
    return Environment(woa, read_gebco(sample_path("gebco"), FRAME, box=box))


def test_sections_sample_the_files_between_their_kinks() -> None:
    """The tracer's section of a link samples the environment at the grid's crossings: along the
    link, the section's smooth floor passes through the file's floor (bicubic in latitude /
    longitude) at them and departs from it between them by at most h^2 / 8 times the largest
    difference of the two curves' second derivatives (two curves with equal values and slopes at
    both ends of each interval h), far below the polyline of the same samples; a missed crossing
    would leave metres. The sound speed's columns are linear between the crossings: within a
    quarter of the grid's largest cell twist |c00 - c10 - c01 + c11| (bilinear's departure from
    its chord between two edge crossings)."""
    env = _environment()
    bathy = env.bathymetry
    assert isinstance(bathy, GeographicBathymetry) and isinstance(env.field, GeographicField)
    c = env.field.speeds
    c_twist = np.max(np.abs(c[:-1, :-1] - c[1:, :-1] - c[:-1, 1:] + c[1:, 1:]))
    rng = np.random.default_rng(11)
    src = np.c_[rng.uniform([-2500, 2000], [2500, 8000], (8, 2)), np.full(8, 20.0)]
    dst = np.c_[rng.uniform([-2500, 2000], [2500, 8000], (8, 2)), np.full(8, 30.0)]
    sec = rangedep.sections(env, src, dst)
    for i in range(8):
        r, cols, fz = sec.link(i)
        q = np.linspace(r[0], r[-1], 4001)
        x, y = src[i, 0] + q * sec.ux[i], src[i, 1] + q * sec.uy[i]
        np.testing.assert_allclose(fz, env.depth(src[i, 0] + r * sec.ux[i], src[i, 1] + r * sec.uy[i]), atol=1e-9)
        floor_err = np.abs(sec.floor_at(i, q) - env.depth(x, y))
        h = 1e-2
        true2 = (env.depth(x + h * sec.ux[i], y + h * sec.uy[i]) - 2 * env.depth(x, y)
                 + env.depth(x - h * sec.ux[i], y - h * sec.uy[i])) / h**2  # fmt: skip
        ours2 = (sec.floor_at(i, q + h) - 2 * sec.floor_at(i, q) + sec.floor_at(i, q - h)) / h**2
        bound = np.diff(r).max() ** 2 / 8.0 * np.max(np.abs(ours2 - true2))
        assert floor_err.max() <= bound + 1e-6, (i, floor_err.max(), bound)
        assert floor_err.max() < 0.5 * np.abs(np.interp(q, r, fz) - env.depth(x, y)).max()
        speed = env.field.columns(x, y)
        lin = np.stack([np.interp(q, r, cols[:, k]) for k in range(env.field.depths.size)], axis=1)
        assert np.max(np.abs(lin - speed)) <= c_twist / 4 + 1e-6


def test_floor_is_bicubic_through_the_nodes_with_its_slope() -> None:
    """The file's floor passes through every node, and the slope the tracer's smooth floor takes
    (slope_along) is the derivative of depth along the line (central differences, 1 mm: their
    truncation and rounding are ~1e-7 of the slope's scale here)."""
    bathy = read_gebco(sample_path("gebco"), FRAME)
    x, y = bathy.grid.nodes_xy()
    np.testing.assert_allclose(bathy.depth(x, y), bathy.depths, rtol=0, atol=1e-8)
    rng = np.random.default_rng(5)
    p = rng.uniform([-3000, 1000], [3000, 9000], (300, 2))
    th = rng.uniform(0.0, 2 * np.pi, 300)
    ux, uy = np.cos(th), np.sin(th)
    s = bathy.slope_along(p[:, 0], p[:, 1], ux, uy)
    assert s is not None
    h = 1e-3
    fd = (bathy.depth(p[:, 0] + h * ux, p[:, 1] + h * uy) - bathy.depth(p[:, 0] - h * ux, p[:, 1] - h * uy)) / (2 * h)
    np.testing.assert_allclose(s, fd, rtol=0, atol=1e-6)
    assert np.abs(s).max() > 0.01  # the sample's slope, not a flat patch
