"""Compiled speed-ups, built with the package (setuptools reads everything else from pyproject.toml).

Each extension is optional: without a C compiler the install still succeeds and the package
runs its pure-Python reference path (the same results, slower; tests hold the two equal).
CI checks that all three were built (``.ci/run``, wheel lane).
"""

from setuptools import Extension, setup

# -ffp-contract=off: no fused multiply-adds, so every float expression rounds as its Python
# reference does (bit-identical traces whichever path runs)
_FLAGS = ["-O2", "-ffp-contract=off", "-fno-strict-aliasing"]

setup(
    ext_modules=[
        Extension("aquasim_py._fastcsv", ["aquasim_py/_fastcsv.c"], optional=True, extra_compile_args=_FLAGS),
        Extension(
            "aquasim_py._events",
            ["aquasim_py/_events.c"],
            depends=["aquasim_py/_events.h"],
            optional=True,
            extra_compile_args=_FLAGS,
        ),
        # queues its entries on _events' queue through that module's C interface (_events.h)
        Extension(
            "aquasim_py.channel._delivery",
            ["aquasim_py/channel/_delivery.c"],
            depends=["aquasim_py/_events.h"],
            optional=True,
            extra_compile_args=_FLAGS,
        ),
    ]
)
