"""Ray-tracer throughput benchmark: pairs per second on one core, with a same-run baseline.

    python tools/bench_raytrace.py [--quick]
    python tools/bench_raytrace.py --profile          # cProfile of the layered direct-only case
    python tools/bench_raytrace.py --dump out/rays.npz  # the layered case's eigenrays, to compare

Every case is a function returning a :class:`Case` (a label, a zero-argument callable that
traces all its pairs, and the pair count); ``CASES`` lists them. The baseline is the plain
straight-line delay ``np.linalg.norm(dst - src, axis=-1) / c`` over the same kind of pairs,
timed in the same run, so the printed ratios are comparable across machines even when the
absolute numbers are not (the machine is shared). Times are CPU times (best of the repeats).
The baseline is timed again after the other cases and the faster of its two runs is used, so
a load change during the run does not skew the ratios of the later (layered) cases.
"""

from __future__ import annotations

import os

# one core: numpy's element-wise kernels are single-threaded, but keep BLAS pools out of it
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from aquasim_py.channel import isogradient  # noqa: E402


@dataclass(frozen=True)
class Case:
    label: str
    run: Callable[[], object]
    pairs: int


def random_pairs(
    n: int, seed: int = 0, depth_m: float = 1000.0, span_m: float = 5000.0
) -> tuple[np.ndarray, np.ndarray]:
    """n (src, dst) pairs uniform in a span x span x depth box (m)."""
    rng = np.random.default_rng(seed)
    lo, hi = np.array([0.0, 0.0, 0.0]), np.array([span_m, span_m, depth_m])
    return rng.uniform(lo, hi, (n, 3)), rng.uniform(lo, hi, (n, 3))


def case_baseline(n: int) -> Case:
    src, dst = random_pairs(n)
    return Case("baseline: norm(dst - src) / c", lambda: np.linalg.norm(dst - src, axis=-1) / 1500.0, n)


def case_isogradient_time(n: int) -> Case:
    src, dst = random_pairs(n)
    return Case("isogradient travel_time (a = +0.1)", lambda: isogradient.travel_time(1480.0, 0.1, src, dst), n)


def case_isogradient_time_checked(n: int) -> Case:
    """Negative gradient plus a bottom: the surface/bottom (vertex) check is on."""
    src, dst = random_pairs(n)
    return Case(
        "isogradient travel_time (a = -0.05, bottom)",
        lambda: isogradient.travel_time(1520.0, -0.05, src, dst, bottom=1000.0),
        n,
    )


def case_isogradient_eigenray(n: int) -> Case:
    src, dst = random_pairs(n)
    return Case("isogradient eigenray (all fields)", lambda: isogradient.eigenray(1480.0, 0.1, src, dst), n)


def case_isogradient_gradient(n: int) -> Case:
    src, dst = random_pairs(n)
    return Case("isogradient travel_time_gradient", lambda: isogradient.travel_time_gradient(1480.0, 0.1, src, dst), n)


#: (case function, number of pairs in a full run); the layered cases are appended here
CASES: list[tuple[Callable[[int], Case], int]] = [
    (case_isogradient_time, 1_000_000),
    (case_isogradient_time_checked, 1_000_000),
    (case_isogradient_eigenray, 1_000_000),
    (case_isogradient_gradient, 1_000_000),
]


def best_seconds(fn: Callable[[], object], repeats: int) -> float:
    """Best CPU time (``time.process_time``) of ``repeats`` calls after one warm-up.

    CPU time, not wall time: on a shared machine the process is descheduled for whole time
    slices, which wall time counts and CPU time does not; the best of several repeats drops
    the remaining (cache and memory-bandwidth) interference."""
    fn()
    best = float("inf")
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def main(argv: list[str] | None = None) -> list[dict[str, float | str]]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="10x fewer pairs, fewer repeats")
    ap.add_argument(
        "--profile", action="store_true", help="cProfile the layered direct-only case (top 15 by own time) instead"
    )
    ap.add_argument(
        "--dump",
        type=Path,
        default=None,
        help="write the layered case's eigenrays (50 000 pairs; reflections none, fallback, all) to this .npz instead",
    )
    args = ap.parse_args(argv)
    if args.dump is not None:
        dump_layered(args.dump, 50_000)
        return []
    if args.profile:
        profile_layered(max(50_000 // (10 if args.quick else 1), 1))
        return []
    scale, repeats = (10, 3) if args.quick else (1, 5)
    rows: list[dict[str, float | str]] = []
    base = case_baseline(max(CASES[0][1] // scale, 1))
    base_rate = base.pairs / best_seconds(base.run, repeats)
    rows.append({"case": base.label, "pairs": base.pairs, "pairs_per_s": base_rate, "vs_baseline": 1.0})
    measured = []
    for make, n in CASES:
        case = make(max(n // scale, 1))
        measured.append((case, case.pairs / best_seconds(case.run, repeats)))
    base_rate = max(base_rate, base.pairs / best_seconds(base.run, repeats))
    rows[0]["pairs_per_s"] = base_rate
    for case, rate in measured:
        rows.append({"case": case.label, "pairs": case.pairs, "pairs_per_s": rate, "vs_baseline": base_rate / rate})
    width = max(len(str(r["case"])) for r in rows)
    print(f"{'case':<{width}}  {'pairs':>9}  {'pairs/s':>12}  {'time / baseline':>15}")
    for r in rows:
        print(f"{r['case']:<{width}}  {r['pairs']:>9d}  {r['pairs_per_s']:>12.3e}  {r['vs_baseline']:>15.2f}")
    return rows


# ---------------------------------------------------------------- layered solver (layered.py)

#: a 10-layer profile with a sound-speed minimum (channel axis at 300 m) and a sea floor
LAYERED_DEPTHS = (0.0, 50.0, 120.0, 200.0, 300.0, 420.0, 550.0, 700.0, 850.0, 1000.0, 1200.0)
LAYERED_SPEEDS = tuple(1500.0 + d for d in (0.0, -5.0, -12.0, -20.0, -24.0, -20.0, -14.0, -8.0, -2.0, 4.0, 8.0))


def _layered_profile():
    from aquasim_py.channel import Layered

    return Layered(LAYERED_DEPTHS, LAYERED_SPEEDS, bottom=1200.0)


def case_layered_time(n: int) -> Case:
    """Direct path only (the solver's own cost)."""
    from aquasim_py.channel import layered

    prof = _layered_profile()
    src, dst = random_pairs(n)
    return Case(
        "layered travel_time, 10 layers (direct only)",
        lambda: layered.travel_time(prof, src, dst, reflections="none"),
        n,
    )


def case_layered_time_fallback(n: int) -> Case:
    """What the channel calls: reflected arrivals where there is no direct path."""
    from aquasim_py.channel import layered

    prof = _layered_profile()
    src, dst = random_pairs(n)
    return Case(
        "layered travel_time, 10 layers (reflection fallback)",
        lambda: layered.travel_time(prof, src, dst, reflections="fallback"),
        n,
    )


def case_layered_gradient(n: int) -> Case:
    from aquasim_py.channel import layered

    prof = _layered_profile()
    src, dst = random_pairs(n)
    return Case("layered travel_time_gradient, 10 layers", lambda: layered.travel_time_gradient(prof, src, dst), n)


def layered_cases() -> list[tuple[Callable[[int], Case], int]]:
    """The layered solver's cases (target: >= 20 000 pairs/s on one core for 10 layers)."""
    return [(case_layered_time, 50_000), (case_layered_time_fallback, 50_000), (case_layered_gradient, 50_000)]


CASES.extend(layered_cases())


def profile_layered(n: int, top: int = 15) -> None:
    """Print the ``top`` functions by own time of one layered direct-only run (after a warm-up)."""
    import cProfile
    import pstats

    case = case_layered_time(n)
    case.run()
    prof = cProfile.Profile()
    prof.runcall(case.run)
    pstats.Stats(prof).strip_dirs().sort_stats("tottime").print_stats(top)


def dump_layered(path: Path, n: int) -> None:
    """Save every eigenray field of the layered case's pairs for reflections none, fallback and
    all (``{mode}_{field}`` arrays), to compare two versions of the solver pair by pair."""
    from aquasim_py.channel import layered

    prof = _layered_profile()
    src, dst = random_pairs(n)
    out = {}
    for mode in ("none", "fallback", "all"):
        ray = layered.eigenray(prof, src, dst, reflections=mode)
        for f in ("time", "length", "launch_angle", "arrival_angle", "turning_depth", "path"):
            out[f"{mode}_{f}"] = np.asarray(getattr(ray, f))
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, **out)  # type: ignore[arg-type]


if __name__ == "__main__":
    main()
