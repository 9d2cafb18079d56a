"""Why a range-dependent run's links are searched: the channel's arrival-cache requests over a
run, by what served them (``ArrivalCache.served_by``), and how far each link's ends had moved
from where it was last searched.

Runs a scenario (default ``scenarios/shelfbreak_network.toml``, its first ``--duration`` s) with
the channel's cache instrumented: each request of a link is classed by the distance of its
farther end from the link's last search (no search yet: "first"; within the cache's
``follow_m``: "near"; beyond: "far", with how many of those lie within 2, 5 and 10 m) and by the
tier that served it (same, follow, reverse, search); and the CPU the run spent in the cache,
searching and following (two runs of different ``--duration`` give a later stretch's by
difference). ``--follow-m`` sets the channel's follow radius for the run (``[channel]
follow_radius_m``; default the scenario's).

    python tools/cache_requests.py                       # the figures of docs/performance.md
    python tools/cache_requests.py --duration 120 --follow-m 10
"""

from __future__ import annotations

import argparse
import functools
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def run_parser(doc: str, duration_s: float) -> argparse.ArgumentParser:
    """The command line of a run with an instrumented arrival cache (this tool's, and
    tools/followed_sets.py's): the scenario, ``--duration`` (default ``duration_s``) and
    ``--follow-m``; ``doc`` is the tool's docstring."""
    ap = argparse.ArgumentParser(description=doc.split("\n")[0])
    ap.add_argument("scenario", nargs="?", default=str(ROOT / "scenarios" / "shelfbreak_network.toml"))
    ap.add_argument("--duration", type=float, default=duration_s, help=f"simulated seconds (default {duration_s:g})")
    ap.add_argument("--follow-m", type=float, default=None, help="[channel] follow_radius_m for this run (m)")
    return ap


def instrumented_run(args: argparse.Namespace, hook: Callable[..., Any]) -> Any:
    """Run ``args.scenario`` for ``args.duration`` s (with ``args.follow_m`` as its follow radius
    if given), every ``cache.get(links, src, dst)`` made ``hook(cache, get, links, src, dst)``
    (``get``: the cache's own, for the hook to call); returns the run's result."""
    from aquasim_py import run_scenario
    from aquasim_py.channel.arrival_cache import ArrivalCache

    overrides: dict[str, float] = {"simulation.duration_s": args.duration}
    if args.follow_m is not None:
        overrides["channel.follow_radius_m"] = args.follow_m
    get = ArrivalCache.get
    ArrivalCache.get = functools.partialmethod(hook, get)  # type: ignore[assignment, method-assign]
    try:
        return run_scenario(args.scenario, overrides=overrides, progress=False)
    finally:
        ArrivalCache.get = get  # type: ignore[method-assign]


def main() -> None:
    args = run_parser(__doc__ or "", 60.0).parse_args()

    from aquasim_py.channel import arrival_cache

    counts: Counter[str] = Counter()
    # CPU (s) in every cache.get, and in its tiers: searching (_fill) and following
    # (_follow_from, its fold and edge checks included)
    spent: dict[str, float] = {"cache": 0.0, "searching": 0.0, "following": 0.0}

    def count(self: arrival_cache.ArrivalCache, get: Callable[..., Any], links, src, dst):
        ids = np.asarray(links, np.int64).ravel()
        s, d = np.asarray(src, float).reshape(-1, 3), np.asarray(dst, float).reshape(-1, 3)
        slots = np.array([self._slot.get(i, -1) for i in ids.tolist()], np.int64)
        known = slots >= 0
        moved = np.full(ids.size, np.nan)  # the farther end's distance from the last search (m)
        k = slots[known]
        moved[known] = np.maximum(
            np.linalg.norm(s[known] - self._sa[k], axis=1), np.linalg.norm(d[known] - self._da[k], axis=1)
        )
        t = time.process_time()
        out = get(self, links, src, dst)
        spent["cache"] += time.process_time() - t
        tier = np.array(arrival_cache.TIERS)[self.served_by]
        with np.errstate(invalid="ignore"):
            cls = np.where(np.isnan(moved), "first", np.where(moved <= self.follow_m, "near", "far"))
            for lim in (2.0, 5.0, 10.0):
                counts[f"far, within {lim:g} m"] += int(((cls == "far") & (moved <= lim)).sum())
        for c, t in zip(cls.tolist(), tier.tolist()):
            counts[f"{c}: {t}"] += 1
        counts["requests"] += ids.size
        return out

    def timed(name: str, f: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(f)
        def g(*a: Any, **k: Any) -> Any:
            t = time.process_time()
            try:
                return f(*a, **k)
            finally:
                spent[name] += time.process_time() - t

        return g

    patched = {"_fill": "searching", "_follow_from": "following"}
    saved = {name: getattr(arrival_cache.ArrivalCache, name) for name in patched}
    for name, label in patched.items():
        setattr(arrival_cache.ArrivalCache, name, timed(label, saved[name]))
    t0 = time.process_time()
    try:
        result = instrumented_run(args, count)
    finally:
        for name, f in saved.items():
            setattr(arrival_cache.ArrivalCache, name, f)
    cpu = time.process_time() - t0
    radius = result.scenario.channel.follow_radius_m
    print(f"{Path(args.scenario).name}, first {args.duration:g} s, follow radius {radius:g} m")
    print(f"  CPU {cpu:.1f} s (instrumented)")
    print(f"  {'CPU in the arrival cache':32s} {spent['cache']:.1f} s")
    print(f"  {'  of which searching':32s} {spent['searching']:.1f} s")
    print(f"  {'  of which following':32s} {spent['following']:.1f} s")
    print(f"  {'requests':32s} {counts['requests']}")
    for cls in ("first", "near", "far"):
        for t in arrival_cache.TIERS:
            if counts[f"{cls}: {t}"]:
                print(f"  {cls + ': ' + t:32s} {counts[f'{cls}: {t}']}")
    for lim in (2, 5, 10):
        print(f"  {f'far, within {lim} m':32s} {counts[f'far, within {lim} m']}")
    searched = sum(v for key, v in counts.items() if key.endswith(": search"))
    print(f"  {'searched':32s} {searched}")


if __name__ == "__main__":
    main()
