"""How far the arrivals of a link can be followed instead of searched: the measurement behind
``ArrivalCache.follow_m`` (aquasim_py.channel.arrival_cache) and the channel's 1 m.

On the shelf-break network of tools/bench_arrivals.py (nodes in 3 km x 3 km across the front
and the slope, every ordered pair a link, 2 bounces), each link is searched, both ends are moved
by ``r`` in random directions, and its arrivals are both followed there (arrivals.follow) and
searched there again (``--back``: a moved source's move followed backwards from the receiver
where following it forwards loses an eigenray, as ``ArrivalCache(follow_back=True)`` does). Per
radius: the share of links followed (the others fall back to a
search), and among the followed ones those whose modem stamp (the first arrival above 10 dB
SNR at a 170 dB source, 72 dB of noise in the band) differs from the new search's, split by
which is earlier: "follow later" = the search found an earlier detectable arrival that
following missed (a path appeared within r), "search later" = following kept one the search
missed (the search is not exhaustive either, docs/channel.md), and how many links' arrival
sets differ: where following lacks an eigenray the new search has (a path appeared within r,
or one the search at the old ends missed), and where the new search lacks one following has.
``--watch``: a link counts as followed only where its search's watched intervals also hold at
the moved ends with the followed eigenrays (:func:`aquasim_py.channel.rangedep.watch`, as the
cache's following tier checks them: a fold in the making, the intervals whose margin is below
``rangedep.watch_reach`` of the move, as a cache of that radius does), its cost counted with
following's.

    python tools/follow_radius.py --seeds 4 --nodes 20 [--back] [--watch]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


def main() -> None:
    from bench_arrivals import network, pairs  # tools/, beside this script

    from aquasim_py.channel import rangedep
    from aquasim_py.channel.arrivals import arrivals, first_detectable, follow, launch_table, watched_arrivals
    from aquasim_py.channel.data import shelfbreak

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--nodes", type=int, default=20)
    ap.add_argument("--radii", default="0.1,0.3,1,3,10")
    ap.add_argument("--back", action="store_true", help="follow a moved source backwards where forwards fails")
    ap.add_argument("--watch", action="store_true", help="followed only where the search's watched folds hold")
    args = ap.parse_args()
    radii = [float(v) for v in args.radii.split(",")]
    env = shelfbreak()
    # links, followed, stamp differs, follow later, search later, sets differ, following lacks, search lacks
    tot = {r: np.zeros(8) for r in radii}
    t_search = t_follow = 0.0
    n_search = n_follow = 0
    for seed in range(1, args.seeds + 1):
        rng = np.random.default_rng(seed)
        pos = network(env, args.nodes, rng)
        si, di, _ids = pairs(args.nodes)
        s, d = pos[si], pos[di]
        watched = {}  # the search's watched intervals per radius, as a cache of that radius keeps them
        for r in radii:
            wm = float(rangedep.watch_reach(r))
            if wm not in watched:
                base, w_rows, w_counts = watched_arrivals(env, s, d, max_bounces=2, watch_m=wm)
                watched[wm] = (w_rows, w_counts)
            watch, nwatch = watched[wm]
            u = rng.normal(size=s.shape)
            v = rng.normal(size=s.shape)
            s2 = s + u / np.linalg.norm(u, axis=1, keepdims=True) * r
            d2 = d + v / np.linalg.norm(v, axis=1, keepdims=True) * r
            for p in (s2, d2):  # stay in the water
                p[:, 2] = np.clip(p[:, 2], 1.0, env.depth(p[:, 0], p[:, 1]) - 1.0)
            t0 = time.perf_counter()
            fol, ok = follow(env, base, s2, d2, max_bounces=2, src_from=s if args.back else None)
            if args.watch:  # with the followed eigenrays, as the cache checks them
                ok &= rangedep.watch(env, s2, d2, 2, watch, nwatch, *launch_table(fol), reach=wm)
            t_follow += time.perf_counter() - t0
            n_follow += s.shape[0]
            t0 = time.perf_counter()
            ex = arrivals(env, s2, d2, max_bounces=2)
            t_search += time.perf_counter() - t0
            n_search += s.shape[0]
            _, fd = first_detectable(fol, 170.0, 72.0, 10.0)
            _, ed = first_detectable(ex, 170.0, 72.0, 10.0)
            f, e = np.nan_to_num(fd, nan=np.inf), np.nan_to_num(ed, nan=np.inf)
            with np.errstate(invalid="ignore"):  # inf - inf: neither has a detectable arrival
                differs = ok & ~((f == e) | (np.abs(f - e) <= 1e-9))
            # per followed link, the eigenrays of each bounce sequence: which side has fewer
            lacks = np.zeros((s.shape[0], 2), bool)  # following lacks some, the search lacks some
            for i in np.flatnonzero(ok):
                cf = Counter(fol.bounce_code[fol.offsets[i] : fol.offsets[i + 1]].tolist())
                ce = Counter(ex.bounce_code[ex.offsets[i] : ex.offsets[i + 1]].tolist())
                lacks[i] = bool(ce - cf), bool(cf - ce)
            tot[r] += [
                s.shape[0],
                ok.sum(),
                differs.sum(),
                (differs & (f > e)).sum(),
                (differs & (f < e)).sum(),
                lacks.any(axis=1).sum(),
                lacks[:, 0].sum(),
                lacks[:, 1].sum(),
            ]
    print(f"search {1e3 * t_search / n_search:.2f} ms/link, follow {1e3 * t_follow / n_follow:.2f} ms/link (all links)")
    print(
        "radius m | links | followed | stamp differs | follow later | search later | sets differ"
        " | following lacks | search lacks"
    )
    for r in radii:
        a = tot[r]
        print(
            f"{r:8g} | {a[0]:5.0f} | {a[1] / a[0]:8.3f} | {a[2]:13.0f} | {a[3]:12.0f} | {a[4]:12.0f} | {a[5]:11.0f}"
            f" | {a[6]:15.0f} | {a[7]:12.0f}"
        )


if __name__ == "__main__":
    main()
