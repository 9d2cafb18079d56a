"""aquasim-py: discrete-event simulation of underwater acoustic sensor networks.

Run a scenario from Python with :func:`run_scenario` (one run, optionally one of the file's
``[variants.NAME]``) or :func:`run_variants` (every variant); both return
:class:`RunResult` objects (trace tables as DataFrames, metrics, the resolved scenario).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from aquasim_py._version import __version__

if TYPE_CHECKING:
    from aquasim_py.runner import RunResult, run_scenario, run_variants

__all__ = ["RunResult", "__version__", "run_scenario", "run_variants"]

_RUNNER = ("RunResult", "run_scenario", "run_variants")


def __getattr__(name: str) -> Any:
    # imported on first use: `import aquasim_py.kernel` (and every worker process) stays light
    if name in _RUNNER:
        from aquasim_py import runner

        return getattr(runner, name)
    raise AttributeError(f"module 'aquasim_py' has no attribute {name!r}")
