"""``aquasim-py report DIR``: plots and ``report.html`` for a run's or a sweep's output directory."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from aquasim_py.cli import common

EXAMPLES = """examples:
  aquasim-py report out/beacon                 # a run: map, errors, sync, CDF, packets
  aquasim-py report out/itmtl                  # every variant's report, and the variants side by side
  aquasim-py report out/itmtl/wsc              # one variant of a run with variants
  aquasim-py report out/ramezani_localization_sweep-sweep           # a sweep: a line per other grid value
  aquasim-py report out/ramezani_localization_sweep-sweep --metrics '*.rmse_m,*.sqrt_mean_crb_m'
  aquasim-py report out/itmtl --out /tmp/rep   # write the report elsewhere
  aquasim-py report out/slope/itmtl --link 4,6 # a range-dependent run: the rays of link 4 -> 6
"""


def parser() -> argparse.ArgumentParser:
    p = common.Parser(
        prog="aquasim-py report",
        description="Draw PNG plots and one self-contained report.html (images embedded) from the "
        "output directory of a run (summary.json + trace tables), of a run with variants (variants.csv) "
        "or of a sweep (sweep.csv).",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("directory", metavar="DIR", help="a run's or a sweep's output directory")
    p.add_argument("--out", metavar="DIR", help="where to write the plots and report.html (default: DIR)")
    common.add_metrics(p)
    p.add_argument(
        "--link",
        metavar="SRC,DST",
        type=_link,
        help="a range-dependent run: the link whose rays environment.png draws (default: the most heard "
        "link without a direct path, else the most heard)",
    )
    return p


def _link(text: str) -> tuple[int, int]:
    try:
        a, b = (int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected two node ids SRC,DST, got {text!r}") from None
    if a == b:
        raise argparse.ArgumentTypeError(f"{text!r}: a link joins two nodes, not node {a} with itself")
    if a < 0 or b < 0:
        raise argparse.ArgumentTypeError(f"{text!r}: node ids are >= 0")
    return a, b


def _check_link(directory: Path, link: tuple[int, int]) -> None:
    """``--link`` names nodes of every run it would draw, and each is range-dependent (only
    those have an environment.png to draw a link in): checked before any report is written."""
    from aquasim_py.reporting.environment import link_problem

    runs = [directory] if (directory / "summary.json").is_file() else []
    runs += [d for d in sorted(directory.iterdir()) if (d / "summary.json").is_file()] if not runs else []
    if not runs:
        raise common.UsageError(
            f"--link {link[0]},{link[1]}: {directory} is not a run's output (a sweep has no link plot)"
        )
    for run in runs:
        problem = link_problem(run, link)
        if problem is not None:
            raise common.UsageError(f"--link {link[0]},{link[1]}: {run}: {problem}")


def _report_into(
    directory: Path, out: Path, metrics: Sequence[str] | None = None, link: tuple[int, int] | None = None
) -> Path:
    """Write the report of ``directory`` into ``out`` and list its files in ``out``'s manifest."""
    from aquasim_py.outdir import record_files
    from aquasim_py.reporting.report import write_report

    html = write_report(directory, out, metrics, link)
    record_files(out, sorted(p.name for p in out.iterdir() if p.suffix == ".png" or p == html))
    return html


def reports_for(out: Path, metrics: Sequence[str] | None = None, link: tuple[int, int] | None = None) -> list[Path]:
    """Report every run under ``out``: the run or sweep itself, or for a run with variants
    each variant directory (``out/NAME/summary.json``) and then the cross-variant report of
    ``out``; returns the report.html paths."""
    if (out / "summary.json").is_file() or (out / "sweep.csv").is_file():
        return [_report_into(out, out, metrics, link)]
    paths = [_report_into(d, d, metrics, link) for d in sorted(out.iterdir()) if (d / "summary.json").is_file()]
    if (out / "variants.csv").is_file():
        paths.append(_report_into(out, out, metrics))
    return paths


def command(argv: Sequence[str]) -> int:
    args = parser().parse_args(argv)  # --help exits here
    from aquasim_py.outdir import refuse_foreign
    from aquasim_py.reporting.report import ReportError

    directory = Path(args.directory)
    if not directory.is_dir():
        raise common.UsageError(f"{directory}: no such directory")
    if args.link is not None:
        _check_link(directory, args.link)
    try:
        metrics = common.metric_patterns(args.metrics)
        if args.out is None:
            paths = reports_for(directory, metrics, args.link)
            if not paths:
                raise ReportError(
                    f"{directory}: neither a run (summary.json), a variants run (variants.csv) nor a sweep "
                    "(sweep.csv) output directory"
                )
        else:
            dest = Path(args.out)
            # never write over a user's files (the report has no --overwrite)
            refuse_foreign(dest, None, "--out", hint="give an empty or new directory")
            dest.mkdir(parents=True, exist_ok=True)
            paths = [_report_into(directory, dest, metrics, args.link)]
    except ReportError as e:
        raise common.UsageError(str(e)) from None
    for p in paths:
        print(f"report: {p}")
    return 0
