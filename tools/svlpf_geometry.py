"""The SVL-PF sensor layout of scenarios/svlpf*.toml, reconstructed from the paper's Table 1.

The paper (Li et al., Sensors 18:8, 2018) does not publish its 20 sensor positions; Table 1
gives how many lie within 10/40/50/60/70/80/90/100 m of the target at (40, 50, 60):
0/2/8/14/18/20/20/20. This script draws, with a fixed seed, 20 positions in the 100 m cube
with exactly those counts: per distance band [lo, hi) the band's number of sensors, each at a
distance uniform in the band and a direction uniform on the sphere (redrawn until inside the
cube). It prints the explicit placement for the scenario files.

    python tools/svlpf_geometry.py [--seed 2018]
"""

from __future__ import annotations

import argparse

import numpy as np

TARGET = np.array([40.0, 50.0, 60.0])
#: (band lo m, band hi m, sensors) from Table 1's first row
BANDS = ((10.0, 40.0, 2), (40.0, 50.0, 6), (50.0, 60.0, 6), (60.0, 70.0, 4), (70.0, 80.0, 2))


def layout(seed: int = 2018, lo: float = 0.0, hi: float = 100.0) -> np.ndarray:
    """(20, 3) sensor positions (m) with Table 1's distance counts from (40, 50, 60)."""
    rng = np.random.default_rng(seed)
    out = []
    for a, b, n in BANDS:
        got = 0
        while got < n:
            r = rng.uniform(a, b)
            u = rng.standard_normal(3)
            p = TARGET + r * u / np.linalg.norm(u)
            if np.all((p >= lo) & (p <= hi)):
                out.append(np.round(p, 2))
                got += 1
    return np.array(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=2018)
    args = ap.parse_args()
    P = layout(args.seed)
    d = np.linalg.norm(P - TARGET, axis=1)
    print("# counts within 10..100 m:", [int((d < r).sum()) for r in (10, 40, 50, 60, 70, 80, 90, 100)])
    print("positions = [")
    for p in P:
        print(f"    [{p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}],")
    print("]")


if __name__ == "__main__":
    main()
