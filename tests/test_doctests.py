"""The ``>>>`` examples in the public API's docstrings run, and print what they say they print.

The API reference shows these examples (docs/reference/); each module listed here must hold
at least one, so that an example removed or renamed away is noticed. Paths in the examples are
relative to the repository's root, as in the tutorials.
"""

from __future__ import annotations

import doctest
import importlib
import io
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

MODULES = [
    "aquasim_py.runner",  # run_scenario
    "aquasim_py.channel.raytrace",  # travel_time, eigenray
    "aquasim_py.estimation.lsq",  # multilaterate
    "aquasim_py.estimation.bounds",  # crb_trace
]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)
    module = importlib.import_module(name)
    tests = [t for t in doctest.DocTestFinder().find(module) if t.examples]
    assert tests, f"{name} has no >>> examples"
    report = io.StringIO()
    runner = doctest.DocTestRunner(optionflags=doctest.NORMALIZE_WHITESPACE)
    for test in tests:
        runner.run(test, out=report.write)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, report.getvalue()
    assert result.attempted >= 3
