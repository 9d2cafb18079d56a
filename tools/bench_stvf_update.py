"""STVF's variational update alone: CPU per update and a hash of the outputs, to time changes
of aquasim_py/estimation/variational.py and check that they are bit-identical.

    python tools/bench_stvf_update.py     # 1500 updates, Table 1's prior, Nr = 3, Ns = Nv = 100

Prints ms per update (process CPU time) and the first 16 hex digits of a SHA-256 over every
update's <s>, Lambda*, <v>, pass count and confidence, and over 600 predictions. Then the same
cases with one generator per case, run one at a time and as batches of 160 (Table 1's unknown
nodes, ``variational_update_batch``): ms per update of each and whether their hashes agree.
"""

from __future__ import annotations

import hashlib
import time

import numpy as np

from aquasim_py.estimation import variational as vf


def main() -> None:
    prior = vf.STVFPrior(n_state_samples=100, n_speed_samples=100)
    rng = np.random.default_rng(1)
    cases = []
    for _ in range(1500):
        node = rng.uniform(0, 200, 2)
        refs = node + rng.uniform(-50, 50, (3, 2))
        z = 1e3 * np.linalg.norm(refs - node, axis=1) / 1500 * (1 + 0.02 * rng.standard_normal(3))
        mu, prec = vf.initial_prior(node + rng.normal(0, 5, 2), 10.0)
        cases.append((z, refs, *vf.predict(mu, prec, prior.transition)))
    h = hashlib.sha256()
    draws = np.random.default_rng(7)
    t = time.process_time()
    for z, refs, mp, lp in cases:
        o = vf.variational_update(z, refs, mp, lp, prior, draws)
        conf = vf.localization_confidence([1.0, 1.0, 1.0], o.position, refs, z, o.speed, absolute=True)
        for a in (o.state, o.mu_precision, np.float64(o.speed), np.int64(o.iterations), np.float64(conf)):
            h.update(np.asarray(a).tobytes())
    dt = time.process_time() - t
    for _z, _refs, mp, lp in cases[:300]:
        for gaps in (1, 2):
            m, p = vf.predict(mp, lp, prior.transition / gaps)
            h.update(m.tobytes())
            h.update(p.tobytes())
    print(f"{dt / len(cases) * 1e3:.3f} ms per update, hash {h.hexdigest()[:16]}")
    one = _per_case(cases, prior, 1)
    many = _per_case(cases, prior, 160)
    print(
        f"one generator per case: {one[0]:.3f} ms per update alone, {many[0]:.3f} in batches of 160, "
        f"hashes {'equal' if one[1] == many[1] else 'DIFFERENT'} ({one[1]})"
    )


def _per_case(cases: list, prior: vf.STVFPrior, size: int) -> tuple[float, str]:
    """(ms per update, hash) of the cases in batches of ``size``, case k drawing from its own
    generator seeded k (a batch of one is ``variational_update``'s path)."""
    h = hashlib.sha256()
    t = time.process_time()
    for s in range(0, len(cases), size):
        part = cases[s : s + size]
        gens = [np.random.default_rng(s + k) for k in range(len(part))]
        z, refs, mu_p, lp = (np.stack([c[i] for c in part]) for i in range(4))
        outs = vf.variational_update_batch(z, refs, mu_p, lp, prior, gens)
        for o in outs:
            for a in (o.state, o.mu, o.mu_precision, o.lam, np.float64(o.speed), np.int64(o.iterations)):
                h.update(np.asarray(a).tobytes())
    return (time.process_time() - t) / len(cases) * 1e3, h.hexdigest()[:16]


if __name__ == "__main__":
    main()
