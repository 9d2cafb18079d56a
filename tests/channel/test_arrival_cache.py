"""The per-link arrival cache (aquasim_py.channel.arrival_cache) against the exact search."""

from __future__ import annotations

import numpy as np
import pytest
from test_rangedep import _front_env

from aquasim_py.channel.arrival_cache import ArrivalCache
from aquasim_py.channel.arrivals import arrivals


def _links(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    s = np.c_[rng.uniform(0, 6000, n), rng.uniform(-2000, 2000, n), rng.uniform(5, 140, n)]
    d = np.c_[rng.uniform(0, 6000, n), rng.uniform(-2000, 2000, n), rng.uniform(5, 140, n)]
    return s, d


def test_served_delays_within_bound_and_1e7() -> None:
    """Random moves of both ends inside the region the Taylor tier serves (a front over a
    slope, every arrival up to 2 bounces): each served delay is within the cache's bound of the
    same eigenray followed exactly to the moved ends, the bound is <= 1e-7 s, and wherever a new
    search finds the same arrival set, within the bound of the search's delays too."""
    from aquasim_py.channel.arrivals import follow

    env = _front_env()
    rng = np.random.default_rng(3)
    n = 40
    s, d = _links(rng, n)
    ids = np.arange(n)
    cache = ArrivalCache(env, n, max_bounces=2, tol_s=1e-7)
    ref = cache.get(ids, s, d)
    radius = cache.radius(ids)
    assert (radius > 0).sum() >= n // 2 and radius.max() <= 0.5
    served, same_set = 0, 0
    for _ in range(4):
        u = rng.normal(size=(n, 6))
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        f = (rng.uniform(0, 1, n) ** (1 / 6) * radius)[:, None]  # uniform in the 6-D ball
        s2, d2 = s + u[:, :3] * f, d + u[:, 3:] * f
        bound = cache.bound(ids, s2, d2)
        got = cache.get(ids, s2, d2)
        fol, ok = follow(env, ref, s2, d2, max_bounces=2)
        new = arrivals(env, s2, d2, max_bounces=2)
        moved_and_served = np.flatnonzero(np.isfinite(bound) & (radius > 0))
        served += moved_and_served.size
        for i in moved_and_served:
            assert bound[i] <= 1e-7
            g = slice(got.offsets[i], got.offsets[i + 1])
            og = np.lexsort((got.launch_angle[g], got.bounce_code[g]))
            if ok[i]:
                f_ = slice(fol.offsets[i], fol.offsets[i + 1])
                of = np.lexsort((fol.launch_angle[f_], fol.bounce_code[f_]))
                np.testing.assert_array_equal(got.bounce_code[g][og], fol.bounce_code[f_][of])
                assert np.all(np.abs(got.delay[g][og] - fol.delay[f_][of]) <= bound[i])
            e = slice(new.offsets[i], new.offsets[i + 1])
            if sorted(got.bounce_code[g]) == sorted(new.bounce_code[e]):
                same_set += 1
                oe = np.lexsort((new.launch_angle[e], new.bounce_code[e]))
                assert np.all(np.abs(got.delay[g][og] - new.delay[e][oe]) <= bound[i] + 1e-9)
    assert served >= 2 * n  # most links are served (those the tier refused do not move)
    assert same_set >= 0.9 * served


def test_second_order_term_is_there() -> None:
    """The Hessian term matters: on 0.4 m moves the served delays are far closer to the exact
    ones (the same eigenrays followed) than a first-order expansion with the exact gradient
    (central differences of followed delays over +-1 mm, independent of the cache) is."""
    from aquasim_py.channel.rangedep import track

    env = _front_env()
    rng = np.random.default_rng(8)
    n = 20
    s, d = _links(rng, n)
    ids = np.arange(n)
    cache = ArrivalCache(env, n, max_bounces=1)
    ref = cache.get(ids, s, d)
    q = int(np.diff(ref.offsets).max())
    rows, cols = ref.link, np.arange(ref.delay.size) - ref.offsets[ref.link]

    def per_link(values: np.ndarray, fill: float) -> np.ndarray:
        out = np.full((n, q), fill)
        out[rows, cols] = values
        return out

    th = per_link(ref.launch_angle, np.nan)
    code = per_link(ref.bounce_code, -1).astype(np.int64)

    def exact(ds: np.ndarray, dd: np.ndarray) -> np.ndarray:
        """(n, q) the reference's eigenrays followed to the moved ends, in its order."""
        return track(env, s + ds, d + dd, 1, th, code)

    u = rng.normal(size=(n, 6))
    u *= 0.4 / np.linalg.norm(u, axis=1, keepdims=True)
    s2, d2 = s + u[:, :3], d + u[:, 3:]
    served = np.isfinite(cache.bound(ids, s2, d2))
    got = cache.get(ids, s2, d2)
    t_new = exact(u[:, :3], u[:, 3:])
    grad_dot = np.zeros((n, q))
    h = 1e-3
    for k in range(6):
        e = np.zeros((n, 6))
        e[:, k] = h
        grad_dot += (exact(e[:, :3], e[:, 3:]) - exact(-e[:, :3], -e[:, 3:])) / (2 * h) * u[:, k : k + 1]
    t_ref = per_link(ref.delay, np.nan)
    # the served delays in the reference's order: match each by its launch angle
    err1, err2 = [], []
    for i in np.flatnonzero(served):
        g = slice(got.offsets[i], got.offsets[i + 1])
        for j in range(int(np.diff(ref.offsets)[i])):
            if not (np.isfinite(t_new[i, j]) and np.isfinite(grad_dot[i, j])):
                continue
            k = int(np.argmin(np.abs(got.launch_angle[g] - th[i, j]) + 10.0 * (got.bounce_code[g] != code[i, j])))
            err2.append(abs(got.delay[g][k] - t_new[i, j]))
            err1.append(abs(t_ref[i, j] + grad_dot[i, j] - t_new[i, j]))
    assert len(err2) >= 2 * n
    assert np.median(err2) < 0.1 * np.median(err1)
    assert max(err2) <= 1e-7


def test_moves_beyond_the_bound_are_solved_again() -> None:
    env = _front_env()
    rng = np.random.default_rng(4)
    s, d = _links(rng, 10)
    ids = np.arange(10)
    cache = ArrivalCache(env, 10, max_bounces=1)
    cache.get(ids, s, d)
    moved = d + np.array([5.0, 0.0, 0.0])
    got = cache.get(ids, s, moved)
    assert cache.stats.hits == 0 and cache.stats.misses == 20
    exact = arrivals(env, s, moved, max_bounces=1)
    np.testing.assert_allclose(got.delay, exact.delay, rtol=0, atol=1e-12)


def test_searches_of_fast_moving_links_are_not_expanded() -> None:
    """The expansion is made at a link's first request and where its ends moved little since
    the last one (<= 0.5 m / 13): a link moved 5 m per request is searched without it (no Taylor
    region), one moved 1 cm gets it again and is then served by Taylor."""
    env = _front_env()
    rng = np.random.default_rng(7)
    s, d = _links(rng, 12)
    ids = np.arange(12)
    cache = ArrivalCache(env, 12, max_bounces=1, follow_m=0.0)
    cache.get(ids, s, d)
    expanded = cache.radius(ids) > 0
    assert expanded.sum() >= 6 and cache.stats.not_expanded == 0
    step = np.array([5.0, 0.0, 0.0])
    cache.get(ids, s, d + step)
    assert cache.stats.misses == 24 and cache.stats.not_expanded == 12
    assert np.all(cache.radius(ids) == 0.0)
    small = np.array([0.01, 0.0, 0.0])
    cache.get(ids, s, d + step + small)  # searched (no region), now expanded
    assert cache.stats.misses == 36 and cache.stats.not_expanded == 12
    again = cache.radius(ids) > 0
    assert again.sum() >= 6
    hits = cache.stats.hits
    got = cache.get(ids, s, d + step + 2 * small)
    assert cache.stats.hits - hits == again.sum()
    exact = arrivals(env, s, d + step + 2 * small, max_bounces=1)
    np.testing.assert_allclose(got.delay, exact.delay, rtol=0, atol=1e-7)


def test_bad_ids() -> None:
    cache = ArrivalCache(_front_env(), 3)
    with pytest.raises(ValueError, match="link ids"):
        cache.get([5], [[0, 0, 10]], [[100, 0, 10]])
    with pytest.raises(ValueError, match="twice"):
        cache.get([1, 1], [[0, 0, 10]] * 2, [[100, 0, 10]] * 2)


@pytest.mark.exact
def test_follow_tier_matches_the_exact_search() -> None:
    """The following tier (no Taylor tier): both ends moved by up to 0.8 m (inside follow_m =
    1 m) are served by following the last search's eigenrays; every followed link's arrivals
    equal a new exact search's (same bounce sequences, delays to 1e-9 s, the search's own
    accuracy) wherever the search found the same set, and the cache never serves a link it did
    not follow or search."""
    env = _front_env()
    rng = np.random.default_rng(5)
    n = 30
    s, d = _links(rng, n)
    ids = np.arange(n)
    cache = ArrivalCache(env, n, max_bounces=2, tol_s=0.0, follow_m=1.0)
    cache.get(ids, s, d)
    u = rng.normal(size=(n, 6))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    f = rng.uniform(0.2, 0.8, (n, 1))
    s2, d2 = s + u[:, :3] * f, d + u[:, 3:] * f
    got = cache.get(ids, s2, d2)
    assert cache.stats.follows >= n // 2  # most links are followed, not searched
    assert cache.stats.follows + cache.stats.misses == 2 * n
    exact = arrivals(env, s2, d2, max_bounces=2)
    same = 0
    for i in range(n):
        g = slice(got.offsets[i], got.offsets[i + 1])
        e = slice(exact.offsets[i], exact.offsets[i + 1])
        if sorted(got.bounce_code[g]) != sorted(exact.bounce_code[e]) or got.delay[g].size != exact.delay[e].size:
            continue  # a fold's pair the search missed, or a path that appeared: the docstring's caveat
        same += 1
        np.testing.assert_allclose(np.sort(got.delay[g]), np.sort(exact.delay[e]), rtol=0, atol=1e-9)
    assert same >= n - 3
    # the positions of the cached solutions: the followed links' new ends, the others' too
    # (searched there)
    ps, pd = cache.positions(ids)
    np.testing.assert_array_equal(ps, s2)
    np.testing.assert_array_equal(pd, d2)
    with pytest.raises(ValueError, match="never requested"):
        ArrivalCache(env, 2).positions([1])
    # a move beyond follow_m is searched again
    m0 = cache.stats.misses
    cache.get(ids, s2 + np.array([3.0, 0.0, 0.0]), d2)
    assert cache.stats.misses - m0 == n


def test_follow_keeps_delays_and_levels() -> None:
    """Following writes the secant's last slope as the ray-tube width: the levels of followed
    arrivals equal the exact search's (central difference) to 0.01 dB on 1 m moves."""
    from aquasim_py.channel.arrivals import follow

    env = _front_env()
    rng = np.random.default_rng(6)
    s, d = _links(rng, 20)
    base = arrivals(env, s, d, max_bounces=1)
    d2 = d + np.array([0.6, -0.5, 0.3])
    fol, ok = follow(env, base, s, d2, max_bounces=1)
    exact = arrivals(env, s, d2, max_bounces=1)
    assert ok.sum() >= 15
    for i in np.flatnonzero(ok):
        g = slice(fol.offsets[i], fol.offsets[i + 1])
        e = slice(exact.offsets[i], exact.offsets[i + 1])
        if sorted(fol.bounce_code[g]) != sorted(exact.bounce_code[e]):
            continue
        og, oe = np.argsort(fol.bounce_code[g], kind="stable"), np.argsort(exact.bounce_code[e], kind="stable")
        np.testing.assert_allclose(fol.delay[g][og], exact.delay[e][oe], rtol=0, atol=1e-9)
        np.testing.assert_allclose(fol.level_db[g][og], exact.level_db[e][oe], rtol=0, atol=0.01)


def test_section_structure_changes_are_not_served() -> None:
    """Where an end crosses a kink of the environment (here a grid line of the shelf-break
    sample's gridded floor and field, x = 1000 m), the section changes its columns and the
    delays' slopes may jump there: the structure hash of the section changes, does not depend on
    the other links of the batch, and the Taylor tier does not serve across it, even inside its
    region (the link runs at 45 degrees, so its stencil, +-0.5 m along and across it, stays 0.05 m
    short of the grid line; the request is followed or searched: exact)."""
    from aquasim_py.channel.data import shelfbreak
    from aquasim_py.channel.rangedep import sections

    env = shelfbreak()
    d_before = np.array([[999.6, 300.0, 60.0]])
    s = d_before - np.array([[300.0, 300.0, 20.0]])
    d_after = d_before + np.array([0.45, 0.0, 0.0])
    other = np.array([[-200.0, -900.0, 30.0]])
    st = sections(env, s, d_before).structure
    assert sections(env, np.r_[other, s], np.r_[d_after, d_before]).structure[1] == st[0]
    assert sections(env, s, d_after).structure[0] != st[0]
    assert sections(env, s, d_before + np.array([0.3, -0.2, 0.3])).structure[0] == st[0]  # no kink crossed
    cache = ArrivalCache(env, 1, max_bounces=2)
    cache.get([0], s, d_before)
    assert cache.radius([0])[0] >= 0.45  # the move below is inside the region
    hits = cache.stats.hits
    got = cache.get([0], s, d_after)
    assert cache.stats.hits == hits
    exact = arrivals(env, s, d_after, max_bounces=2)
    if sorted(got.bounce_code) == sorted(exact.bounce_code):
        np.testing.assert_allclose(np.sort(got.delay), np.sort(exact.delay), rtol=0, atol=1e-9)


def test_reversed_arrivals_are_the_other_ends_search() -> None:
    """A link searched from its other end and travelled backwards (reversed_arrivals) lists the
    search's eigenrays: the same bounce sequences, launch angles the search's to 1e-6 rad (the
    two sections sample the field from opposite ends), end speeds swapped, ray-tube widths by
    reciprocity to 1e-3 and delays to 1e-9 s."""
    from aquasim_py.channel.arrivals import reversed_arrivals

    env = _front_env()
    s, d = _links(np.random.default_rng(8), 12)
    fwd = arrivals(env, s, d, max_bounces=2)
    back = reversed_arrivals(arrivals(env, d, s, max_bounces=2))
    assert fwd.delay.size == back.delay.size > 0
    for i in range(12):
        g = slice(fwd.offsets[i], fwd.offsets[i + 1])
        b = slice(back.offsets[i], back.offsets[i + 1])
        og, ob = np.lexsort((fwd.delay[g], fwd.bounce_code[g])), np.lexsort((back.delay[b], back.bounce_code[b]))
        np.testing.assert_array_equal(fwd.bounce_code[g][og], back.bounce_code[b][ob])
        np.testing.assert_allclose(fwd.launch_angle[g][og], back.launch_angle[b][ob], rtol=0, atol=1e-6)
        np.testing.assert_allclose(fwd.arrival_angle[g][og], back.arrival_angle[b][ob], rtol=0, atol=1e-6)
        np.testing.assert_allclose(fwd.source_speed[g][og], back.source_speed[b][ob], rtol=0, atol=1e-6)
        np.testing.assert_allclose(fwd.dz_dlaunch[g][og], back.dz_dlaunch[b][ob], rtol=1e-3)
        np.testing.assert_allclose(fwd.delay[g][og], back.delay[b][ob], rtol=0, atol=1e-9)


def test_reverse_links_are_followed_from_the_other_direction() -> None:
    """With n_nodes, a link whose reverse was searched within follow_m of both ends is followed
    from the reverse's eigenrays (no search): the arrivals equal a new search's (sequences,
    delays to 1e-9 s) wherever it finds the same set; beyond follow_m the link is searched, and
    so is a link within follow_m of its own search whose following fails."""
    env = _front_env()
    rng = np.random.default_rng(9)
    n_nodes = 8
    pos = np.c_[rng.uniform(0, 6000, n_nodes), rng.uniform(-2000, 2000, n_nodes), rng.uniform(5, 140, n_nodes)]
    src, dst = np.triu_indices(n_nodes, 1)
    cache = ArrivalCache(env, n_nodes * n_nodes, max_bounces=2, tol_s=0.0, n_nodes=n_nodes)
    cache.get(src * n_nodes + dst, pos[src], pos[dst])  # one direction searched
    assert cache.stats.misses == src.size
    moved = pos + rng.normal(scale=0.3, size=pos.shape)
    got = cache.get(dst * n_nodes + src, moved[dst], moved[src])  # the other, ends moved < 1 m
    assert cache.stats.reversed == cache.stats.follows >= src.size // 2
    assert cache.stats.follows + cache.stats.misses == 2 * src.size
    exact = arrivals(env, moved[dst], moved[src], max_bounces=2)
    same = 0
    for i in range(src.size):
        g = slice(got.offsets[i], got.offsets[i + 1])
        e = slice(exact.offsets[i], exact.offsets[i + 1])
        if sorted(got.bounce_code[g]) != sorted(exact.bounce_code[e]):
            continue
        same += 1
        np.testing.assert_allclose(np.sort(got.delay[g]), np.sort(exact.delay[e]), rtol=0, atol=1e-9)
    assert same >= src.size - 2
    # the reverse's search is the centre: 3 m away, searched
    m0 = cache.stats.misses
    far = moved + np.array([3.0, 0.0, 0.0])
    other = ArrivalCache(env, n_nodes * n_nodes, max_bounces=2, tol_s=0.0, n_nodes=n_nodes)
    other.get(src * n_nodes + dst, pos[src], pos[dst])
    other.get(dst * n_nodes + src, far[dst], far[src])
    assert other.stats.reversed == 0 and other.stats.misses == 2 * src.size
    assert cache.stats.misses == m0
    # a link near its own search is never followed from its reverse: where following it fails
    # (its arrival set changing), it is searched
    from aquasim_py.channel.data import shelfbreak

    shelf = shelfbreak()  # following fails on about half its links moved 0.3 m (docs/channel.md)
    pos = np.c_[rng.uniform(-1000, 2000, n_nodes), rng.uniform(-1400, 1400, n_nodes), rng.uniform(15, 85, n_nodes)]
    both = ArrivalCache(shelf, n_nodes * n_nodes, max_bounces=2, tol_s=0.0, n_nodes=n_nodes)
    fwd, bwd = src * n_nodes + dst, dst * n_nodes + src
    both.get(np.r_[fwd, bwd], pos[np.r_[src, dst]], pos[np.r_[dst, src]])
    u = rng.normal(size=pos.shape)
    near = pos + 0.5 * u / np.linalg.norm(u, axis=1, keepdims=True)
    both.get(np.r_[fwd, bwd], near[np.r_[src, dst]], near[np.r_[dst, src]])  # each followed from its own
    assert both.stats.reversed == 0 and both.stats.misses > 2 * src.size  # some searched again
    with pytest.raises(ValueError, match="n_nodes"):
        ArrivalCache(env, 10, n_nodes=4)


@pytest.mark.parametrize("tol_s", [0.0, 1e-7])
def test_links_with_more_arrivals_than_the_initial_width_are_kept_whole(tol_s: float) -> None:
    """Tables 2 arrivals wide at first: every link is served whole (the exact search's arrivals)
    and then followed like any other, not searched at every request; ``served_by`` names the
    tier of each link."""
    from aquasim_py.channel.arrival_cache import TIERS

    env = _front_env()
    rng = np.random.default_rng(11)
    n = 12
    s, d = _links(rng, n)
    ids = np.arange(n)
    cache = ArrivalCache(env, n, max_bounces=2, tol_s=tol_s, max_arrivals=2)
    got = cache.get(ids, s, d)
    exact = arrivals(env, s, d, max_bounces=2)
    counts = np.diff(exact.offsets)
    assert (counts > 2).sum() >= n // 2  # the case in point
    np.testing.assert_array_equal(np.diff(got.offsets), counts)
    np.testing.assert_array_equal(got.delay, exact.delay)
    np.testing.assert_array_equal(got.bounce_code, exact.bounce_code)
    assert [TIERS[t] for t in cache.served_by] == ["search"] * n
    # unmoved: served as they are; the receivers moved 0.7 m (beyond the Taylor tier's 0.5 m,
    # within following's 1 m): followed, the same arrivals as a new search's
    cache.get(ids, s, d)
    assert set(cache.served_by.tolist()) <= {TIERS.index("same"), TIERS.index("taylor")}
    d2 = d + np.array([0.0, 0.4, 0.5])
    got = cache.get(ids, s, d2)
    tiers = np.array([TIERS[t] for t in cache.served_by])
    assert set(tiers) <= {"follow", "search"} and cache.stats.misses == n + (tiers == "search").sum()
    exact = arrivals(env, s, d2, max_bounces=2)
    for i in np.flatnonzero(tiers == "follow"):
        g = slice(got.offsets[i], got.offsets[i + 1])
        e = slice(exact.offsets[i], exact.offsets[i + 1])
        if sorted(got.bounce_code[g]) == sorted(exact.bounce_code[e]):
            np.testing.assert_allclose(np.sort(got.delay[g]), np.sort(exact.delay[e]), rtol=0, atol=1e-9)
    wide = np.flatnonzero((counts > 2) & (tiers == "follow"))
    assert wide.size >= n // 3


# a shelf-break link (the bundled sample) whose receiver sits where a fold of the direct family is
# in the making: with both ends moved 0.3 m, two more direct eigenrays (4.6 us after the first,
# as strong) appear, away from the six it had (found on the 40-node network of
# tools/bench_arrivals.py, seed 1, the first drift step at 0.3 m/s)
_FOLD_LINK = (
    ([-564.506, 1019.645, 73.757], [-44.427, 437.163, 78.167]),
    ([-564.267, 1019.463, 73.77], [-44.675, 436.993, 78.168]),
)


@pytest.mark.parametrize("reverse", [False, True])
def test_a_fold_born_within_the_follow_radius_is_searched(reverse: bool) -> None:
    """Following the link's known eigenrays cannot see the two born at a fold; the search's
    watched interval there fails its check at the moved ends, so the link is searched and its
    arrival set is the new search's, the two new direct eigenrays included. So too where the
    link is reached from its reverse, whose watch is checked in the direction it was searched."""
    from aquasim_py.channel.arrival_cache import TIERS
    from aquasim_py.channel.data import shelfbreak

    env = shelfbreak()
    (s0, d0), (s1, d1) = (np.array(p)[None] for p in _FOLD_LINK[0]), (np.array(p)[None] for p in _FOLD_LINK[1])
    old = arrivals(env, s0, d0, max_bounces=2)
    new = arrivals(env, s1, d1, max_bounces=2)
    assert (new.bounce_code == 0).sum() == (old.bounce_code == 0).sum() + 2
    cache = ArrivalCache(env, 4, max_bounces=2, tol_s=0.0, n_nodes=2)
    if reverse:  # link 1 -> 0 searched, then 0 -> 1 requested (ids src * 2 + dst)
        cache.get([2], d0, s0)
    else:
        cache.get([1], s0, d0)
    got = cache.get([1], s1, d1)
    assert TIERS[cache.served_by[0]] == "search"
    assert sorted(got.bounce_code) == sorted(new.bounce_code)
    np.testing.assert_allclose(np.sort(got.delay), np.sort(new.delay), rtol=0, atol=1e-9)


# a moored anchor's link on the shelf-break sample whose receiver moves 0.8 m: a direct eigenray
# enters its family across the edge with the surface-reflected one (3e-6 rad from it)
_EDGE_LINK = ([1500.0, 0.0, 138.0], [121.197, 125.009, 62.259], [121.887, 124.611, 62.327])


def test_an_eigenray_entering_across_a_watched_edge_is_searched() -> None:
    """Following cannot see an eigenray that enters its family across the family's edge, and no
    fold is involved; the search watched that edge (the family's miss there 0.016 m off zero),
    its check fails at the moved ends where the folds' alone pass, so the link is searched and
    its arrival set is the new search's, the new direct eigenray included."""
    from aquasim_py.channel import rangedep
    from aquasim_py.channel._rangedep_search_jit import F_CODE, F_THETA0, W_CODE, W_EDGE
    from aquasim_py.channel.arrival_cache import TIERS
    from aquasim_py.channel.data import shelfbreak

    env = shelfbreak()
    s, d0, d1 = (np.array(p)[None] for p in _EDGE_LINK)
    old = arrivals(env, s, d0, max_bounces=2)
    new = arrivals(env, s, d1, max_bounces=2)
    assert (new.bounce_code == 0).sum() == (old.bounce_code == 0).sum() + 1
    assert sorted(new.bounce_code[new.bounce_code != 0]) == sorted(old.bounce_code[old.bounce_code != 0])
    rows, cnt, watch, nwatch = rangedep.solve(env, rangedep.sections(env, s, d0), 2)
    w = watch[0, : nwatch[0]]
    assert ((w[:, W_EDGE] != 0) & (w[:, W_CODE] == 0)).any()
    th, code = rows[:, : cnt[0], F_THETA0], rows[:, : cnt[0], F_CODE].astype(np.int64)
    followed, ok, _sec = rangedep.follow(env, s, d1, 2, th, code)
    assert ok.all()  # following alone carries the old set
    folds = w[w[:, W_EDGE] == 0][None]
    args = (followed[..., F_THETA0], code, 2.0)
    assert rangedep.watch(env, s, d1, 2, folds, np.array([folds.shape[1]]), *args)[0]
    assert not rangedep.watch(env, s, d1, 2, watch, nwatch, *args)[0]
    cache = ArrivalCache(env, 4, max_bounces=2, tol_s=0.0)
    cache.get([0], s, d0)
    got = cache.get([0], s, d1)
    assert TIERS[cache.served_by[0]] == "search"
    assert sorted(got.bounce_code) == sorted(new.bounce_code)
    np.testing.assert_allclose(np.sort(got.delay), np.sort(new.delay), rtol=0, atol=1e-9)


# a shelf-break link whose ends move 1.6 m: a fold of its bottom-bottom family brings two
# eigenrays at 11.37 and 11.57 deg, and following the old one at 12.77 deg (a steep ray, dz /
# d theta 8e6 m/rad) lands on the one at 11.57
_TURN_LINK = (
    ([-738.043, 1166.679, 77.826], [-422.542, -171.32, 45.393]),
    ([-738.025, 1165.042, 77.826], [-422.032, -169.748, 45.393]),
)


def test_a_followed_eigenray_that_turns_onto_a_new_root_is_searched() -> None:
    """A followed eigenray whose launch angle moved farther than its ray-tube width allows for the
    move (rangedep.turned_within) is not followed: the link is searched, and its arrival set is the
    new search's; followed without that bound, the link would lack two of the family's four."""
    from aquasim_py.channel import rangedep
    from aquasim_py.channel.arrival_cache import TIERS
    from aquasim_py.channel.arrivals import follow
    from aquasim_py.channel.data import shelfbreak

    env = shelfbreak()
    (s0, d0), (s1, d1) = (np.array(p)[None] for p in _TURN_LINK[0]), (np.array(p)[None] for p in _TURN_LINK[1])
    old = arrivals(env, s0, d0, max_bounces=2)
    new = arrivals(env, s1, d1, max_bounces=2)
    assert (new.bounce_code == 8).sum() == (old.bounce_code == 8).sum() + 2 == 4
    moved = max(np.linalg.norm(s1 - s0), np.linalg.norm(d1 - d0))
    got, ok = follow(env, old, s1, d1, max_bounces=2)
    assert ok.all() and (got.bounce_code == 8).sum() == 2  # the unbounded follow keeps two
    _got, ok = follow(env, old, s1, d1, max_bounces=2, reach=rangedep.watch_reach([moved]))
    assert not ok.any()
    cache = ArrivalCache(env, 4, max_bounces=2, tol_s=0.0, follow_m=3.0)
    cache.get([0], s0, d0)
    served = cache.get([0], s1, d1)
    assert TIERS[cache.served_by[0]] == "search"
    assert sorted(served.bounce_code) == sorted(new.bounce_code)


def test_watched_intervals_hold_at_the_ends_they_were_searched_at() -> None:
    """Checked at the very ends of their search, the watched intervals of every link are clear
    (the check repeats the search's own test there), but for links with more than the rows hold;
    and links whose search watched nothing are clear wherever they are."""
    from aquasim_py.channel import rangedep
    from aquasim_py.channel._rangedep_search_jit import WATCH_ROWS

    env = _front_env()
    rng = np.random.default_rng(5)
    s, d = _links(rng, 60)
    _rows, _cnt, watch, nwatch = rangedep.solve(env, rangedep.sections(env, s, d), 2)
    assert (nwatch > 0).sum() >= 5  # else the check would be empty
    clear = rangedep.watch(env, s, d, 2, watch, nwatch)
    np.testing.assert_array_equal(clear, nwatch <= WATCH_ROWS)
    none = nwatch == 0
    assert rangedep.watch(env, s[none] + 7.0, d[none] - 3.0, 2, watch[none], nwatch[none]).all()


def test_intervals_beyond_the_reach_are_not_walked() -> None:
    """Only the intervals whose margin is below the reach are checked: at ends moved 3 m down,
    where some links' intervals fail, a reach below each link's every margin passes them all, and
    the links whose failing intervals are all beyond the reach pass."""
    from aquasim_py.channel import rangedep
    from aquasim_py.channel._rangedep_search_jit import W_MARGIN, WATCH_ROWS

    env = _front_env()
    rng = np.random.default_rng(5)
    s, d = _links(rng, 60)
    _rows, _cnt, watch, nwatch = rangedep.solve(env, rangedep.sections(env, s, d), 2, 20.0)
    fits = (nwatch > 0) & (nwatch <= WATCH_ROWS)
    s, d, watch, nwatch = s[fits], d[fits], watch[fits], nwatch[fits]
    moved = s + [0.0, 0.0, 3.0]
    every = rangedep.watch(env, moved, d, 2, watch, nwatch)
    assert (~every).sum() >= 3  # else nothing would tell the reach apart
    lowest = np.nanmin(watch[..., W_MARGIN], axis=1)
    assert rangedep.watch(env, moved, d, 2, watch, nwatch, reach=np.minimum(lowest, 0.0) - 1.0).all()
    # each failing link checked one interval at a time: it fails only with a reach above the
    # margin of an interval that fails on its own
    for i in np.flatnonzero(~every)[:5]:
        ends = (moved[i : i + 1], d[i : i + 1])
        fails = []
        for k in range(nwatch[i]):
            one = watch[i : i + 1].copy()
            one[0, [0, k]] = one[0, [k, 0]]
            fails.append(not rangedep.watch(env, *ends, 2, one, np.array([1]))[0])
        worst = min(m for m, f in zip(watch[i, : nwatch[i], W_MARGIN], fails) if f)
        assert rangedep.watch(env, *ends, 2, watch[i : i + 1], nwatch[i : i + 1], reach=worst)[0]
        assert not rangedep.watch(
            env, *ends, 2, watch[i : i + 1], nwatch[i : i + 1], reach=np.nextafter(worst, np.inf)
        )[0]


def test_a_search_watches_the_intervals_below_its_watch_m() -> None:
    """A search keeps the watched intervals whose margin is below ``watch_m``: at 2 m exactly
    those of a search at 20 m with a margin below 2 m, in the same order, and more at 20 m."""
    from aquasim_py.channel import rangedep
    from aquasim_py.channel._rangedep_search_jit import W_MARGIN, WATCH_ROWS

    env = _front_env()
    s, d = _links(np.random.default_rng(5), 60)
    sec = rangedep.sections(env, s, d)
    _r, _c, near, n_near = rangedep.solve(env, sec, 2, 2.0)
    _r, _c, wide, n_wide = rangedep.solve(env, sec, 2, 20.0)
    fits = n_wide <= WATCH_ROWS
    assert n_wide[fits].sum() > n_near[fits].sum() > 0
    for i in np.flatnonzero(fits):
        rows = wide[i, : n_wide[i]]
        assert (rows[:, W_MARGIN] < 20.0).all()
        np.testing.assert_array_equal(near[i, : n_near[i]], rows[rows[:, W_MARGIN] < 2.0])


def test_watch_reach_is_two_metres_per_metre_of_move_at_least_one() -> None:
    """The rule the search and the check share: 2 m of miss per metre the farther end moved,
    the move taken as at least 1 m (docs/channel.md)."""
    from aquasim_py.channel import rangedep

    np.testing.assert_array_equal(rangedep.watch_reach([0.0, 0.3, 1.0, 3.0, 10.0]), [2.0, 2.0, 2.0, 6.0, 20.0])
