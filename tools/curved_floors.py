"""The curved-floor table of docs/channel.md: aquasim_py's eigenrays over a Gaussian seamount, a
ridge and a gridded canyon against the independent tracer (tests/channel/ray_ode_curved.py) and
against BELLHOP (pelagic) with dense fans on the same sections.

    python tools/curved_floors.py --links 12 --seed 2            # the table (about an hour)
    python tools/curved_floors.py --links 2 --no-bellhop         # a quick look

Per case (tests/channel/curved_cases.py: max 3 bounces, links 2-10 km across the feature):

* against the tracer: its eigenrays (a dense fan, edges bisected, folds sought), how many of
  them we find, miss (at least 1e-3 deg from their family's edge, and nearer), and ours without
  a counterpart: confirmed when the tracer shot from our launch angle finds them (a family
  narrower than its fan), within 1e-3 deg of our own family's edge (where the sampled floor's
  eigenrays and the true one's differ), else extra; the largest delay difference over its
  tolerance (2 / c_min times the floor's largest departure per bottom bounce);
* against BELLHOP (curvilinear bathymetry through our floor every 10 m, 10 m step, fans of 2001
  beams 1 degree wide around each eigenray of ours and of the tracer's, so that every beam is
  0.0005 deg from the next): its arrivals grouped into eigenrays (same bounce counts, launch
  angles within three beams), and how many of ours it confirms within 1e-4 s (its documented
  accuracy is about that), how many of its groups we lack, and the largest difference.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "channel"))


def bellhop_groups(case, src, dst, launches_deg: list[float]):
    """BELLHOP's arrivals in windows 1 degree wide around the given launch angles, grouped into
    eigenrays: (delay, surface, bottom, launch deg) per group."""
    import bellhop_ref  # type: ignore[import-not-found]

    from aquasim_py.channel.rangedep import sections

    sec = sections(case.env, src, dst)
    r, c, _fz = sec.link(0)
    rq = np.linspace(r[0], r[-1], int(np.ceil((r[-1] - r[0]) / 10.0)) + 1)
    fz = sec.floor_at(0, rq)
    env = case.env
    bottom = (env.bottom.sound_speed_mps, env.bottom.density, env.bottom.attenuation_db_per_wavelength)
    windows: list[tuple[float, float]] = []
    for th in sorted(launches_deg):
        if windows and th - 0.5 <= windows[-1][1]:
            windows[-1] = (windows[-1][0], th + 0.5)
        else:
            windows.append((th - 0.5, th + 0.5))
    for lo, hi in windows:
        beams = int(round((hi - lo) / 0.0005)) + 1
        b = bellhop_ref.run(
            rq, fz, sec.z, c[0], src[2], dst[2], bottom, beams=beams, angles_deg=(lo, hi), step_m=10.0, R=sec.R[0],
            curved=True,
        )  # fmt: skip
        spacing = (hi - lo) / (beams - 1)
        order = np.lexsort((b.launch_deg, b.bottom, b.surface))
        groups: list[list[int]] = []
        for i in order:
            j = groups[-1][-1] if groups else -1
            same = j >= 0 and b.surface[i] == b.surface[j] and b.bottom[i] == b.bottom[j]
            if same and abs(b.launch_deg[i] - b.launch_deg[j]) <= 3.0 * spacing:
                groups[-1].append(int(i))
                continue
            groups.append([int(i)])
        for g in groups:
            yield (
                float(np.median(b.delay[g])),
                int(b.surface[g[0]]),
                int(b.bottom[g[0]]),
                float(np.median(b.launch_deg[g])),
            )


def main() -> None:
    import curved_cases as cc  # type: ignore[import-not-found]

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--links", type=int, default=12)
    ap.add_argument("--seed", type=int, default=2)
    ap.add_argument("--no-bellhop", action="store_true")
    args = ap.parse_args()
    rows_t, rows_b = [], []
    for case in cc.cases():
        t = dict(links=0, ref=0, found=0, missed_far=0, missed_near=0, confirmed=0, near_edge=0, extra=0, ratio=0.0)
        b = dict(ours=0, confirmed=0, lacking=0, worst=0.0)
        delta = 0.0
        t0 = time.time()
        for src, dst in cc.links(case, args.links, args.seed):
            cmp = cc.compare(case, src, dst)
            t["links"] += 1
            t["ref"] += len(cmp.reference)
            t["found"] += len(cmp.matched)
            t["missed_far"] += len(cmp.missed_far)
            t["missed_near"] += len(cmp.missed) - len(cmp.missed_far)
            t["confirmed"] += len(cmp.confirmed)
            t["near_edge"] += len(cmp.near_edge)
            t["extra"] += len(cmp.extra)
            t["ratio"] = max(t["ratio"], cmp.worst_ratio)
            delta = max(delta, cmp.delta_m)
            for e in cmp.missed_far:
                print(f"  {case.name}: missed code {e.code} at {math.degrees(e.launch):.4f} deg", file=sys.stderr)
            if not args.no_bellhop:
                ours = cmp.ours
                launches = list(np.degrees(ours.launch_angle)) + [math.degrees(e.launch) for e in cmp.reference]
                groups = list(bellhop_groups(case, src, dst, launches))
                used = np.zeros(len(groups), bool)
                for i in range(ours.delay.size):
                    b["ours"] += 1
                    cand = [
                        k for k, g in enumerate(groups)
                        if g[1] == ours.surface_bounces[i] and g[2] == ours.bottom_bounces[i] and not used[k]
                    ]  # fmt: skip
                    if cand:
                        k = min(cand, key=lambda k: abs(groups[k][0] - ours.delay[i]))
                        diff = abs(groups[k][0] - ours.delay[i])
                        if diff <= 1e-4:
                            used[k] = True
                            b["confirmed"] += 1
                            b["worst"] = max(b["worst"], diff)
                b["lacking"] += int((~used).sum())
            print(f"{case.name}: {t['links']} links, {time.time() - t0:.0f} s", file=sys.stderr)
        rows_t.append((case.name, t, delta))
        rows_b.append((case.name, b))
    print(
        "| floor | links | tracer's eigenrays | found | missed (>= 1e-3 deg from the edge / nearer) | ours beyond the tracer's fan: confirmed by shooting / within 1e-3 deg of an edge / extra | largest delay difference / tolerance | floor's largest departure, m |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name, t, delta in rows_t:
        print(f"| {name} | {t['links']} | {t['ref']} | {t['found']} | {t['missed_far']} / {t['missed_near']} | "
              f"{t['confirmed']} / {t['near_edge']} / {t['extra']} | {t['ratio']:.2f} | {delta:.1e} |")  # fmt: skip
    if not args.no_bellhop:
        print()
        print(
            "| floor | our eigenrays | confirmed by BELLHOP within 1e-4 s | BELLHOP's eigenrays we lack | largest difference, s |"
        )
        print("|---|---|---|---|---|")
        for name, b in rows_b:
            print(f"| {name} | {b['ours']} | {b['confirmed']} | {b['lacking']} | {b['worst']:.1e} |")


if __name__ == "__main__":
    main()
