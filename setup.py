"""The optional compiled CSV writer, built with the package (setuptools reads everything else
from pyproject.toml).

``aquasim_py._fastcsv`` formats trace rows as CSV and moves row tuples into the trace's typed
columns in C; its pure-Python reference is ``aquasim_py/trace/csvfmt.py`` and ``Table``'s batch
append, which give the same bytes (tests/test_trace_csv.py holds the two equal, field by field,
against ``repr`` and pandas). Without a C compiler the install still succeeds and the reference
runs (``aquasim-py --version`` says which); CI runs the suite both ways (``.ci/run``).
"""

from setuptools import Extension, setup

# -ffp-contract=off: no fused multiply-adds (the writer only formats floats, but a compiler
# default must not change any float it touches)
_FLAGS = ["-O2", "-ffp-contract=off", "-fno-strict-aliasing"]

setup(
    ext_modules=[
        Extension("aquasim_py._fastcsv", ["aquasim_py/_fastcsv.c"], optional=True, extra_compile_args=_FLAGS),
    ]
)
