"""Why does STVF trail SLMP here? A controlled experiment outside the network.

One unknown node drifts at about 1 m/s (the meandering-current speed of Table 1); six references
drift with it (small relative drift), 20-75 m away, positions known exactly. Every 1-s period
the node measures one-way delays (ms, std 2 % of the delay), keeps the best Nr = 3 by gamma
(eqs 27-29, as the text reads eq 27: nearest references first; the protocol's default is eq 27
as printed) and runs Algorithm 1 (``aquasim_py.estimation.variational``) from its previous
q(mu), exactly as ``protocols/stvf/node.py`` does, but with no kernel, no packet loss and no
promotion: only the filter's own dynamics are left. Each variant changes one thing in Table 1:

- ``table1``: Table 1 as shipped (z in ms, Gam(3, 200), W = 5 I, n = 10, stop at 0.1 m).
- ``one_sample_set``: one set of importance samples for all passes of a localization (our
  former default) instead of new samples in every pass (Algorithm 1).
- ``fixed_point``: the same equations iterated towards their fixed point (stop at 1e-4 m, at
  most 300 passes).
- ``z_in_seconds``: Table 1 with z in seconds (the other reading of the unit).
- ``noise_prior_matched``: Gam(3, beta) with beta = 3 sigma^2, sigma = 0.67 ms (2 % of the
  delay over 50 m), i.e. a noise prior that matches the simulated ranging error.
- ``loose_wishart``: W = 0.01 I (prior state std about 3 m around mu instead of 0.14 m).
- ``nr_2``, ``nr_6``, ``nr_6_matched``: 2 or all 6 measurements instead of Nr = 3.

Baselines on the same measurements: a least-squares fix (linear multilateration refined by
scipy's least_squares, as SLMP computes it) from the same 3 references each period, and from
all 6. Prints mean error and the along-track component (positive = behind the node)
over t >= 30 s, the mean iteration count and the proposal std at the last iteration, over
``--runs`` independent runs (also written to ``--out`` as CSV).

    python tools/stvf_lag.py [--runs 10] [--periods 120]     # about 2.5 CPU-minutes
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from aquasim_py.estimation import variational as vf
from aquasim_py.estimation.lsq import multilaterate

SPEED = 1500.0


def variants() -> dict[str, tuple[vf.STVFPrior, int]]:
    """name -> (prior, Nr): Table 1 with one thing changed."""
    base = vf.STVFPrior()
    sigma_ms = 0.02 * 1e3 * 50.0 / SPEED  # 2 % of the delay over a typical 50 m link
    matched = base.noise_shape * sigma_ms**2
    return {
        "table1": (base, 3),
        "one_sample_set": (replace(base, common_random_numbers=True), 3),
        "fixed_point": (replace(base, tol=1e-4, max_iter=300), 3),
        "z_in_seconds": (replace(base, z_scale=1.0), 3),
        "noise_prior_matched": (replace(base, noise_rate=matched), 3),
        "loose_wishart": (replace(base, wishart_scale=0.01 * np.eye(4)), 3),
        "nr_2": (base, 2),
        "nr_6": (base, 6),
        "nr_6_matched": (replace(base, noise_rate=matched), 6),
    }


def fix(refs: np.ndarray, ranges: np.ndarray) -> np.ndarray:
    """Nonlinear least-squares position (m) from ranges, started at the linear multilateration
    (what SLMP computes)."""
    return least_squares(lambda p: np.linalg.norm(refs - p, axis=1) - ranges, multilaterate(refs, ranges)).x


def velocity(t: np.ndarray | float) -> np.ndarray:
    """A slowly turning drift of about 1 m/s (m/s)."""
    return np.stack([0.8 * np.cos(0.03 * np.asarray(t)), 0.6 + 0.3 * np.sin(0.05 * np.asarray(t))], -1)


def one_run(prior: vf.STVFPrior, n_ref: int, seed: int, periods: int) -> dict[str, np.ndarray]:
    """Errors (periods, 2) of STVF and of the two least-squares baselines for one run."""
    rng = np.random.default_rng(seed)
    noise_rng = np.random.default_rng(seed + 10_000)  # same measurements for every variant
    filt_rng = np.random.default_rng(seed + 20_000)
    ang = rng.uniform(0, 2 * np.pi, 6)
    rad = rng.uniform(20.0, 75.0, 6)
    offsets = np.stack([rad * np.cos(ang), rad * np.sin(ang)], -1)
    drift = rng.normal(0.0, 0.05, (6, 2))  # m/s relative to the node
    scale = prior.z_scale

    t = np.arange(periods + 1, dtype=float)
    truth = np.vstack([np.zeros(2), np.cumsum(velocity(t[:-1]), axis=0)])
    out = {k: np.full((periods, 2), np.nan) for k in ("stvf", "ls3", "ls6")}
    its = np.zeros(periods)
    prop = np.zeros(periods)
    mu = lp = None
    for k in range(1, periods + 1):
        refs = truth[k] + offsets + drift * t[k]
        r = np.linalg.norm(refs - truth[k], axis=1)
        z_ms = 1e3 * r / SPEED * (1.0 + 0.02 * noise_rng.standard_normal(6))
        # eq 27 as the text reads it (nearest first), the reading these measurements were taken
        # with (docs/stvf.md); the protocol's default is eq 27 as printed (penalize=False)
        gamma = vf.measurement_confidence(np.ones(6), z_ms, np.zeros(6), penalize=True)
        sel = vf.select_references(gamma, n_ref)
        sel3 = vf.select_references(gamma, 3)
        ranges = z_ms * SPEED / 1e3
        out["ls6"][k - 1] = fix(refs, ranges) - truth[k]
        out["ls3"][k - 1] = fix(refs[sel3], ranges[sel3]) - truth[k]
        if mu is None or lp is None:
            mu, lp = vf.initial_prior(out["ls6"][k - 1] + truth[k], 10.0)
        assert mu is not None and lp is not None
        mu_p, lp_p = vf.predict(mu, lp, prior.transition)
        res = vf.variational_update(z_ms[sel] * scale / 1e3, refs[sel], mu_p, lp_p, prior, filt_rng)
        mu, lp = res.mu, res.mu_precision
        out["stvf"][k - 1] = res.position - truth[k]
        its[k - 1] = res.iterations
        prop[k - 1] = float(np.sqrt(np.trace(np.linalg.inv(res.lam)[np.ix_(vf.POS, vf.POS)]) / 2))
    vel = velocity(t[1:])
    unit = vel / np.linalg.norm(vel, axis=1, keepdims=True)
    return {**out, "its": its, "prop": prop, "unit": unit}


def summarize(name: str, runs: list[dict[str, np.ndarray]], burn: int) -> dict[str, Any]:
    def stats(key: str) -> tuple[float, float]:
        err = np.concatenate([r[key][burn:] for r in runs])
        unit = np.concatenate([r["unit"][burn:] for r in runs])
        return float(np.linalg.norm(err, axis=1).mean()), float(-(err * unit).sum(1).mean())

    e, lag = stats("stvf")
    its = np.concatenate([r["its"][burn:] for r in runs])
    prop = np.concatenate([r["prop"][burn:] for r in runs])
    return {
        "variant": name,
        "error_m": e,
        "behind_m": lag,
        "iterations": float(its.mean()),
        "within_5": float((its <= 5).mean()),
        "proposal_std_m": float(np.median(prop)),
        "ls3_m": stats("ls3")[0],
        "ls6_m": stats("ls6")[0],
    }


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--periods", type=int, default=120)
    ap.add_argument("--burn", type=int, default=30, help="periods skipped before scoring")
    ap.add_argument("--out", default="out/stvf_lag.csv")
    a = ap.parse_args(argv)
    rows = []
    for name, (prior, n_ref) in variants().items():
        runs = [one_run(prior, n_ref, s, a.periods) for s in range(a.runs)]
        rows.append(summarize(name, runs, a.burn))
    import pandas as pd

    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    pd.DataFrame(rows).to_csv(a.out, index=False)
    head = f"{'variant':<22}{'error m':>9}{'behind m':>10}{'iters':>7}{'<=5':>6}{'prop std m':>11}"
    print(head + f"{'LS(3) m':>9}{'LS(6) m':>9}")
    for r in rows:
        print(
            f"{r['variant']:<22}{r['error_m']:>9.2f}{r['behind_m']:>10.2f}{r['iterations']:>7.1f}"
            f"{r['within_5']:>6.2f}{r['proposal_std_m']:>11.3f}{r['ls3_m']:>9.2f}{r['ls6_m']:>9.2f}"
        )


if __name__ == "__main__":
    main()
