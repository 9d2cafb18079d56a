"""``aquasim-py report DIR``: plots and ``report.html`` for a run's or a sweep's output directory."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from aquasim_py.cli import common

EXAMPLES = """examples:
  aquasim-py report out/itmtl                  # a run: map, errors, sync, CDF, packets
  aquasim-py report out/itmtl/wsc              # one variant of a run with variants
  aquasim-py report out/itmtl_sweep            # a sweep: each metric vs the swept values, 95 % CI
  aquasim-py report out/itmtl --out /tmp/rep   # write the report elsewhere
"""


def parser() -> argparse.ArgumentParser:
    p = common.Parser(
        prog="aquasim-py report",
        description="Draw PNG plots and one self-contained report.html (images embedded) from the "
        "output directory of a run (summary.json + trace tables) or of a sweep (sweep.csv).",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("directory", metavar="DIR", help="a run's or a sweep's output directory")
    p.add_argument("--out", metavar="DIR", help="where to write the plots and report.html (default: DIR)")
    return p


def _report_into(directory: Path, out: Path) -> Path:
    """Write the report of ``directory`` into ``out`` and list its files in ``out``'s manifest."""
    from aquasim_py.outdir import record_files
    from aquasim_py.report import write_report

    html = write_report(directory, out)
    record_files(out, sorted(p.name for p in out.iterdir() if p.suffix == ".png" or p == html))
    return html


def reports_for(out: Path) -> list[Path]:
    """Report every run under ``out``: the run itself, or each variant directory of a run with
    variants (``out/NAME/summary.json``); returns the report.html paths."""
    if (out / "summary.json").is_file() or (out / "sweep.csv").is_file():
        return [_report_into(out, out)]
    return [_report_into(d, d) for d in sorted(out.iterdir()) if (d / "summary.json").is_file()]


def command(argv: Sequence[str]) -> int:
    from aquasim_py.outdir import refuse_foreign
    from aquasim_py.report import ReportError

    args = parser().parse_args(argv)
    directory = Path(args.directory)
    if not directory.is_dir():
        raise common.UsageError(f"{directory}: no such directory")
    try:
        if args.out is None:
            paths = reports_for(directory)
            if not paths:
                raise ReportError(f"{directory}: neither a run (summary.json) nor a sweep (sweep.csv) output directory")
        else:
            dest = Path(args.out)
            # never write over a user's files (the report has no --overwrite)
            refuse_foreign(dest, None, "--out", hint="give an empty or new directory")
            dest.mkdir(parents=True, exist_ok=True)
            paths = [_report_into(directory, dest)]
    except ReportError as e:
        raise common.UsageError(str(e)) from None
    for p in paths:
        print(f"report: {p}")
    return 0
