"""ITMTL: do anchor-covered nodes keep their anchor-only sync error when promotion is on?

    python tools/itmtl_anchor_covered.py [--seeds 20] [--workers 1]

Runs the main job's ``itmtl`` variant (600 s) with promotion on (the scenario as written) and
off (anchors only) for each seed, takes the ordinary nodes whose last round had answers from
at least ``min_refs`` buoys / anchors in both runs, and prints the mean final |sync error| of
those nodes in each mode and their paired difference (95 % t-intervals over the node finals).
The hierarchy (docs/itmtl.md) means such a node uses anchors only, so the two should agree.
"""

from __future__ import annotations

import argparse
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from itmtl_compare import SCEN, scenario_raw, t_ci

from aquasim_py import scenario


def final_errors(args: tuple[int, bool]) -> dict[int, float]:
    """node -> final |sync error| (s) of the anchor-covered ordinary nodes of one run."""
    seed, promotion = args
    raw = scenario_raw("itmtl", seed, 600.0, "meandering", promotion)
    sim = scenario.build(scenario.load_dict(raw, SCEN))
    sim.run(600.0)
    fr = sim.trace.frames()
    rounds = fr["reqres_rounds"]
    last = rounds[rounds["protocol"] == "itmtl"].sort_values("round").groupby("node").tail(1)
    covered = last.loc[last["anchors"] >= last["needed"], "node"]
    clk: pd.DataFrame = fr["clocks"]
    fin = clk[clk["node"].isin(covered)].sort_values("time").groupby("node").tail(1)
    return dict(zip(fin["node"].astype(int), fin["error"].abs()))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--workers", type=int, default=1)
    a = ap.parse_args()
    jobs = [(s, p) for p in (True, False) for s in range(1, a.seeds + 1)]
    with ProcessPoolExecutor(a.workers) as ex:
        out = list(ex.map(final_errors, jobs))
    on_all, off_all = out[: a.seeds], out[a.seeds :]
    on, off = [], []
    for x, y in zip(on_all, off_all, strict=True):
        for n in sorted(set(x) & set(y)):
            on.append(x[n])
            off.append(y[n])
    diff = [p - q for p, q in zip(on, off, strict=True)]

    def us(ci: tuple[float, float, float]) -> str:
        return f"{ci[0] * 1e6:.2f} [{ci[1] * 1e6:.2f}, {ci[2] * 1e6:.2f}] us"

    print(
        f"{len(on)} node finals over {a.seeds} seeds: promotion on {us(t_ci(on))}, "
        f"anchors only {us(t_ci(off))}, paired difference {us(t_ci(diff))}"
    )


if __name__ == "__main__":
    main()
