"""Schema models of the range-dependent part of ``[environment]`` (see :mod:`.ocean` for the
file format and the builder). A leaf module: :mod:`.schema` imports it.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

import annotated_types as at
from pydantic import BaseModel, ConfigDict, Field, model_validator

__all__ = [
    "OCEAN_KEYS",
    "PACKAGE_PREFIX",
    "BathymetrySpec",
    "FlatBathymetry",
    "GridBathymetry",
    "GridSSP",
    "PlaneBathymetry",
    "SeamountBathymetry",
    "Season",
    "SectionSSP",
    "SedimentSpec",
    "check_geographic",
]

# constraints as annotated-types markers, not Field(...): pydantic before 2.12 wrote a field's
# default into a shared Annotated[..., Field()] alias, so a later required field of the same
# alias silently took that default (BatterySpec.capacity_j = 10.0 from drift_interval_s);
# schema.py uses these too
PosFloat = Annotated[float, at.Gt(0.0)]
NonNegFloat = Annotated[float, at.Ge(0.0)]


class Strict(BaseModel):
    """The configuration of every section of :mod:`.schema` (a copy: this module is a leaf)."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, frozen=False)


#: the shelf-break front sample bundled with the package (tools/make_shelfbreak_sample.py)
PACKAGE_PREFIX = "package:"


class SectionSSP(Strict):
    """Profiles at distances along a horizontal line, linear between them."""

    model: Literal["section"]
    ranges_m: Annotated[list[float], Field(min_length=1)]
    depths_m: Annotated[list[float], Field(min_length=2)]
    speeds_mps: Annotated[list[list[PosFloat]], Field(min_length=1)]
    origin_m: Annotated[list[float], Field(min_length=2, max_length=2)] = Field(default_factory=lambda: [0.0, 0.0])
    azimuth_deg: float = Field(0.0, description="direction of the line, counter-clockwise from +x")

    @model_validator(mode="after")
    def _shape(self) -> SectionSSP:
        if len(self.speeds_mps) != len(self.ranges_m):
            raise ValueError(
                f"speeds_mps needs one profile per range ({len(self.ranges_m)}), got {len(self.speeds_mps)}"
            )
        for i, row in enumerate(self.speeds_mps):
            if len(row) != len(self.depths_m):
                raise ValueError(f"speeds_mps[{i}] has {len(row)} values for {len(self.depths_m)} depths_m")
        return self


class GridSSP(Strict):
    """A netCDF grid read with xarray: ``speed`` if named, else temperature / salinity (TEOS-10)."""

    model: Literal["grid"]
    file: str = Field(description="netCDF path relative to the scenario file, or package:NAME")
    speed: str | None = None
    temperature: str = "temperature"
    salinity: str = "salinity"
    x: str = "x"
    y: str = "y"
    depth: str = "depth"


class FlatBathymetry(Strict):
    model: Literal["flat"]
    depth_m: PosFloat


class PlaneBathymetry(Strict):
    model: Literal["plane"]
    depth_m: PosFloat = Field(description="depth at (x0_m, y0_m)")
    slope_x: float = 0.0
    slope_y: float = 0.0
    x0_m: float = 0.0
    y0_m: float = 0.0
    max_depth_m: PosFloat = 11000.0


class SeamountBathymetry(Strict):
    model: Literal["seamount"]
    base_m: PosFloat
    height_m: NonNegFloat
    width_m: PosFloat
    x0_m: float = 0.0
    y0_m: float = 0.0
    resolution_m: PosFloat = 50.0


class GridBathymetry(Strict):
    model: Literal["grid"]
    file: str = Field(description="netCDF path relative to the scenario file, or package:NAME")
    variable: str = "depth"
    x: str = "x"
    y: str = "y"


BathymetrySpec = Annotated[
    FlatBathymetry | PlaneBathymetry | SeamountBathymetry | GridBathymetry, Field(discriminator="model")
]


class SedimentSpec(Strict):
    """A fluid sediment half-space: a preset name, or its three values."""

    name: Literal["clay", "silt", "sand", "gravel"] | None = None
    sound_speed_mps: PosFloat | None = None
    density: PosFloat | None = None
    attenuation_db_per_wavelength: NonNegFloat | None = None

    @model_validator(mode="after")
    def _one_way(self) -> SedimentSpec:
        vals = (self.sound_speed_mps, self.density, self.attenuation_db_per_wavelength)
        if self.name is None and any(v is None for v in vals):
            raise ValueError(
                "give name (clay, silt, sand, gravel) or all of sound_speed_mps, density, attenuation_db_per_wavelength"
            )
        if self.name is not None and any(v is not None for v in vals):
            raise ValueError("give either name or the three values, not both")
        return self


#: the ``[environment]`` keys of a range-dependent environment, left out of the resolved scenario when unset
OCEAN_KEYS = ("bathymetry", "sediment", "origin", "woa", "gebco", "month", "season")

Season = Literal["winter", "spring", "summer", "autumn"]


def check_geographic(env: Any) -> None:
    """The rules of ``origin``, ``woa``, ``gebco``, ``month`` and ``season`` in ``[environment]``
    (ValueError naming the keys)."""
    files = env.woa is not None or env.gebco is not None
    if files and env.origin is None:
        raise ValueError("woa and gebco need origin = [latitude, longitude] (deg) of x = y = 0")
    if env.origin is not None:
        if not files:
            raise ValueError("origin places the files woa / gebco on the globe: give at least one of them")
        lat, lon = env.origin
        if not -90.0 < lat < 90.0:
            raise ValueError(f"origin: latitude {lat} must lie strictly between -90 and 90 deg")
        if not -360.0 <= lon <= 360.0:
            raise ValueError(f"origin: longitude {lon} must lie in [-360, 360] deg")
    if env.woa is not None and "sound_speed" in env.model_fields_set:
        raise ValueError("give sound_speed or woa (the sound speed from the World Ocean Atlas), not both")
    if env.gebco is not None and (env.bathymetry is not None or env.bottom_m is not None):
        raise ValueError("give gebco (the floor from a GEBCO / ETOPO grid) or bathymetry / bottom_m, not both")
    if env.month is not None and env.season is not None:
        raise ValueError("give month or season, not both")
    if (env.month is not None or env.season is not None) and env.woa is None:
        raise ValueError("month and season choose the period of the woa files: give woa")
