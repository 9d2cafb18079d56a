"""How often a run's followed links lack an eigenray: every request the channel's arrival cache
serves by following (from the link's own last solution or its reverse's) is checked against a
new search at the same ends, bounce sequence by bounce sequence.

Runs a scenario (default ``scenarios/shelfbreak_network.toml``, its first ``--duration`` s) with
the cache instrumented. Per followed request: whether following lacks an eigenray the new search
has (a path that appeared since the link's last search, or one that search missed) or carries
one the search lacks (the search is not exhaustive either, docs/channel.md). Then the distinct
eigenrays following lacked (a link, a bounce sequence and a launch angle to 0.1 degree), their
strongest level and the links they are on. ``--follow-m`` sets ``[channel] follow_radius_m``
for the run, ``--watch-rate`` the fold check's metres of miss per metre of move
(``WATCH_M_PER_M``, which :func:`aquasim_py.channel.rangedep.watch_reach` reads; an experiment).

    python tools/followed_sets.py --duration 20                    # docs/channel.md
    python tools/followed_sets.py --duration 20 --follow-m 3
"""

from __future__ import annotations

import sys
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


def main() -> None:
    from cache_requests import instrumented_run, run_parser  # tools/, beside this script

    from aquasim_py.channel import _rangedep_search_jit, arrival_cache
    from aquasim_py.channel.arrivals import arrivals

    ap = run_parser(__doc__ or "", 20.0)
    ap.add_argument("--watch-rate", type=float, default=None, help="the fold check's m of miss per m of move")
    args = ap.parse_args()
    if args.watch_rate is not None:  # read by rangedep.watch_reach at each search and check
        _rangedep_search_jit.WATCH_M_PER_M = args.watch_rate
    counts: Counter[str] = Counter()
    lacked: dict[tuple[int, int, float], float] = {}  # (link, bounce code, launch deg) -> level dB
    followed_tiers = np.array([arrival_cache.TIERS.index("follow"), arrival_cache.TIERS.index("reverse")])

    def checked(self: arrival_cache.ArrivalCache, get: Callable[..., Any], links, src, dst):
        out = get(self, links, src, dst)
        fol = np.flatnonzero(np.isin(self.served_by, followed_tiers))
        if not fol.size:
            return out
        s = np.asarray(src, float).reshape(-1, 3)[fol]
        d = np.asarray(dst, float).reshape(-1, 3)[fol]
        new = arrivals(self.env, s, d, max_bounces=self.max_bounces, frequency_khz=self.frequency_khz)
        ids = np.asarray(links, np.int64).ravel()[fol]
        for j, i in enumerate(fol.tolist()):
            a = slice(out.offsets[i], out.offsets[i + 1])
            e = slice(new.offsets[j], new.offsets[j + 1])
            counts["followed"] += 1
            mine, theirs = Counter(out.bounce_code[a].tolist()), Counter(new.bounce_code[e].tolist())
            counts["carries one more"] += bool(mine - theirs)
            if not theirs - mine:
                continue
            counts["lacks one"] += 1
            for code in theirs - mine:  # the new search's eigenrays of that sequence following lacks
                known = out.launch_angle[a][out.bounce_code[a] == code]
                for q in np.flatnonzero(new.bounce_code[e] == code) + e.start:
                    if not (np.abs(known - new.launch_angle[q]) < 1e-4).any():
                        key = (int(ids[j]), int(code), round(float(np.degrees(new.launch_angle[q])), 1))
                        lacked[key] = max(lacked.get(key, -np.inf), float(new.level_db[q]))
        return out

    instrumented_run(args, checked)
    print(f"{Path(args.scenario).name}, first {args.duration:g} s")
    for k in ("followed", "lacks one", "carries one more"):
        print(f"  {'requests ' + k:36s} {counts[k]}")
    levels = np.array(list(lacked.values()))
    print(f"  {'distinct eigenrays lacked':36s} {len(lacked)} on {len({k[0] for k in lacked})} links")
    if levels.size:
        print(f"  {'  strongest (dB re 1 m)':36s} {levels.max():.1f}")
        print(f"  {'  above -80 dB':36s} {(levels > -80).sum()}")


if __name__ == "__main__":
    main()
