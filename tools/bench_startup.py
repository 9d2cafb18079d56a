"""Start-up times: ``import aquasim_py``, ``aquasim-py --version`` and ``--help``, and a short run
(``scenarios/beacon.toml``, 1 s simulated) to its first event and to its end; this checkout
against another one, timed in the same session and alternated.

    python tools/bench_startup.py                      # against the previous commit (HEAD~1)
    python tools/bench_startup.py --baseline v0.1.0 --rounds 20

Both sides are installed as tools/bench_scenarios.py installs them (``pip install --no-deps
--target``, byte-compiled: the start-up of an installed package, not of a source tree compiled
on every import) and each measurement is a fresh process of this interpreter. The short run's
first event is the moment ``Simulation.run`` is entered (everything it needs is imported and the
network built; the child wraps that method, after importing the kernel a run imports anyway).
The table gives the minimum over the rounds of the wall time and of the CPU time (user +
system) of each: start-up noise only ever adds time, so the minimum is the figure an idle
machine gives (``python -c pass`` is the interpreter's own floor).
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_scenarios import _CLI, Side, install_checkout, install_revision  # tools/, beside this script

#: runs the CLI and prints, on stderr, the monotonic clock and the CPU time when the simulation starts
_FIRST_EVENT = """\
import resource, sys, time
from aquasim_py import kernel
_run = kernel.Simulation.run
def run(self, *args, **kwargs):
    u = resource.getrusage(resource.RUSAGE_SELF)
    print("first-event", time.monotonic(), u.ru_utime + u.ru_stime, file=sys.stderr, flush=True)
    return _run(self, *args, **kwargs)
kernel.Simulation.run = run
from aquasim_py.cli import main
sys.exit(main(sys.argv[1:]))
"""

#: name -> python arguments
STEPS: dict[str, list[str]] = {
    "python -c pass": ["-c", "pass"],
    "import aquasim_py": ["-c", "import aquasim_py"],
    "aquasim-py --version": ["-c", _CLI, "--version"],
    "aquasim-py --help": ["-c", _CLI, "--help"],
}
SHORT_RUN = ["scenarios/beacon.toml", "--set", "simulation.duration_s=1", "--quiet"]


def _timed(side: Side, args: list[str], cwd: Path) -> tuple[float, float, str]:
    """(wall s, CPU s, stderr) of one process of ``side``'s Python."""
    env = dict(os.environ)
    if side.pythonpath is not None:
        env["PYTHONPATH"] = side.pythonpath
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.monotonic()
    # cwd outside both checkouts: Python puts the current directory first on its path
    p = subprocess.run([side.python, *args], env=env, cwd=cwd, capture_output=True, text=True, check=False)
    wall = time.monotonic() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode != 0:
        raise SystemExit(f"{side.label}: {args} exited {p.returncode}\n{p.stderr}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), p.stderr


def measure(side: Side, tmp: Path) -> dict[str, tuple[float, float]]:
    """One round: (wall s, CPU s) of every step of ``side``."""
    out = {name: _timed(side, args, tmp)[:2] for name, args in STEPS.items()}
    t0 = time.monotonic()
    dest = tmp / f"out-{side.label}"
    wall, cpu, err = _timed(
        side, ["-c", _FIRST_EVENT, str(side.root / SHORT_RUN[0]), *SHORT_RUN[1:], "--out", str(dest)], tmp
    )
    _, at, cpu_at = next(line.split() for line in err.splitlines() if line.startswith("first-event"))
    out["short run: to its first event"] = (float(at) - t0, float(cpu_at))
    out["short run: whole (1 s simulated)"] = (wall, cpu)
    shutil.rmtree(dest, ignore_errors=True)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--baseline", default="HEAD~1", help="git revision to compare with (default HEAD~1)")
    ap.add_argument("--no-baseline", action="store_true", help="time this checkout alone")
    ap.add_argument("--rounds", type=int, default=10, help="rounds (default 10)")
    args = ap.parse_args(argv)
    if args.rounds < 1:
        ap.error("--rounds must be >= 1")
    with tempfile.TemporaryDirectory(prefix="bench-startup-") as tmp_s:
        tmp = Path(tmp_s)
        print("installing this checkout ...", file=sys.stderr, flush=True)
        sides = [install_checkout(tmp / "current")]
        if not args.no_baseline:
            print(f"installing {args.baseline} ...", file=sys.stderr, flush=True)
            sides.append(install_revision(args.baseline, tmp / "baseline"))
        best: dict[str, dict[str, tuple[float, float]]] = {s.label: {} for s in sides}
        for r in range(args.rounds):
            for side in sides if r % 2 == 0 else sides[::-1]:
                for name, (wall, cpu) in measure(side, tmp).items():
                    w, c = best[side.label].get(name, (wall, cpu))
                    best[side.label][name] = (min(w, wall), min(c, cpu))
            print(f"round {r + 1} done", file=sys.stderr, flush=True)
    cols = ["", *(f"{what} ({s.label})" for s in sides for what in ("wall s", "CPU s"))]
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for name in best[sides[0].label]:
        print(
            f"| {name} | "
            + " | ".join(f"{best[s.label][name][0]:.3f} | {best[s.label][name][1]:.3f}" for s in sides)
            + " |"
        )
    load = os.getloadavg()
    print(
        f"\nminimum of {args.rounds} round(s), sides alternated; load average {load[0]:.1f} (1 min) on {os.cpu_count()} CPUs"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
