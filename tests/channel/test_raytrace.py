"""Public dispatch (raytrace) for every profile, against independent references."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad

from aquasim_py.channel import (
    Constant,
    Isogradient,
    Layered,
    Munk,
    PathKind,
    eigenray,
    from_ctd,
    isogradient,
    layered,
    raytrace,
    straight_line_time,
    travel_time,
    travel_time_gradient,
    why_no_path,
)

CTD = from_ctd(
    [2, 50, 100, 200, 400, 700, 1000],
    [22, 20, 15, 11, 8, 5, 4],
    [35.2, 35.1, 35.0, 34.9, 34.8, 34.7, 34.7],
    bottom=1100.0,
)
PROFILES = {
    "constant": Constant(1500.0, bottom=1100.0),
    "isogradient": Isogradient(1480.0, 0.1),
    "isogradient-neg": Isogradient(1530.0, -0.03, bottom=1100.0),
    "layered": Layered([0, 80, 300, 700, 1100], [1510, 1495, 1480, 1488, 1494], bottom=1100.0),
    "munk": Munk(axis_depth=600.0, scale=600.0, bottom=1100.0, n_layers=60),
    "ctd": CTD,
}


def pairs(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    src = rng.uniform([0, 0, 0], [3000, 3000, 1000], (n, 3))
    dst = rng.uniform([0, 0, 0], [3000, 3000, 1000], (n, 3))
    return src, dst


@pytest.mark.parametrize("name", list(PROFILES))
def test_every_profile_gives_arrivals(name: str) -> None:
    ssp = PROFILES[name]
    src, dst = pairs(300, seed=1)
    for mode in ("none", "fallback", "all"):
        ray = eigenray(ssp, src, dst, reflections=mode)
        t = travel_time(ssp, src, dst, reflections=mode)
        np.testing.assert_array_equal(t, ray.time)
        has = ray.path != PathKind.NONE
        assert np.array_equal(has, np.isfinite(ray.time))
        assert has.mean() > 0.8
        dist = np.linalg.norm(dst - src, axis=1)
        _lo, hi = ssp.speed_bounds()
        # strict physical bounds, less the solvers' relative rounding (<= 1e-13, 10x margin)
        assert np.all(ray.time[has] >= dist[has] / hi * (1 - 1e-12))
        assert np.all(ray.length[has] >= dist[has] * (1 - 1e-12))
    reasons = why_no_path(ssp, src, dst)
    none = np.isnan(travel_time(ssp, src, dst, reflections="none"))
    assert np.array_equal(reasons != "", none)


@pytest.mark.exact
def test_dispatch_targets() -> None:
    src, dst = pairs(500, seed=2)
    iso = PROFILES["isogradient"]
    np.testing.assert_array_equal(
        travel_time(iso, src, dst, reflections="none"), isogradient.travel_time(1480.0, 0.1, src, dst)
    )
    munk = PROFILES["munk"]
    np.testing.assert_array_equal(travel_time(munk, src, dst), layered.travel_time(munk.to_layered(), src, dst))
    c = PROFILES["constant"]
    # constant speed: D / c, a few roundings (~3 eps)
    np.testing.assert_allclose(travel_time(c, src, dst), np.linalg.norm(dst - src, axis=1) / 1500.0, rtol=1e-15)
    # isogradient through the layered solver (one layer) agrees with the closed form
    np.testing.assert_allclose(
        layered.travel_time(iso.to_layered(), src, dst, reflections="none"),
        isogradient.travel_time(1480.0, 0.1, src, dst),
        rtol=1e-12,
    )  # 2 x 1e-13, 5x margin


@pytest.mark.parametrize("name", ["constant", "isogradient-neg", "layered", "ctd"])
def test_reflection_modes(name: str) -> None:
    ssp = PROFILES[name]
    src, dst = pairs(300, seed=3)
    none = eigenray(ssp, src, dst, reflections="none")
    fb = eigenray(ssp, src, dst, reflections="fallback")
    al = eigenray(ssp, src, dst, reflections="all")
    direct = none.path == PathKind.DIRECT
    np.testing.assert_array_equal(fb.time[direct], none.time[direct])
    assert np.all(fb.path[direct] == PathKind.DIRECT)
    assert np.all(fb.path[~direct] != PathKind.DIRECT)
    ok = np.isfinite(al.time)
    assert np.all(al.time[direct] <= none.time[direct])
    assert np.all(al.time[ok & np.isfinite(fb.time)] <= fb.time[ok & np.isfinite(fb.time)])
    # every reflected arrival equals the explicit reflected eigenray off its boundary
    for kind, boundary in ((PathKind.SURFACE, "surface"), (PathKind.BOTTOM, "bottom")):
        sel = al.path == kind
        if sel.any():
            r = raytrace.reflected_eigenray(ssp, src[sel], dst[sel], boundary)
            # the same computation on a subset: only the batch's summation order may differ
            np.testing.assert_allclose(r.time, al.time[sel], rtol=1e-14)


def test_constant_surface_reflection_is_the_image_distance() -> None:
    """Constant speed: the surface-reflected time is the image-source distance over c."""
    src, dst = pairs(100, seed=4)
    r = raytrace.reflected_eigenray(PROFILES["constant"], src, dst, "surface")
    img = dst.copy()
    img[:, 2] *= -1
    # range refined to 1e-13 relative, time stationary in it: rounding only
    np.testing.assert_allclose(r.time, np.linalg.norm(img - src, axis=1) / 1500.0, rtol=1e-13)


@pytest.mark.parametrize("name", ["layered", "munk", "ctd"])
def test_straight_line_time_is_the_line_integral(name: str) -> None:
    ssp = PROFILES[name]
    lay = ssp.to_layered()
    src, dst = pairs(15, seed=5)
    t = straight_line_time(ssp, src, dst)
    for i in range(len(src)):
        d = dst[i] - src[i]
        # integral of ds / c(z(s)) along the chord, by adaptive quadrature over s in [0, 1]
        kinks = [(zk - src[i, 2]) / d[2] for zk in lay.depths if d[2] != 0 and 0 < (zk - src[i, 2]) / d[2] < 1]
        ref = (
            np.linalg.norm(d)
            * quad(
                lambda u: 1.0 / float(lay.speed(src[i, 2] + u * d[2])),
                0.0,
                1.0,
                points=kinks or None,
                epsabs=0,
                epsrel=1e-13,
                limit=200,
            )[0]
        )
        assert abs(t[i] - ref) < 1e-12 * ref  # quad asked for 1e-13 relative; 10x margin
    # equal depths: distance over the local speed; isogradient: eqs 23-24
    a, b = np.array([0, 0, 321.0]), np.array([1500, 0, 321.0])
    assert straight_line_time(ssp, a, b) == pytest.approx(1500.0 / float(lay.speed(321.0)), rel=1e-14)
    iso = PROFILES["isogradient"]
    np.testing.assert_array_equal(
        straight_line_time(iso, src, dst), isogradient.straight_line_time(1480.0, 0.1, src, dst)
    )


@pytest.mark.parametrize("name", list(PROFILES))
def test_gradient_matches_finite_differences(name: str) -> None:
    ssp = PROFILES[name]
    src, dst = pairs(40, seed=6)
    g = travel_time_gradient(ssp, src, dst)
    h = 1e-2
    fd = np.empty_like(g)
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        fd[:, k] = (travel_time(ssp, src, dst + e) - travel_time(ssp, src, dst - e)) / (2 * h)
    ok = np.isfinite(g).all(axis=1) & np.isfinite(fd).all(axis=1)
    assert ok.sum() >= 30
    err = np.linalg.norm(g[ok] - fd[ok], axis=1) / np.linalg.norm(g[ok], axis=1)
    # tolerance: central-difference truncation ~ h^2 / (6 D^2) relative (< 2e-9 here, D >=
    # 299 m at seed 6; < 1.7e-7 at any D >= 10 m) plus the two times' error (1e-13 t each, ~4 s) over 2h, relative to
    # |g| >= 1/1510 s/m (< 3e-8): 1e-6 keeps a 5x margin
    assert err.max() < 1e-6


def test_reasons_and_errors() -> None:
    iso = Isogradient(1530.0, -0.1, bottom=500.0)
    a, b = np.array([0, 0, 10.0]), np.array([3000, 0, 10.0])
    assert np.isnan(travel_time(iso, a, b, reflections="none"))
    assert why_no_path(iso, a, b) == layered.REASON_SURFACE
    e = eigenray(iso, a, b, reflections="fallback")
    assert e.path in (PathKind.SURFACE, PathKind.BOTTOM)
    assert why_no_path(PROFILES["constant"], a, [0, 0, 2000.0]) == layered.REASON_OUTSIDE
    assert why_no_path(iso, a, [100, 0, 20.0]) == ""
    with pytest.raises(ValueError):
        travel_time(iso, a, b, reflections="maybe")
    with pytest.raises(ValueError):
        travel_time(iso, [0, 0], b)
