"""What the ``aquasim-py`` subcommands share: the one-line argument parser, option types and
common options, output directories, progress and table helpers."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

if TYPE_CHECKING:
    from aquasim_py.scenario import Scenario

EXIT_USAGE = 2


class UsageError(Exception):
    """A command-line mistake that is not about the scenario file."""


class Interrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM reached the command. ``detail``: what was kept (set on the way out)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum
        self.detail: str | None = None


def version_line() -> str:
    """``aquasim-py --version``: the package, Python and SimPy versions, and whether the optional
    compiled CSV writer (aquasim_py._fastcsv, built at install when a C compiler is there) is
    in use; without it the trace is written by its pure-Python reference, with the same bytes."""
    from importlib import import_module
    from importlib.metadata import version

    from aquasim_py._version import __version__

    try:  # the import the trace makes (aquasim_py.trace.csvfmt), without loading pandas for it
        import_module("aquasim_py._fastcsv")
        fast = "compiled (aquasim_py._fastcsv)"
    except ImportError:
        fast = "pure Python"
    return (
        f"aquasim-py {__version__} (Python {sys.version.split()[0]}, SimPy {version('simpy')}; "
        f"trace CSV writer: {fast})"
    )


class Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line, not usage + message
        raise UsageError(f"{message} (see {self.prog} --help)")


def positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {v}")
    return v


def seed(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {text!r}") from None
    if not 0 <= v < 2**63:
        raise argparse.ArgumentTypeError(f"expected an integer in [0, 2^63), got {v}")
    return v


def add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", metavar="SCENARIO.toml", help="scenario file")
    p.add_argument(
        "--out", metavar="DIR", help="output directory (default: [output] directory, else out/<scenario name>)"
    )
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="write into a non-empty directory that is not an aquasim-py output (only the files "
        "written are replaced; nothing else there is touched)",
    )
    p.add_argument("--seed", type=seed, metavar="N", help="override [simulation] seed")
    p.add_argument(
        "--set", action="append", default=[], metavar="KEY.PATH=VALUE", help="override any scenario value (repeatable)"
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar and no tables")


def add_metrics(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--metrics",
        action="append",
        metavar="PATTERN",
        help="the metrics to tabulate and plot: shell patterns, comma-separated or repeated "
        "(e.g. 'localization.*,*.rmse_m'); default every metric but the packet counts",
        type=lambda text: [x.strip() for x in text.split(",") if x.strip()],
    )


def metric_patterns(given: Sequence[Sequence[str]] | None) -> list[str] | None:
    """``--metrics`` as one list of patterns (None when not given)."""
    return [x for group in given for x in group] if given else None


def output_dir(sc: Scenario, out: str | None, suffix: str = "") -> tuple[Path, str]:
    """The output directory and the key an error about it names (``--out`` or the file's)."""
    if out:
        return Path(out), "--out"
    if sc.output.directory:
        return Path(sc.output.directory + suffix), "output.directory"
    return Path("out") / f"{sc.name}{suffix}", "output.directory"


def _progress_wanted(quiet: bool) -> bool:
    return not quiet and sys.stderr.isatty()
