"""TOML scenario -> validated :class:`Scenario` -> built :class:`~aquasim_py.kernel.Simulation`.

One module per job:

- :mod:`~aquasim_py.scenario.schema`: the file format (strict pydantic models);
- :mod:`~aquasim_py.scenario.load`: reading TOML, ``--set`` overrides, ``[variants.NAME]``
  override sets, sweep grid keys (:func:`load`, :func:`load_dict`, :func:`resolve`);
- :mod:`~aquasim_py.scenario.validate`: checks across sections (positions inside the volume,
  protocol and mobility parameters);
- :mod:`~aquasim_py.scenario.build`: the simulation, sound-speed profile and channel
  configuration of a validated scenario (:func:`build`);
- :mod:`~aquasim_py.scenario.errors`: :class:`ScenarioError` (file, key path, problem).

Every user mistake raises :class:`ScenarioError` naming the file, the key path
(``nodes[1].count``) and the problem.
"""

from aquasim_py.scenario.build import (
    DEPRECATED_MOBILITY,
    MOBILITY_CLASSES,
    ScenarioDeprecationWarning,
    build,
    channel_config,
    make_ssp,
    mobility_class,
    placement_positions,
)
from aquasim_py.scenario.errors import ScenarioError, format_key_path
from aquasim_py.scenario.load import (
    VARIANT_KEY,
    Scenario,
    apply_override,
    load,
    load_dict,
    parse_key_path,
    parse_value,
    resolve,
)
from aquasim_py.scenario.validate import LIMITS, PLAUSIBLE, ScenarioWarning

__all__ = [
    "DEPRECATED_MOBILITY",
    "LIMITS",
    "MOBILITY_CLASSES",
    "PLAUSIBLE",
    "VARIANT_KEY",
    "Scenario",
    "ScenarioDeprecationWarning",
    "ScenarioError",
    "ScenarioWarning",
    "apply_override",
    "build",
    "channel_config",
    "format_key_path",
    "load",
    "load_dict",
    "make_ssp",
    "mobility_class",
    "parse_key_path",
    "parse_value",
    "placement_positions",
    "resolve",
]
