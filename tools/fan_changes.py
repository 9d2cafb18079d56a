"""How much of a link's launch-angle fan changes when both its ends move: the room a re-search
that re-walks only the launch angles where something can have changed would have, and what a
bound per launch angle would have to catch.

On the shelf-break network of tools/bench_arrivals.py (nodes in 3 km x 3 km across the front and
the slope, 2 bounces), ``--links`` random links each walk a fan of ``--angles`` launch angles
(-0.6 to 0.6 rad) at their ends, at both ends moved by ``r`` in random horizontal directions, and
at both moved by 5 cm in the same directions. Of the angles whose ray reaches the receiver within
the bounce limit at either end set, per move (median and 90th percentile over the links):

* changed: the share whose bounce sequence or depth-miss sign differs between the two end sets
  (every eigenray that appears, vanishes or moves lies in it: what an exact bound would mark), and
  of it the share whose bounce sequence changed;
* uniform: the share a reach uniform over the fan marks, the channel's fold check's
  (:func:`aquasim_py.channel.rangedep.watch_reach` of the move: |miss| below it), and how many
  changed angles lie outside it (of them with a changed sequence);
* first order: the share marked by the 5 cm move's change scaled to ``r``, times ``k``: |miss| below
  k times the miss's change, or within k times its shift (and one fan step) of an edge between
  two sequences (each edge bisected to 1e-10 rad at the ends and after the 5 cm move; the whole fan
  where that move changed the sequence at either fan angle beside it); and how many changed
  angles lie outside it (of them with a changed sequence): where a bound from the first-order
  sensitivities of the walk would not look.

    python tools/fan_changes.py --links 40 --moves 1,2
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

_STEP_M = 0.05  # the small move whose change is scaled (first order)
_FACTORS = (1.5, 2.0, 4.0)


def family_edge(code_at: Callable[[float], int], lo: float, hi: float, code_lo: int) -> float:
    """The edge of the bounce sequence ``code_lo`` (``code_at(lo)``, the sequence of the ray
    launched at an angle) towards ``hi``, bisected to 1e-10 rad (also tools/windowed_research.py's)."""
    while abs(hi - lo) > 1e-10:
        mid = 0.5 * (lo + hi)
        if code_at(mid) == code_lo:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def main() -> None:
    from bench_arrivals import network  # tools/, beside this script

    from aquasim_py.channel import _rangedep_jit as jit
    from aquasim_py.channel import rangedep
    from aquasim_py.channel.data import shelfbreak

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--links", type=int, default=40)
    ap.add_argument("--angles", type=int, default=3000)
    ap.add_argument("--moves", default="1,2", help="moves of both ends (m), comma-separated")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    env = shelfbreak()
    mb = 2
    bpar = np.array(env.bottom.params, dtype=float)
    theta = np.linspace(-0.6, 0.6, args.angles)
    path, noev = np.empty((1, 3)), np.empty(0)

    def walker(s: np.ndarray, d: np.ndarray) -> Callable[[float], tuple[float, int]]:
        """The walk of the link s -> d: launch angle (rad) -> (depth miss (m, NaN: not reached
        within the bounce limit), bounce sequence (-1: none))."""
        sec = rangedep.sections(env, s[None], d[None])
        a, b = int(sec.offs[0]), int(sec.offs[1])
        rr, cc, bb, ff = sec.r[a:b], np.ascontiguousarray(sec.c[a:b]), sec.floor_z[a:b], sec.floor_shape[a:b]

        def walk(th: float) -> tuple[float, int]:
            res = jit.trace(rr, sec.z, cc, bb, ff, sec.floor, sec.zs[0], th, sec.R[0], mb, bpar, False, path, noev)
            return (res[1] - sec.zr[0], int(res[7])) if res[0] == jit.S_REACHED else (math.nan, -1)

        return walk

    def codes(walk: Callable[[float], tuple[float, int]]) -> Callable[[float], int]:
        """The bounce sequence alone of ``walk``."""
        return lambda th: walk(th)[1]

    def fan(walk: Callable[[float], tuple[float, int]]) -> tuple[np.ndarray, np.ndarray]:
        """(depth miss, bounce sequence) at every angle of the fan."""
        out = [walk(th) for th in theta.tolist()]
        return np.array([m for m, _ in out]), np.array([c for _, c in out], np.int64)

    rng = np.random.default_rng(args.seed)
    pos = network(env, 100, rng)
    moves = [float(v) for v in args.moves.split(",")]
    for r in moves:
        changed: list[float] = []
        new_code: list[float] = []
        uniform: list[float] = []
        share: dict[float, list[float]] = {k: [] for k in _FACTORS}
        outside = {k: [0, 0] for k in _FACTORS}
        total, uniform_out = 0, [0, 0]
        for _ in range(args.links):
            i, j = rng.choice(pos.shape[0], size=2, replace=False)
            s, d = pos[i], pos[j]
            ang = rng.uniform(0.0, 2.0 * np.pi, 2)
            us = np.array([np.cos(ang[0]), np.sin(ang[0]), 0.0])
            ud = np.array([np.cos(ang[1]), np.sin(ang[1]), 0.0])
            w0, ws = walker(s, d), walker(s + _STEP_M * us, d + _STEP_M * ud)
            f0, c0 = fan(w0)
            f1, c1 = fan(walker(s + r * us, d + r * ud))
            fs, cs = fan(ws)
            live = (c0 >= 0) | (c1 >= 0)
            if not live.any():
                continue
            n = live.sum()
            diff = live & ((c0 != c1) | (np.sign(f0) != np.sign(f1)))
            changed.append(diff.sum() / n)
            new_code.append((live & (c0 != c1)).sum() / n)
            by_reach = live & ~(np.abs(f0) > float(rangedep.watch_reach(r)))
            uniform.append(by_reach.sum() / n)
            uniform_out[0] += int((diff & ~by_reach).sum())
            uniform_out[1] += int((diff & ~by_reach & (c0 != c1)).sum())
            total += int(diff.sum())
            lin = np.abs(fs - f0) * (r / _STEP_M)
            # each edge between two fan angles: located at the ends and after the small move, its
            # shift scaled to r (unknown, the whole fan, where the small move changed either side)
            edges = []
            for m in np.flatnonzero((c0[:-1] != c0[1:]) & (live[:-1] | live[1:])).tolist():
                a, b = float(theta[m]), float(theta[m + 1])
                if cs[m] != c0[m] or cs[m + 1] != c0[m + 1]:
                    edges.append((a, math.inf))
                    continue
                e0 = family_edge(codes(w0), a, b, int(c0[m]))
                es = family_edge(codes(ws), a, b, int(c0[m]))
                edges.append((e0, abs(es - e0) * (r / _STEP_M)))
            for k in _FACTORS:
                near = np.zeros(theta.size, bool)
                for e0, shift in edges:  # within k times the edge's shift, and one fan step
                    near |= np.abs(theta - e0) <= k * shift + (theta[1] - theta[0])
                marked = live & (near | ~(np.abs(f0) > k * lin))
                share[k].append(marked.sum() / n)
                outside[k][0] += int((diff & ~marked).sum())
                outside[k][1] += int((diff & ~marked & (c0 != c1)).sum())

        def q(a: list[float]) -> str:
            p50, p90 = np.percentile(a, [50, 90]) * 100.0
            return f"{p50:.2f} / {p90:.2f} %"

        print(f"move {r:g} m, {len(changed)} links, {args.angles} angles (shares: median / 90th percentile)")
        print(f"  changed                 {q(changed)} (bounce sequence changed {q(new_code)}); {total} angles")
        print(
            f"  uniform reach {float(rangedep.watch_reach(r)):g} m     {q(uniform)}; changed angles outside it {uniform_out[0]}"
            f" ({uniform_out[1]} with a changed sequence)"
        )
        for k in _FACTORS:
            print(
                f"  first order x{k:<4g}       {q(share[k])}; changed angles outside it {outside[k][0]}"
                f" ({outside[k][1]} with a changed sequence)"
            )


if __name__ == "__main__":
    main()
