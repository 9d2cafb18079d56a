"""Is a run's peak memory flat in simulated time? Peak RSS of a short and a long run, metrics included.

    python tools/memory_flat.py                                   # 7-node beacon, 600 s vs 12000 s
    python tools/memory_flat.py --durations 600 3000 12000
    python tools/memory_flat.py scenarios/itmtl.toml --set 'trace.tables=["nodes"]' --variant itmtl

Runs ``aquasim-py SCENARIO --quiet --out TMP`` once per duration, each in its own subprocess,
and reads that child's peak resident set size from the kernel (``os.wait4``'s rusage
``ru_maxrss``: the high-water mark of the whole process, so the metric stage at the end of
the run is included). The default is the acceptance case of issue 35 item 8: the beacon
scenario with 3 sensors (7 nodes: 4 anchors, 3 sensors) and only the ``nodes`` table written
(the metrics still read ``packets`` / ``estimates`` / ``clocks`` from scratch files). Prints
one line per duration and the growth of the last over the first; exits 1 when it exceeds
``--limit`` (default 10 %). Not part of the test suite (a 12000-s run takes about a minute).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: the acceptance case: 7 nodes, only the nodes table written
DEFAULT_SETS = ("nodes.1.count=3", 'trace.tables=["nodes"]')


def peak_rss_mb(cmd: list[str], cwd: str) -> tuple[float, float]:
    """(peak RSS in MiB, wall s) of ``cmd`` run to completion as a child process."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode() if proc.stderr else ""
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{err}")
    scale = 1.0 if sys.platform == "darwin" else 1024.0  # ru_maxrss: bytes on macOS, KiB on Linux
    return usage.ru_maxrss * scale / 2**20, wall


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenario", nargs="?", default=str(ROOT / "scenarios" / "beacon.toml"))
    ap.add_argument("--durations", type=float, nargs="+", default=[600.0, 12000.0], help="simulated s")
    ap.add_argument("--set", action="append", default=None, help="as aquasim-py --set (default: the 7-node case)")
    ap.add_argument("--variant", default=None)
    ap.add_argument("--limit", type=float, default=10.0, help="allowed growth, %% of the first duration's peak")
    ap.add_argument("--cli", default=None, help="the aquasim-py executable (default: beside this Python)")
    args = ap.parse_args()
    cli = args.cli or str(Path(sys.executable).with_name("aquasim-py"))
    sets = DEFAULT_SETS if args.set is None else tuple(args.set)
    peaks = []
    for dur in args.durations:
        with tempfile.TemporaryDirectory() as tmp:
            cmd = [cli, str(Path(args.scenario).resolve()), "--quiet", "--out", str(Path(tmp) / "out")]
            for s in (*sets, f"simulation.duration_s={dur}"):
                cmd += ["--set", s]
            if args.variant:
                cmd += ["--variant", args.variant]
            peak, wall = peak_rss_mb(cmd, tmp)
        peaks.append(peak)
        print(f"{dur:>9g} s simulated: peak RSS {peak:8.1f} MiB  ({wall:.1f} s wall)", flush=True)
    growth = 100.0 * (peaks[-1] / peaks[0] - 1.0)
    print(f"growth {args.durations[-1]:g} s over {args.durations[0]:g} s: {growth:+.1f} % (limit {args.limit:g} %)")
    return 0 if growth <= args.limit else 1


if __name__ == "__main__":
    sys.exit(main())
