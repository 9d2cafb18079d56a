"""What a windowed re-search would cost: the walks a search of a link's moved ends would still make
if it re-walked only the launch angles where the last search's samples, moved to first order, say
that something can have changed, against the walks of a whole new search.

On the shelf-break network of tools/bench_arrivals.py (links up to ``--max-range``, 2 bounces),
``--links`` random links are each searched at their ends (E0) and again with both ends moved by
``r`` in random horizontal directions (E1), the searches' walks logged (the compiled walks run as
Python for that: about 1 s a link). Each sample of the E0 search (every angle its fan and its
refinement walked, not Newton's steps) is walked again with both ends moved 5 cm the same ways;
its change, scaled to ``r``, stands in for the first-order sensitivities a re-search would take
from the walk itself. An interval between two neighbouring E0 samples is a window, to be searched
again as a search does, where:

* mark: an end's bounce sequence changes under the 5 cm move, or its depth miss lies within k
  times its change of zero (of the families within the bounce limit);
* fold: one family with end slopes of opposite signs whose margin (the search's bound on the miss
  at the extremum) lies within k times the larger end's change of zero;
* event: wider than the search's edge resolution, with an end's predicted bounce change (the
  walk's event offset, moved by k times its change) inside it;
* edge: around each family edge (bisected to 1e-10 rad at E0 and after the 5 cm move), k times
  its shift and the edge resolution either side.

The re-search's walks: the E1 search's walks inside the windows (its fan samples, refinement,
Newton steps and extrema there), two for each window's ends, and three for each E1 eigenray outside
them (Newton from the E0 eigenray it continues; following takes about two). Printed per move:
that count against the E1 search's walks, as the ratio of the sums and its median and 90th
percentile over the links; the same without the event windows, and with the edge windows alone
(the floor of the scheme: families re-located, eigenrays followed); and the completeness checks:
E1 eigenrays outside the windows without an E0 eigenray of the same bounce sequence within 0.02
rad (born where no window looked), and E0 eigenrays outside them without such an E1 eigenray.

    python tools/windowed_research.py --links 40 --moves 1,2
"""

from __future__ import annotations

import os

os.environ["NUMBA_DISABLE_JIT"] = "1"  # the walks as Python, so that the search's calls can be logged

import argparse
import math
import sys
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

_STEP_M = 0.05  # the small move whose change is scaled (first order)
_NEWTON_WALKS = 3  # walks to carry an eigenray outside the windows from E0 to E1
_SAME_RAD = 0.02  # an eigenray continues one of the same bounce sequence within this
_VARIANTS = {"all windows": (), "without event windows": ("event",), "edge windows alone": ("mark", "fold", "event")}


def main() -> None:
    from bench_arrivals import network  # tools/, beside this script
    from fan_changes import family_edge

    from aquasim_py.channel import _rangedep_jit as kjit
    from aquasim_py.channel import _rangedep_search_jit as sjit
    from aquasim_py.channel import rangedep
    from aquasim_py.channel.data import shelfbreak

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--links", type=int, default=40)
    ap.add_argument("--moves", default="1,2", help="moves of both ends (m), comma-separated")
    ap.add_argument("--factor", type=float, default=1.5, help="k: the first-order changes' safety factor")
    ap.add_argument("--max-range", type=float, default=2000.0, help="the longest link (m), the network scenario's")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    env = shelfbreak()
    mb, k = 2, args.factor
    bpar = np.array(env.bottom.params, dtype=float)
    edge_rad = sjit._EDGE_RAD

    # the search's walks, logged through the functions it calls (module globals, looked up per call)
    walks: list[tuple[float, np.ndarray | None]] = []
    sample0, miss0, fill0 = sjit._sample, sjit._miss, sjit._fill

    def logged_sample(*a: Any) -> None:
        sample0(*a)
        walks.append((float(a[9]), a[-1].copy()))

    def logged_miss(*a: Any) -> Any:
        walks.append((float(a[9]), None))
        return miss0(*a)

    def logged_fill(*a: Any) -> Any:
        walks.append((float(a[11]), None))
        return fill0(*a)

    sjit._sample = logged_sample  # type: ignore[assignment]
    sjit._miss = logged_miss  # type: ignore[assignment]
    sjit._fill = logged_fill  # type: ignore[assignment]

    def search(s: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[tuple[float, int]]]:
        """(the search's samples (n, NS) by angle, the angles of all its walks, its eigenrays
        (launch angle, bounce sequence))."""
        walks.clear()
        rows, cnt, _, _ = rangedep.solve(env, rangedep.sections(env, s[None], d[None]), mb)
        smp = {th: row for th, row in walks if row is not None}
        samples = np.array([smp[th] for th in sorted(smp)]).reshape(-1, sjit.NS)
        eig = [(float(rows[0, i, sjit.F_THETA0]), int(rows[0, i, sjit.F_CODE])) for i in range(int(cnt[0]))]
        return samples, np.array([th for th, _ in walks]), eig

    def sampler(s: np.ndarray, d: np.ndarray) -> Callable[[float], np.ndarray]:
        """The sample (S_* fields) of a launch angle on the link s -> d."""
        sec = rangedep.sections(env, s[None], d[None])
        a, b = int(sec.offs[0]), int(sec.offs[1])
        rr, cc, bb, ff = sec.r[a:b], np.ascontiguousarray(sec.c[a:b]), sec.floor_z[a:b], sec.floor_shape[a:b]
        dummy, ev = np.empty((1, 3)), np.empty(2)

        def walk(th: float) -> np.ndarray:
            out = np.empty(sjit.NS)
            sample0(rr, sec.z, cc, bb, ff, sec.floor, sec.zs[0], sec.zr[0], sec.R[0], th, mb, bpar, dummy, ev, out)
            return out

        return walk

    def edge(walk: Callable[[float], np.ndarray], lo: float, hi: float, code_lo: int) -> float:
        """The edge of the sequence ``code_lo`` (at ``lo``) towards ``hi``, to 1e-10 rad."""
        return family_edge(lambda th: int(walk(th)[sjit.S_CODE]), lo, hi, code_lo)

    def edge_near(walk: Callable[[float], np.ndarray], e0: float, code_lo: int) -> float:
        """The edge of ``code_lo`` (below it) nearest ``e0``: a bracket doubled from 1e-6 rad."""
        step = 1e-6
        for _ in range(40):
            lo, hi = e0 - step, e0 + step
            if int(walk(lo)[sjit.S_CODE]) == code_lo and int(walk(hi)[sjit.S_CODE]) != code_lo:
                return edge(walk, lo, hi, code_lo)
            step *= 2.0
        return math.nan

    def windows(
        S: np.ndarray,
        Ss: np.ndarray,
        scale: float,
        walk0: Callable[[float], np.ndarray],
        walk_s: Callable[[float], np.ndarray],
    ) -> list[tuple[float, float, str]]:
        """The windows (angle from, to, why) of the E0 samples S, Ss after the small move."""
        th, f, q = S[:, sjit.S_TH], S[:, sjit.S_F], S[:, sjit.S_Q]
        c, cs = S[:, sjit.S_CODE].astype(np.int64), Ss[:, sjit.S_CODE].astype(np.int64)
        df = np.abs(Ss[:, sjit.S_F] - f) * scale
        mark = (cs != c) | ((c >= 0) & (np.abs(f) <= k * df))
        out: list[tuple[float, float, str]] = []
        for m in range(th.size - 1):
            a, b = float(th[m]), float(th[m + 1])
            w = b - a
            if mark[m] or mark[m + 1]:
                out.append((a, b, "mark"))
            elif c[m] == c[m + 1] >= 0 and (q[m] > 0.0) != (q[m + 1] > 0.0) and (f[m] > 0.0) == (f[m + 1] > 0.0):
                margin = min(abs(f[m]), abs(f[m + 1])) - 2.0 * max(abs(q[m]), abs(q[m + 1])) * w
                if margin < k * max(df[m], df[m + 1]):
                    out.append((a, b, "fold"))
            if w > edge_rad and not (c[m] < -1 and S[m, sjit.S_NB] >= mb + kjit.OVER_BOUNCES):
                evp, evm = S[m, sjit.S_EVP], S[m + 1, sjit.S_EVM]
                evp -= k * abs(Ss[m, sjit.S_EVP] - evp) * scale if math.isfinite(evp) else 0.0
                evm -= k * abs(Ss[m + 1, sjit.S_EVM] - evm) * scale if math.isfinite(evm) else 0.0
                if evp < w or evm < w:
                    out.append((a, b, "event"))
            if c[m] != c[m + 1] and w <= edge_rad:
                e0 = edge(walk0, a, b, int(c[m]))
                es = edge_near(walk_s, e0, int(c[m]))
                pad = k * abs(es - e0) * scale + edge_rad if math.isfinite(es) else math.inf
                out.append((e0 - pad, e0 + pad, "edge"))
        return out

    def merged(win: list[tuple[float, float, str]], drop: tuple[str, ...]) -> np.ndarray:
        spans: list[list[float]] = []
        for a, b, _ in sorted(x for x in win if x[2] not in drop):
            if spans and a <= spans[-1][1]:
                spans[-1][1] = max(spans[-1][1], b)
            else:
                spans.append([a, b])
        return np.array(spans).reshape(-1, 2)

    def inside(spans: np.ndarray, th: np.ndarray) -> np.ndarray:
        return np.asarray(((spans[None, :, 0] <= th[:, None]) & (th[:, None] <= spans[None, :, 1])).any(axis=1))

    rng = np.random.default_rng(args.seed)
    pos = network(env, 100, rng)
    for r in (float(v) for v in args.moves.split(",")):
        cost: dict[str, list[float]] = {v: [] for v in _VARIANTS}
        full: list[float] = []
        n_links, reasons, born, vanished, eigen_out, eigen = 0, Counter[str](), 0, 0, 0, 0
        while n_links < args.links:
            i, j = rng.choice(pos.shape[0], size=2, replace=False)
            s, d = pos[i], pos[j]
            if np.hypot(*(d - s)[:2]) > args.max_range:
                continue
            ang = rng.uniform(0.0, 2.0 * np.pi, 2)
            us = np.array([np.cos(ang[0]), np.sin(ang[0]), 0.0])
            ud = np.array([np.cos(ang[1]), np.sin(ang[1]), 0.0])
            S, _, eig0 = search(s, d)
            if S.shape[0] < 2:
                continue
            walk_s = sampler(s + _STEP_M * us, d + _STEP_M * ud)
            Ss = np.array([walk_s(th) for th in S[:, sjit.S_TH].tolist()])
            win = windows(S, Ss, r / _STEP_M, sampler(s, d), walk_s)
            _, w1, eig1 = search(s + r * us, d + r * ud)
            n_links += 1
            reasons.update(why for _, _, why in win)
            full.append(w1.size)
            th1 = np.array([t for t, _ in eig1])
            for name, drop in _VARIANTS.items():
                spans = merged(win, drop)
                out1 = ~inside(spans, th1)
                cost[name].append(inside(spans, w1).sum() + 2 * spans.shape[0] + _NEWTON_WALKS * out1.sum())
            spans = merged(win, ())
            out1 = ~inside(spans, th1)
            eigen += th1.size
            eigen_out += int(out1.sum())
            for (t1, c1), o in zip(eig1, out1, strict=True):
                born += bool(o) and not any(c == c1 and abs(t - t1) < _SAME_RAD for t, c in eig0)
            out0 = ~inside(spans, np.array([t for t, _ in eig0]))
            for (t0, c0), o in zip(eig0, out0, strict=True):
                vanished += bool(o) and not any(c == c0 and abs(t - t0) < _SAME_RAD for t, c in eig1)

        print(f"move {r:g} m, {n_links} links up to {args.max_range:g} m, k = {k:g}")
        print(f"  a new search: {np.mean(full):.0f} walks a link; windows: {dict(reasons)}")
        for name in _VARIANTS:
            ratio = np.array(cost[name]) / np.array(full)
            p50, p90 = np.percentile(ratio, [50, 90])
            print(
                f"  {name:<24} {sum(cost[name]) / sum(full):.3f} of its walks (median {p50:.3f}, 90th percentile"
                f" {p90:.3f})"
            )
        print(
            f"  eigenrays at E1 {eigen}, outside the windows {eigen_out}: born there {born}; E0 eigenrays outside"
            f" them that vanished {vanished}"
        )


if __name__ == "__main__":
    main()
