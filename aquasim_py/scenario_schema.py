"""Kept so that ``from aquasim_py.scenario_schema import ...`` still works: the models live in
:mod:`aquasim_py.scenario.schema`."""

from aquasim_py.scenario.schema import *  # noqa: F403
from aquasim_py.scenario.schema import __all__  # noqa: F401
