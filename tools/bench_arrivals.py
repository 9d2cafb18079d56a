"""Range-dependent arrivals for a 100-node network: link evaluations per second, with and without
the per-link cache, and BELLHOP (pelagic) on the same links in the same run.

The network: 100 nodes in a 3 km x 3 km square across the bundled shelf-break front and slope
(aquasim_py.channel.data.shelfbreak: TEOS-10 sound speed, gridded bathymetry, sand), 10 m above
the floor at most; every ordered pair is a link (9 900), arrivals up to ``--max-bounces``.

Timed, after a warm-up (numba compilation) on other links:

1. ``solve``: every link solved once by the exact search (aquasim_py.channel.arrivals);
2. ``cache``, for each of ``--modes``: ``channel`` (the channel's cache: no Taylor tier, every
   delay exact, links followed within the channel's default radius, ``[channel]
   follow_radius_m`` = 1 m, of their last search or of their reverse's), ``channel_reverse``
   (the same, the links src < dst evaluated half a step before the others, which then meet
   their reverse's search half a step old), ``channel_<R>m`` (e.g. ``channel_1m``,
   ``channel_10m``: followed within R m, the search's watched intervals scaled to the radius),
   ``taylor`` (the Taylor tier, 1e-7 s bound, one-leg following within 1 m), ``taylor_back``
   (the same with ``follow_back``): filled once per Taylor bound and radius (every link
   searched, and expanded for the Taylor tier), then for each of ``--speeds`` (m/s) from a copy
   of it: the nodes drift (each in its own fixed direction) and every link is evaluated every
   ``--step`` s for ``--steps`` steps: the rate, the shares of the tiers, and on
   ``--check`` links per step (the Taylor modes: links its tier served) the served delays against
   the exact eigenrays (the Taylor tier: the same eigenrays carried to the new ends in moves of 1
   cm, and the error's ratio to the bound; the channel: a new search's, eigenray by eigenray) and
   whether the arrival set equals a new search's (in total, and by the tier that served the
   link: ``ArrivalCache.served_by``);
3. ``bellhop``: BELLHOP (pelagic, arrivals run, ``--beams`` beams, its default step) on
   ``--bellhop-links`` of the same links, one run per link (each link of the network has its own
   section: no two receivers of a source share a vertical plane; the range-dependent sound speed
   as BELLHOP's 'Q' option), and its delay errors against ours on the arrivals both list; and,
   counted fairly where the geometry allows one run for many receivers, BELLHOP with
   ``--line-receivers`` receivers on one vertical plane of a source (one run, an irregular
   receiver grid) against our search of the same links.

    python tools/bench_arrivals.py                 # the tables of docs/channel.md
    python tools/bench_arrivals.py --modes channel --speeds 0.3 --json out.json

BELLHOP's throughput is reported per link; the ratio ours / BELLHOP is the issue's figure (goal:
at least 0.5 at 1000x its timing accuracy).
"""

from __future__ import annotations

import argparse
import copy
import json
import re
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


def continued(env, ref, s0, d0, s1, d1, mb: int, step_m: float = 0.01):
    """The eigenrays of ``ref`` (solved at s0, d0 (n, 3)) carried to (s1, d1) in moves of at most
    ``step_m`` per end, each followed from the last: (arrivals, followed (n,)). One jump may land
    on another eigenray of the same bounce sequence, which is not the error the Taylor bound is
    about (measured on the shelf-break sample: a two-bounce eigenray near grazing, followed 0.1 m
    in one jump, landed on one whose reflection points lie 50 m away, the second across a floor
    kink, 2.5e-5 s earlier, and which the search does not list)."""
    from aquasim_py.channel.arrivals import follow

    move = np.maximum(np.linalg.norm(s1 - s0, axis=1), np.linalg.norm(d1 - d0, axis=1))
    n_steps = max(1, int(np.ceil(move.max(initial=0.0) / step_m)))
    cur, ok = ref, np.ones(s0.shape[0], bool)
    for k in range(1, n_steps + 1):
        f = k / n_steps
        cur, ok_k = follow(env, cur, s0 + (s1 - s0) * f, d0 + (d1 - d0) * f, max_bounces=mb)
        ok &= ok_k
    return cur, ok


def bellhop_floor(sec, q: int) -> tuple[np.ndarray, np.ndarray, bool]:
    """(ranges, depths, curved) of link q's floor for BELLHOP: a curved floor (our arcs) every 10
    m as its curvilinear bathymetry, else the section's polyline."""
    r, _c, fz = sec.link(q)
    a, b = sec.offs[q], sec.offs[q + 1]
    if not np.any(sec.floor_shape[a:b, 5:7] != 0.0):
        return r, fz, False
    rq = np.linspace(r[0], r[-1], int(np.ceil((r[-1] - r[0]) / 10.0)) + 1)
    return rq, sec.floor_at(q, rq), True


def drift(env, cache, pos, vel, si_all, di_all, ids_all, args, res, key, halves: bool = False) -> None:
    """Every link every ``args.step`` s for ``args.steps`` steps, the nodes drifting at ``vel``
    (m/s) from ``pos`` through the filled ``cache``; the results under ``key``. ``halves``: the
    links src < dst half a step before the others (each direction then meets its reverse's
    search half a step old: the reverse-following tier); the check samples the others."""
    from aquasim_py.channel.arrival_cache import TIERS
    from aquasim_py.channel.arrivals import arrivals

    mb = args.max_bounces
    evals, t_drift = 0, 0.0
    by_tier = np.zeros((len(TIERS), 2), np.int64)  # (sets that differ, compared) by serving tier
    worst, worst_ratio, checked = 0.0, 0.0, 0
    st = cache.stats
    hits0, fol0, mis0, lazy0, rev0 = st.hits, st.follows, st.misses, st.not_expanded, st.reversed
    early = si_all < di_all if halves else np.zeros(ids_all.size, bool)
    si, di, ids = si_all[~early], di_all[~early], ids_all[~early]
    for k in range(1, args.steps + 1):
        if halves:
            p = pos + vel * ((k - 0.5) * args.step)
            t0 = time.perf_counter()
            cache.get(ids_all[early], p[si_all[early]], p[di_all[early]])
            t_drift += time.perf_counter() - t0
            evals += int(early.sum())
        p = pos + vel * (k * args.step)
        bound = cache.bound(ids, p[si], p[di])
        served = np.flatnonzero(np.isfinite(bound))
        if cache.tol_s <= 0.0:  # no Taylor tier: check any links
            served = np.arange(ids.size)
        sample = served[:: max(1, served.size // max(args.check, 1))][: args.check]
        ref = cache.last(ids[sample])  # the Taylor references of a sample of the served links
        s0, d0 = cache.positions(ids[sample])
        t0 = time.perf_counter()
        got = cache.get(ids, p[si], p[di])
        t_drift += time.perf_counter() - t0
        evals += ids.size
        if not sample.size:
            continue
        tier = cache.served_by[sample]
        # served delays against the same eigenrays carried exactly to the new ends (the error
        # the bound is about), and the arrival sets against a new search
        new = arrivals(env, p[si[sample]], p[di[sample]], max_bounces=mb)
        if cache.tol_s <= 0.0:
            # every delay served is exact: against the new search's, eigenray by eigenray (the
            # nearest launch angle in its bounce sequence)
            for q, link in enumerate(sample):
                g = slice(got.offsets[link], got.offsets[link + 1])
                e = slice(new.offsets[q], new.offsets[q + 1])
                differ = sorted(got.bounce_code[g]) != sorted(new.bounce_code[e])
                by_tier[tier[q]] += (int(differ), 1)
                for i in range(g.start, g.stop):
                    same = np.flatnonzero(new.bounce_code[e] == got.bounce_code[i])
                    if same.size:
                        j = e.start + same[np.argmin(np.abs(new.launch_angle[e][same] - got.launch_angle[i]))]
                        if abs(new.launch_angle[j] - got.launch_angle[i]) < 1e-4:
                            worst = max(worst, abs(float(got.delay[i] - new.delay[j])))
                checked += 1
            continue
        fol, ok = continued(env, ref, s0, d0, p[si[sample]], p[di[sample]], mb)
        for q, link in enumerate(sample):
            g = slice(got.offsets[link], got.offsets[link + 1])
            f = slice(fol.offsets[q], fol.offsets[q + 1])
            e = slice(new.offsets[q], new.offsets[q + 1])
            differ = sorted(got.bounce_code[g]) != sorted(new.bounce_code[e])
            by_tier[tier[q]] += (int(differ), 1)
            if not ok[q] or g.stop == g.start:
                continue
            og = np.lexsort((got.launch_angle[g], got.bounce_code[g]))
            of = np.lexsort((fol.launch_angle[f], fol.bounce_code[f]))
            err = float(np.max(np.abs(got.delay[g][og] - fol.delay[f][of])))
            worst, worst_ratio, checked = max(worst, err), max(worst_ratio, err / bound[link]), checked + 1
    total = st.hits - hits0 + st.follows - fol0 + st.misses - mis0
    out = {
        "links_per_s": evals / t_drift,
        "taylor_share": (st.hits - hits0) / total,
        "follow_share": (st.follows - fol0) / total,
        "search_share": (st.misses - mis0) / total,
        "reverse_follow_share": (st.reversed - rev0) / total,
        "searches_not_expanded": st.not_expanded - lazy0,
        "checked_links": checked,
        "worst_served_error_s": worst,
        "worst_error_over_bound": worst_ratio,
        "sets_differ_from_search": f"{by_tier[:, 0].sum()} of {by_tier[:, 1].sum()}",
        # by what served the link: the Taylor tier, unmoved, followed, followed from the reverse,
        # searched (a search of the same ends again: the solver's own determinism)
        "sets_differ_by_tier": ", ".join(f"{t} {k} of {m}" for t, (k, m) in zip(TIERS, by_tier) if m),
    }
    for name, v in out.items():
        res[key + name] = v
    print(f"drift {np.linalg.norm(vel, axis=1).max():g} m/s", flush=True)
    for name, v in out.items():
        print(f"  {name:32s} {v:.4g}" if isinstance(v, float) else f"  {name:32s} {v}", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--nodes", type=int, default=100)
    ap.add_argument("--max-bounces", type=int, default=2)
    ap.add_argument(
        "--speeds",
        type=lambda v: [float(x) for x in v.split(",")],
        default=[0.005, 0.05, 0.3],
        help="node drift speeds (m/s), comma separated: one drift run each from the same filled cache",
    )
    ap.add_argument("--step", type=float, default=1.0, help="time between evaluations of every link (s)")
    ap.add_argument("--steps", type=int, default=10, help="drift steps after the fill")
    ap.add_argument("--check", type=int, default=200, help="served links checked per step (0: none, timing only)")
    ap.add_argument(
        "--modes", default="channel,channel_10m,taylor,taylor_back", help="cache configurations (comma separated)"
    )
    ap.add_argument("--beams", type=int, default=2001)
    ap.add_argument("--bellhop-links", type=int, default=40)
    ap.add_argument("--line-receivers", type=int, default=40, help="receivers on one plane for BELLHOP's batched run")
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
    w = ArrivalCache(env, 2, max_bounces=mb)
    for dz in (0.0, 0.1, 0.7):
        w.get([0, 1], warm[:2] + dz, warm[2:] - dz)
    res: dict[str, object] = {"nodes": n, "links": int(ids.size), "max_bounces": mb}

    def show(*keys: str) -> None:
        for key in keys:
            v = res[key]
            print(f"{key:34s} {v:.4g}" if isinstance(v, float) else f"{key:34s} {v}", flush=True)

    t0 = time.perf_counter()
    ex = arrivals(env, pos[si], pos[di], max_bounces=mb)
    t_solve = time.perf_counter() - t0
    res["solve_links_per_s"] = ids.size / t_solve
    res["arrivals_per_link"] = float(ex.delay.size / ids.size)
    res["links_without_arrival"] = int((np.diff(ex.offsets) == 0).sum())
    show("nodes", "links", "max_bounces", "solve_links_per_s", "arrivals_per_link", "links_without_arrival")

    heading = rng.normal(size=(n, 3))
    heading[:, 2] *= 0.1
    heading /= np.linalg.norm(heading, axis=1, keepdims=True)
    from aquasim_py.channel.config import ChannelConfig

    radius_m = ChannelConfig().follow_radius_m

    # mode -> (Taylor bound s, following radius m, follow_back)
    configs = {
        "channel": (0.0, radius_m, False),
        "channel_reverse": (0.0, radius_m, False),
        "taylor": (1e-7, 1.0, False),
        "taylor_back": (1e-7, 1.0, True),
    }
    modes = [m.strip() for m in args.modes.split(",") if m.strip()]
    for mode in modes:  # channel_<R>m: the channel's cache with another radius
        radius = re.fullmatch(r"channel_(\d+(?:\.\d+)?)m", mode)
        if radius:
            configs[mode] = (0.0, float(radius.group(1)), False)
        elif mode not in configs:
            sys.exit(f"bench_arrivals.py: --modes: unknown mode {mode!r}")
    filled: dict[tuple[float, float], ArrivalCache] = {}
    for mode in modes:
        tol, follow_m, back = configs[mode]
        if (tol, follow_m) not in filled:
            # the radius sets how far the search watches folds (rangedep.solve's watch_m)
            cache = ArrivalCache(env, n * n, max_bounces=mb, tol_s=tol, follow_m=follow_m)
            # the cold fill: every link searched (and with the Taylor tier, its expansion made)
            t0 = time.perf_counter()
            cache.get(ids, pos[si], pos[di])
            t_fill = time.perf_counter() - t0
            tag = "cache_fill" if tol > 0.0 else "channel_fill"
            res[f"{tag}_links_per_s"] = ids.size / t_fill
            if tol > 0.0:
                res["cache_fill_uncacheable_links"] = cache.stats.uncacheable
                res["cache_fill_taylor_links"] = int((cache.radius(ids) > 0).sum())
            show(*[k for k in res if k.startswith(tag)])
            filled[tol, follow_m] = cache
        res["step_s"], res["drift_steps"] = args.step, args.steps
        for speed in args.speeds:
            copied = copy.deepcopy(filled[tol, follow_m])
            copied.follow_back = back
            copied.n_nodes = n if mode.startswith("channel") else 0  # the channel numbers its links so
            tag = f"{mode}_drift_{speed:g}_"
            print(mode, end=" ")
            halves = mode == "channel_reverse"
            drift(env, copied, pos, heading * speed, si, di, ids, args, res, tag, halves)

    try:
        import bellhop_ref  # type: ignore[import-not-found]

        ok, why = bellhop_ref.available()
    except ImportError as e:  # pragma: no cover
        ok, why = False, str(e)
    if ok and args.bellhop_links > 0:
        pick = rng.choice(ids.size, size=min(args.bellhop_links, ids.size), replace=False)
        sec = sections(env, pos[si[pick]], pos[di[pick]])
        bottom = (env.bottom.sound_speed_mps, env.bottom.density, env.bottom.attenuation_db_per_wavelength)
        errs = []
        t0 = time.perf_counter()
        outs = []
        for q in range(pick.size):
            r, c, _fz = sec.link(q)
            rb, fb, curved = bellhop_floor(sec, q)
            outs.append(
                bellhop_ref.run(
                    r,
                    fb,
                    sec.z,
                    c,
                    sec.zs[q],
                    sec.zr[q],
                    bottom,
                    beams=args.beams,
                    R=float(sec.R[q]),
                    curved=curved,
                    floor_r=rb,
                )
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
        bellhop_rate = pick.size / tb
        res["ratio_solve_over_bellhop"] = ids.size / t_solve / bellhop_rate
        for speed in args.speeds:
            for mode in modes:
                rate = res[f"{mode}_drift_{speed:g}_links_per_s"]
                assert isinstance(rate, float)
                res[f"ratio_{mode}_drift_{speed:g}_over_bellhop"] = rate / bellhop_rate
        # fairly counted: one BELLHOP run for many receivers of a source on one vertical plane
        # (an irregular receiver grid), against our search of the same links
        k = args.line_receivers
        if k > 0:
            src = pos[0]
            az = rng.uniform(0.0, 2.0 * np.pi)
            # depths increasing with range (a sloping line of receivers: BELLHOP's irregular grid
            # pairs sorted depths with sorted ranges)
            rk = np.sort(rng.uniform(300.0, 2000.0, k))
            px, py = src[0] + rk * np.cos(az), src[1] + rk * np.sin(az)
            zk = np.linspace(10.0, 0.8 * float(np.min(env.depth(px, py))), k)
            dst = np.c_[px, py, zk]
            far = int(np.argmax(rk))
            sec1 = sections(env, src, dst[far])
            r, c, _fz = sec1.link(0)
            rb, fb, curved = bellhop_floor(sec1, 0)
            t0 = time.perf_counter()
            line = bellhop_ref.run(
                r, fb, sec1.z, c, src[2], zk, bottom, beams=args.beams, R=rk, curved=curved, floor_r=rb
            )
            tl = time.perf_counter() - t0
            t0 = time.perf_counter()
            ours_line = arrivals(env, np.broadcast_to(src, (k, 3)), dst, max_bounces=mb)
            to = time.perf_counter() - t0
            res["bellhop_line_links_per_s"] = k / tl
            res["solve_line_links_per_s"] = k / to
            res["ratio_solve_over_bellhop_line"] = tl / to
            res["bellhop_line_arrivals"] = int(line.delay.size)
            res["line_arrivals"] = int(ours_line.delay.size)
    else:
        res["bellhop"] = f"skipped: {why}" if not ok else "skipped: --bellhop-links 0"

    show(*[key for key in res if key.startswith(("bellhop", "ratio"))])
    if args.json:
        args.json.write_text(json.dumps(res, indent=2) + "\n")


if __name__ == "__main__":
    main()
