"""Following eigenrays to moved ends in two legs (rangedep.follow_ends) and the reversed link
(rangedep.reversed_rows), against the exact search."""

from __future__ import annotations

import numpy as np

from aquasim_py.channel.arrivals import arrivals, follow
from aquasim_py.channel.data import shelfbreak
from aquasim_py.channel.rangedep import reversed_code


def _network(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """n links between random points of the shelf-break sample, 5 m below the surface to 10 m
    above the floor."""
    env = shelfbreak()
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-1500.0, 1500.0, (2 * n, 2))
    floor = env.depth(xy[:, 0], xy[:, 1])
    p = np.c_[xy, rng.uniform(5.0, np.maximum(floor - 10.0, 6.0))]
    return p[:n], p[n:]


def test_reversed_code() -> None:
    # (bottom, surface) -> (surface, bottom); one bounce and none stay; -1 stays
    assert reversed_code(np.array([2 + 3 * 1]), np.array([2]))[0] == 1 + 3 * 2
    np.testing.assert_array_equal(reversed_code(np.array([1, 2, 0, -1]), np.array([1, 1, 0, 0])), [1, 2, 0, -1])
    assert reversed_code(np.array([1 + 3 * 2 + 9 * 2]), np.array([3]))[0] == 2 + 3 * 2 + 9 * 1


def test_reversed_link_is_the_same_eigenrays() -> None:
    """Reciprocity of the model: the search from the receiver finds the same eigenrays
    travelled backwards, delays to 1e-12 s, angles swapped and negated, sequences reversed,
    and, away from caustics (|dz / dth| <= 1e5 m/rad, where the searches' own central differences
    hold), the ray-tube width of the reversed fan as the reciprocity relation gives it, to 1e-3."""
    env = shelfbreak()
    s, d = _network(12, 2)
    fwd = arrivals(env, s, d, max_bounces=2)
    back = arrivals(env, d, s, max_bounces=2)
    matched = 0
    for i in range(12):
        f = slice(fwd.offsets[i], fwd.offsets[i + 1])
        b = slice(back.offsets[i], back.offsets[i + 1])
        for k in range(f.start, f.stop):
            j = np.flatnonzero(np.abs(back.delay[b] - fwd.delay[k]) < 1e-11) + b.start
            if j.size != 1:
                continue  # a fold's pair one of the searches missed
            j = int(j[0])
            matched += 1
            assert abs(back.launch_angle[j] + fwd.arrival_angle[k]) < 1e-9
            assert abs(back.arrival_angle[j] + fwd.launch_angle[k]) < 1e-9
            nb = fwd.surface_bounces[k] + fwd.bottom_bounces[k]
            assert back.bounce_code[j] == reversed_code(fwd.bounce_code[k : k + 1], np.array([nb]))[0]
            pred = (
                fwd.dz_dlaunch[k]
                * fwd.source_speed[k]
                * np.cos(fwd.arrival_angle[k])
                / (fwd.receiver_speed[k] * np.cos(fwd.launch_angle[k]))
            )
            if abs(pred) <= 1e5:  # away from caustics, where the central differences fail
                assert abs(back.dz_dlaunch[j] - pred) <= 1e-3 * abs(pred)
    assert matched >= 60


def test_two_legs_keep_what_one_leg_loses() -> None:
    """Sources moved 0.3 m down: following from the moved source keeps fewer links than
    following the move backwards from the receiver, and every link the two-leg follow keeps
    equals a new search (delays to 1e-9 s) wherever the search finds the same set."""
    env = shelfbreak()
    s, d = _network(60, 1)
    ref = arrivals(env, s, d, max_bounces=2)
    s2 = s + np.array([0.0, 0.0, 0.3])
    _one, ok1 = follow(env, ref, s2, d, max_bounces=2)
    two, ok2 = follow(env, ref, s2, d, max_bounces=2, src_from=s)
    assert ok2.sum() >= ok1.sum() + 15
    new = arrivals(env, s2, d, max_bounces=2)
    same = 0
    lv = []
    for i in np.flatnonzero(ok2):
        g = slice(two.offsets[i], two.offsets[i + 1])
        e = slice(new.offsets[i], new.offsets[i + 1])
        if sorted(two.bounce_code[g]) != sorted(new.bounce_code[e]):
            continue
        same += 1
        np.testing.assert_allclose(two.delay[g], new.delay[e], rtol=0, atol=1e-9)
        lv.append(np.abs(two.level_db[g] - new.level_db[e]))
    assert same >= 0.8 * ok2.sum()
    # levels: the ray-tube width of the second leg is the reversed walk's, converted by the
    # reciprocity of the propagator; they differ most near caustics
    lv = np.concatenate(lv)
    assert np.quantile(lv, 0.9) <= 0.01 and lv.max() <= 0.2
