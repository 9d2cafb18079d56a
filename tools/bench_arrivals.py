"""Range-dependent arrivals for a 100-node network: link evaluations per second, with and without
the per-link cache, and BELLHOP (pelagic) on the same links in the same run.

The network: 100 nodes in a 3 km x 3 km square across the bundled shelf-break front and slope
(aquasim_py.channel.data.shelfbreak: TEOS-10 sound speed, gridded bathymetry, sand), 10 m above
the floor at most; every ordered pair is a link (9 900), arrivals up to ``--max-bounces``.

Timed, after a warm-up (numba compilation) on other links:

1. ``solve``: every link solved once by the exact search (aquasim_py.channel.arrivals);
2. ``cache``: the nodes drift (each in its own fixed direction at ``--speed`` m/s) and every link
   is evaluated every ``--step`` s for ``--steps`` steps through ArrivalCache (1e-7 s bound):
   the rate, the share served from the cache, the served error against the exact search on a
   sample of links (checked <= the bound); then every link once more at the same positions
   (``cache_repeat``: the served path, as for the repeated evaluations of one packet's link);
3. ``bellhop``: BELLHOP (pelagic, arrivals run, ``--beams`` beams, its default step) on
   ``--bellhop-links`` of the same links, one run per link (each link has its own section; the
   range-dependent sound speed as BELLHOP's 'Q' option), and its delay errors against ours
   on the arrivals both list.

    python tools/bench_arrivals.py                 # the table of docs/channel.md
    python tools/bench_arrivals.py --json out.json

BELLHOP's throughput is reported per link; the ratio ours / BELLHOP is the issue's figure (goal:
at least 0.5 at 1000x its timing accuracy).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "channel"))


def network(env, n: int, rng: np.random.Generator) -> np.ndarray:
    x = rng.uniform(-1500.0, 1500.0, n)
    y = rng.uniform(-1500.0, 1500.0, n)
    floor = env.depth(x, y)
    z = rng.uniform(5.0, np.maximum(floor - 10.0, 6.0))
    return np.c_[x, y, z]


def pairs(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    keep = i != j
    return i[keep], j[keep], (i * n + j)[keep]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--nodes", type=int, default=100)
    ap.add_argument("--max-bounces", type=int, default=2)
    ap.add_argument("--speed", type=float, default=0.05, help="node drift speed (m/s)")
    ap.add_argument("--step", type=float, default=1.0, help="time between evaluations of every link (s)")
    ap.add_argument("--steps", type=int, default=6)
    ap.add_argument("--beams", type=int, default=2001)
    ap.add_argument("--bellhop-links", type=int, default=40)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args()

    from aquasim_py.channel.arrival_cache import ArrivalCache
    from aquasim_py.channel.arrivals import arrivals
    from aquasim_py.channel.data import shelfbreak
    from aquasim_py.channel.rangedep import sections

    env = shelfbreak()
    rng = np.random.default_rng(args.seed)
    n = args.nodes
    pos = network(env, n, rng)
    si, di, ids = pairs(n)
    mb = args.max_bounces
    # warm-up: compile the kernels on a few other links
    warm = network(env, 4, np.random.default_rng(99))
    arrivals(env, warm[:2], warm[2:], max_bounces=mb)
    res: dict[str, object] = {"nodes": n, "links": int(ids.size), "max_bounces": mb}

    def show(*keys: str) -> None:
        for key in keys:
            v = res[key]
            print(f"{key:34s} {v:.4g}" if isinstance(v, float) else f"{key:34s} {v}", flush=True)

    t0 = time.perf_counter()
    ex = arrivals(env, pos[si], pos[di], max_bounces=mb)
    dt = time.perf_counter() - t0
    res["solve_links_per_s"] = ids.size / dt
    res["arrivals_per_link"] = float(ex.delay.size / ids.size)
    res["links_without_arrival"] = int((np.diff(ex.offsets) == 0).sum())
    show("nodes", "links", "max_bounces", "solve_links_per_s", "arrivals_per_link", "links_without_arrival")

    cache = ArrivalCache(env, n * n, max_bounces=mb)
    vel = rng.normal(size=(n, 3))
    vel[:, 2] *= 0.1
    vel *= args.speed / np.linalg.norm(vel, axis=1, keepdims=True)
    evals = 0
    t_cache = 0.0
    p = pos.copy()
    worst, worst_ratio = 0.0, 0.0
    for k in range(args.steps):
        p = pos + vel * (k * args.step)
        t0 = time.perf_counter()
        hits0 = cache.stats.hits
        bound = cache.bound(ids, p[si], p[di])
        got = cache.get(ids, p[si], p[di])
        t_cache += time.perf_counter() - t0
        evals += ids.size
        if k > 0 and cache.stats.hits > hits0:
            # check served links against the exact search (a sample of 200)
            served = np.flatnonzero(np.isfinite(bound) & (bound <= 1e-7))[:200]
            sub = got.offsets
            exact = arrivals(env, p[si[served]], p[di[served]], max_bounces=mb)
            for q, link in enumerate(served):
                a, b = sub[link], sub[link + 1]
                c0, c1 = exact.offsets[q], exact.offsets[q + 1]
                if b - a == c1 - c0 and b > a:
                    e = float(np.max(np.abs(got.delay[a:b] - exact.delay[c0:c1])))
                    worst = max(worst, e)
                    worst_ratio = max(worst_ratio, e / bound[link])
    res["cache_links_per_s"] = evals / t_cache
    # the served path alone: the same positions again (every cacheable link a hit)
    h0, m0 = cache.stats.hits, cache.stats.misses
    t0 = time.perf_counter()
    cache.get(ids, p[si], p[di])
    dt = time.perf_counter() - t0
    res["cache_repeat_links_per_s"] = ids.size / dt
    res["cache_repeat_hit_rate"] = (cache.stats.hits - h0) / max(1, cache.stats.hits - h0 + cache.stats.misses - m0)
    res["cache_hit_rate"] = cache.stats.hit_rate
    res["cache_uncacheable_misses"] = cache.stats.uncacheable
    res["cache_worst_served_error_s"] = worst
    res["cache_worst_error_over_bound"] = worst_ratio
    res["drift_mps"], res["step_s"], res["steps"] = args.speed, args.step, args.steps
    show(
        "cache_links_per_s",
        "cache_repeat_links_per_s",
        "cache_repeat_hit_rate",
        "cache_hit_rate",
        "cache_uncacheable_misses",
        "cache_worst_served_error_s",
        "cache_worst_error_over_bound",
        "drift_mps",
        "step_s",
        "steps",
    )

    try:
        import bellhop_ref  # type: ignore[import-not-found]

        ok, why = bellhop_ref.available()
    except ImportError as e:  # pragma: no cover
        ok, why = False, str(e)
    if ok:
        pick = rng.choice(ids.size, size=min(args.bellhop_links, ids.size), replace=False)
        sec = sections(env, pos[si[pick]], pos[di[pick]])
        bottom = (env.bottom.sound_speed_mps, env.bottom.density, env.bottom.attenuation_db_per_wavelength)
        errs = []
        t0 = time.perf_counter()
        outs = []
        for q in range(pick.size):
            r, c, fz = sec.link(q)
            outs.append(
                bellhop_ref.run(r, fz, sec.z, c, sec.zs[q], sec.zr[q], bottom, beams=args.beams, R=float(sec.R[q]))
            )
        tb = time.perf_counter() - t0
        ours = arrivals(env, pos[si[pick]], pos[di[pick]], max_bounces=mb)
        for q, b in enumerate(outs):
            a0, a1 = ours.offsets[q], ours.offsets[q + 1]
            for i in range(a0, a1):
                m = (b.surface == ours.surface_bounces[i]) & (b.bottom == ours.bottom_bounces[i])
                if m.any():
                    errs.append(float(np.min(np.abs(b.delay[m] - ours.delay[i]))))
        res["bellhop_links_per_s"] = pick.size / tb
        res["bellhop_beams"] = args.beams
        res["bellhop_delay_error_median_s"] = float(np.median(errs)) if errs else None
        res["bellhop_delay_error_max_s"] = float(np.max(errs)) if errs else None
        res["bellhop_share_within_1e-4_s"] = float(np.mean(np.asarray(errs) <= 1e-4)) if errs else None
        res["bellhop_compared_arrivals"] = len(errs)
        res["ratio_solve_over_bellhop"] = res["solve_links_per_s"] / res["bellhop_links_per_s"]  # type: ignore[operator]
        res["ratio_cache_over_bellhop"] = res["cache_links_per_s"] / res["bellhop_links_per_s"]  # type: ignore[operator]
    else:
        res["bellhop"] = f"skipped: {why}"

    show(*[key for key in res if key.startswith(("bellhop", "ratio"))])
    if args.json:
        args.json.write_text(json.dumps(res, indent=2) + "\n")


if __name__ == "__main__":
    main()
