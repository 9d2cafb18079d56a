"""Ocean samples shipped with the package (package data; no download at run time).

* ``shelfbreak``: an idealised summer shelf-break front over a continental slope in the Middle
  Atlantic Bight (temperature, salinity, bathymetry on an across-shelf section), made by
  ``tools/make_shelfbreak_sample.py`` from published climatological values (its docstring cites
  them). Read it with :func:`shelfbreak` or in a scenario as ``file = "package:shelfbreak"``.
* ``woa23_t08``, ``woa23_s08``, ``gebco``: synthetic files in the formats of the World Ocean
  Atlas 2023 (August temperature and salinity, 1/4 degree) and of a GEBCO grid subset (15 arc
  seconds) over a continental slope near 40 N, 70 W, made by ``tools/make_geographic_sample.py``
  (its docstring says what they hold; no WOA or GEBCO data is shipped). In a scenario:
  ``woa = ["package:woa23_t08", "package:woa23_s08"]``, ``gebco = "package:gebco"``,
  ``origin = [40.0, -70.0]``.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any

__all__ = ["SAMPLES", "sample_path", "shelfbreak"]

SAMPLES = {
    "shelfbreak": "shelfbreak.nc",
    "woa23_t08": "woa23_sample_t08.nc",
    "woa23_s08": "woa23_sample_s08.nc",
    "gebco": "gebco_sample.nc",
}


def sample_path(name: str) -> Path:
    """The file of a bundled sample (KeyError naming the samples if there is none)."""
    if name not in SAMPLES:
        raise KeyError(f"no bundled sample {name!r} (available: {', '.join(sorted(SAMPLES))})")
    return Path(str(resources.files(__name__).joinpath(SAMPLES[name])))


def shelfbreak() -> Any:
    """The shelf-break sample as an :class:`~aquasim_py.channel.environment.Environment`:
    TEOS-10 sound speed from its temperature / salinity, its bathymetry, a sandy bottom."""
    from ..bathymetry import SEDIMENTS, GriddedBathymetry
    from ..environment import Environment
    from ..fields import GriddedField

    path = sample_path("shelfbreak")
    return Environment(
        GriddedField.from_netcdf(path), GriddedBathymetry.from_netcdf(path, "bathymetry"), SEDIMENTS["sand"]
    )
