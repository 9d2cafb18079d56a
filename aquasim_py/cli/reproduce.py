"""``aquasim-py reproduce PAPER``: a paper's claims run as resumable sweeps, reported claim by
claim under every reading (:mod:`aquasim_py.reproduce`)."""

from __future__ import annotations

import argparse
import os
import shlex
import signal
import sys
import time
from collections.abc import Sequence
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from aquasim_py.cli import common

EXAMPLES = """\
examples:
  aquasim-py reproduce stvf --quick                 # about 10 min on 2 cores or less
  aquasim-py reproduce mswpf --full --workers 2     # the paper's scale
  aquasim-py reproduce itmtl --quick --resume       # after Ctrl-C, a crash or a kill
  aquasim-py reproduce svlpf --quick --only s1_svlpf --runs 3
  aquasim-py reproduce ramezani --full --runs track=500      # fewer tracking trials only
  aquasim-py reproduce stvf --full --scheduler tcp://10.0.0.5:8786   # Dask cluster

DIR (--out, default out/reproduce/PAPER-SCALE) gets claims.csv (per claim and reading: the
paper's value, ours with its 95 % CI, whether the paper's number is inside it, n, the
verdict), claims.md, claims.png (a panel per claim), index.html, reproduce.json and
units/<unit>/ (each unit's row journal, sweep.csv, summary.csv). Fewer than 10 runs give no
verdict ("too few runs").
"""


def parser(papers: Sequence[str]) -> argparse.ArgumentParser:
    p = common.Parser(
        prog="aquasim-py reproduce",
        description="Run a paper's claims and write claims.csv and index.html.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("paper", metavar="PAPER", help=f"one of {', '.join(papers)}")
    scale = p.add_mutually_exclusive_group()
    scale.add_argument("--quick", action="store_const", dest="scale", const="quick", help="reduced scale (default)")
    scale.add_argument("--full", action="store_const", dest="scale", const="full", help="the paper's scale")
    run = p.add_mutually_exclusive_group()
    run.add_argument("--workers", type=common.positive_int, metavar="N", help="local worker processes (default: cores)")
    run.add_argument("--scheduler", metavar="ADDRESS", help="run on a Dask cluster (needs 'aquasim-py[dask]')")
    p.add_argument("--resume", action="store_true", help="keep the finished runs in DIR and run only the others")
    p.add_argument("--out", metavar="DIR", help="output directory (default: out/reproduce/PAPER-SCALE)")
    p.add_argument("--only", action="append", default=[], metavar="CLAIM", help="run only this claim (repeatable)")
    p.add_argument(
        "--runs",
        action="append",
        default=[],
        type=_runs,
        metavar="N|KEY=N",
        help="seeds per quantity instead of the scale's; KEY=N for the scale's scenario KEY only (repeatable)",
    )
    p.add_argument(
        "--set", action="append", default=[], metavar="KEY.PATH=VALUE", help="override on every run (repeatable)"
    )
    p.add_argument("--quiet", action="store_true", help="no progress and no table")
    return p


def _runs(text: str) -> tuple[str | None, int]:
    """``N`` or ``KEY=N`` of ``--runs``."""
    key, _, n = text.rpartition("=")
    return (key or None), common.positive_int(n)


def command(argv: Sequence[str]) -> int:
    from aquasim_py import reproduce as rp
    from aquasim_py.outdir import record_files, refuse_foreign

    args = parser(sorted(rp.PAPERS)).parse_args(argv)
    if args.paper not in rp.PAPERS:
        raise common.UsageError(f"reproduce: unknown paper {args.paper!r} (choose from {', '.join(sorted(rp.PAPERS))})")
    scale = args.scale or "quick"
    paper = rp.PAPERS[args.paper]
    try:
        rp.select(paper, args.only)
    except KeyError as e:
        raise common.UsageError(f"reproduce --only: {e.args[0]}") from None
    if args.scheduler is not None:
        try:
            import dask.distributed  # noqa: F401
        except ImportError:
            raise common.UsageError("--scheduler needs dask.distributed: pip install 'aquasim-py[dask]'") from None
    out = Path(args.out) if args.out else Path("out") / "reproduce" / f"{paper.key}-{scale}"
    refuse_foreign(out, None, "--out")
    sc = getattr(paper, scale)
    runs: dict[str | None, int] = dict(args.runs)
    bad = [k for k in runs if k is not None and k not in sc.scenarios]
    if bad:
        raise common.UsageError(
            f"reproduce --runs: no scenario {bad[0]!r} at this scale (keys: {', '.join(sc.scenarios)})"
        )
    # every unit's scenario is checked before anything runs (a bad --set fails here, exit 2)
    units = rp.plan_units(paper, sc, rp.select(paper, args.only), runs=runs or None, sets=args.set)
    for u in units:
        u.load()
    out.mkdir(parents=True, exist_ok=True)
    record_files(out, list(rp.OUTPUTS))
    cmd = shlex.join(["aquasim-py", "reproduce", *argv])
    workers = args.workers if args.workers is not None else (os.cpu_count() or 1)

    # on a terminal one line rewritten in place; in a log (stdout or stderr redirected) whole
    # lines, at most one every 5 s, and the last of each unit
    live = sys.stdout.isatty() and sys.stderr.isatty()
    last = [0.0]

    def progress(unit: rp.Unit, done: int, total: int) -> None:
        if args.quiet:
            return
        if live:
            print(f"\r{unit.name}: {done}/{total} runs", end="" if done < total else "\n", file=sys.stderr, flush=True)
        elif done == total or time.monotonic() - last[0] >= 5.0:
            last[0] = time.monotonic()
            print(f"{unit.name}: {done}/{total} runs", file=sys.stderr, flush=True)

    try:
        res = rp.reproduce(
            paper,
            scale,
            out,
            workers=workers,
            scheduler=args.scheduler,
            resume=args.resume,
            only=args.only,
            runs=runs or None,
            sets=args.set,
            command=cmd,
            progress=progress,
        )
    except (KeyboardInterrupt, BrokenProcessPool) as e:
        why = "a worker process died" if isinstance(e, BrokenProcessPool) else "interrupted"
        if isinstance(e, common.Interrupted):
            why = f"interrupted by {signal.Signals(e.signum).name}"
            e.detail = f"finished runs kept in {out}; finish with --resume"
            raise
        print(f"error: {why}: finished runs kept in {out}; finish with --resume", file=sys.stderr)
        return 130 if isinstance(e, KeyboardInterrupt) else 1
    record_files(out, sorted(p.relative_to(out).as_posix() for p in (out / "units").rglob("*") if p.is_file()))
    if not args.quiet:
        _print_table(res.table)
    counts = res.table["verdict"].value_counts().to_dict()
    print(
        f"{paper.key} {scale}: {len(res.table)} claim rows ({counts}) in {res.wall_s:.0f} s wall, "
        f"{res.cpu_s:.0f} s CPU -> {out / 'claims.csv'}, {out / 'claims.png'}"
    )
    return 0


def _print_table(table: object) -> None:
    from rich.table import Table

    from aquasim_py.reproduce.report import ours_text, paper_text, short_statistic, wording
    from aquasim_py.runner import console

    t = Table(title="claims: ours [95 % CI] in the claim's unit")
    for c in ("claim", "reading", "paper", "ours", "statistic", "verdict"):
        t.add_column(c)
    for r in table.itertuples():  # type: ignore[attr-defined]
        t.add_row(
            r.claim,
            r.reading,
            paper_text(r),
            ours_text(r),
            short_statistic(r.kind, r.statistic_of_runs, r.n, r.reduce),
            wording(r),
        )
    console().print(t)
