"""The ``aquasim-py`` command: run a scenario (:mod:`~aquasim_py.cli.run`), or a sweep of it
(:mod:`~aquasim_py.cli.sweep`); both run through :func:`aquasim_py.run_scenario`.

User mistakes (bad scenario, bad variant, bad override, unwritable output) print one line
``error: FILE: KEY.PATH: problem`` on stderr and exit with status 2, before anything is
written. Outputs are staged in a hidden temporary directory next to the target and renamed
into place only when complete, so an interrupted or failed run leaves no half-written
directory (and an existing one untouched until the new one is ready); see
:mod:`aquasim_py.outdir` for what may be written where.

SIGTERM (what ``timeout``, systemd and SLURM send) is handled as SIGINT: the run stops, the
staging directory is removed, one line ``error: interrupted by SIGTERM (...)`` is printed and
the exit status is 128 + the signal number (143 for SIGTERM, 130 for SIGINT).
"""

from __future__ import annotations

import signal
import sys
import threading
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import Any

from aquasim_py.cli.common import EXIT_USAGE, Interrupted, UsageError
from aquasim_py.errors import ScenarioError

__all__ = ["EXIT_USAGE", "UsageError", "main"]


@contextmanager
def _one_line_warnings() -> Iterator[None]:
    """Scenario deprecations (e.g. an old mobility model name) and implausible values as one
    ``warning:`` line each, each line once in a command (a variants run validates its scenario
    once per variant, and the "default" filter's registry forgets what it showed whenever
    something changes the filters in between)."""
    from aquasim_py.errors import ScenarioDeprecationWarning, ScenarioWarning

    shown: set[str] = set()

    def show(message: Warning | str, category: type[Warning], *args: Any, **kwargs: Any) -> None:
        line = f"warning: {message}"
        if line not in shown:
            shown.add(line)
            print(line, file=sys.stderr)

    with warnings.catch_warnings():
        warnings.simplefilter("default", ScenarioDeprecationWarning)
        warnings.simplefilter("default", ScenarioWarning)  # implausible values: once per message
        warnings.showwarning = show
        yield


@contextmanager
def _interruptible() -> Iterator[None]:
    """SIGINT and SIGTERM raise :class:`Interrupted` in the main thread; once one has arrived
    further ones are ignored, so the clean-up on the way out is not itself interrupted. Each is
    noted in ``outdir.INTERRUPTIONS`` too, so an interruption whose exception is swallowed
    still keeps the outputs from being moved into place."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    import tempfile

    from aquasim_py.outdir import INTERRUPTIONS

    # tempfile finds the temporary directory on first use by writing and removing a probe file
    # of a bare random name there; an interruption raised between the two would leave it (seen
    # once in CI as a stray 8-letter name in TMPDIR after a SIGTERM): find it before handling
    tempfile.gettempdir()
    sigs = (signal.SIGINT, signal.SIGTERM)

    def handler(signum: int, frame: Any) -> None:
        for s in sigs:
            signal.signal(s, signal.SIG_IGN)
        exc = Interrupted(signum)
        INTERRUPTIONS.append(exc)
        raise exc

    old = {s: signal.signal(s, handler) for s in sigs}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        INTERRUPTIONS.clear()


_COMMANDS = ("sweep", "report", "arrivals", "reproduce")


def _help(rest: Sequence[str]) -> list[str]:
    """The argv that shows the help ``aquasim-py help [COMMAND]`` asks for."""
    if not rest or rest[0] == "help":
        return ["--help"]
    if rest[0] not in _COMMANDS:
        raise UsageError(f"help: no command {rest[0]!r} (commands: {', '.join(_COMMANDS)}; see aquasim-py --help)")
    return [rest[0], "--help"]


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``aquasim-py``; returns the exit status. Each subcommand's module is
    imported when it runs, so that ``--version`` and ``--help`` load no more than they need."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        if argv[:1] == ["help"]:  # "aquasim-py help [COMMAND]": that command's --help
            argv = _help(argv[1:])
        with _interruptible(), _one_line_warnings():
            if argv and argv[0] == "sweep":
                from aquasim_py.cli import sweep

                return sweep.command(argv[1:])
            if argv and argv[0] == "report":
                from aquasim_py.cli import report

                return report.command(argv[1:])
            if argv and argv[0] == "arrivals":
                from aquasim_py.cli import arrivals

                return arrivals.command(argv[1:])
            if argv and argv[0] == "modems":
                from aquasim_py.cli import modems

                return modems.command(argv[1:])
            if argv and argv[0] == "reproduce":
                from aquasim_py.cli import reproduce

                return reproduce.command(argv[1:])
            from aquasim_py.cli import run

            return run.command(argv)
    except (ScenarioError, UsageError) as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except SystemExit as e:  # argparse's --help / --version
        return int(e.code) if isinstance(e.code, int) else (0 if e.code is None else EXIT_USAGE)
    except KeyboardInterrupt as e:  # Interrupted, or a KeyboardInterrupt raised before the handler
        signum = e.signum if isinstance(e, Interrupted) else int(signal.SIGINT)
        detail = (e.detail if isinstance(e, Interrupted) else None) or "no output written"
        print(f"error: interrupted by {signal.Signals(signum).name} ({detail})", file=sys.stderr)
        return 128 + signum
