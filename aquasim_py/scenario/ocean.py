"""The range-dependent part of ``[environment]``: bathymetry, sediment, sound-speed sections and
grids (schema models), and :func:`make_environment`, the scenario's
:class:`aquasim_py.channel.environment.Environment`.

```toml
[environment.sound_speed]          # profiles along a line (a section across a front)
model = "section"
ranges_m = [0.0, 10000.0]          # distances along the line from origin_m at azimuth_deg
depths_m = [0.0, 50.0, 200.0]
speeds_mps = [[1500.0, 1495.0, 1490.0], [1510.0, 1500.0, 1491.0]]

[environment.sound_speed]          # or a netCDF grid (speed, or temperature + salinity via TEOS-10)
model = "grid"
file = "shelfbreak.nc"             # relative to the scenario file; "package:shelfbreak" = the bundled sample

[environment.bathymetry]           # flat | plane | seamount | grid
model = "plane"
depth_m = 200.0
slope_x = 0.03

[environment.sediment]             # a preset (clay, silt, sand, gravel) or the three values
name = "sand"

[environment]                      # or the ocean from standard files, placed on the globe
origin = [40.0, -70.0]             # latitude, longitude (deg) of x = y = 0; x east, y north (m)
woa = ["woa23_decav_t08_04.nc", "woa23_decav_s08_04.nc"]   # World Ocean Atlas t_an / s_an
gebco = "gebco_2024_n40.3_s39.8_w-70.3_e-69.7.nc"          # GEBCO elevation (or ETOPO z)
month = 8                          # or season = "summer"; neither: the files' one period
```

A scenario without these keys resolves exactly as before (the keys are left out of the resolved
scenario when unset).
"""

from __future__ import annotations

from typing import Any

from aquasim_py.scenario.errors import ScenarioError
from aquasim_py.scenario.ocean_schema import (
    PACKAGE_PREFIX,
    FlatBathymetry,
    GridSSP,
    PlaneBathymetry,
    SeamountBathymetry,
    SectionSSP,
)

__all__ = ["ARRIVAL_KEYS", "centre_profile", "depth_profile", "local_frame", "make_environment", "range_dependent"]

#: the ``[channel]`` keys of a range-dependent channel (aquasim_py.channel.arrival_links)
ARRIVAL_KEYS = ("max_bounces", "detection_threshold_db", "direct_only", "follow_radius_m")


def range_dependent(sc: Any) -> bool:
    """The scenario's environment has a section / grid / WOA sound speed or a bathymetry."""
    env = sc.environment
    return not depth_profile(sc) or env.bathymetry is not None or env.gebco is not None


def depth_profile(sc: Any) -> bool:
    """The scenario's sound speed is a depth profile (:func:`aquasim_py.scenario.build.make_ssp`):
    not a section, a grid or the World Ocean Atlas."""
    env = sc.environment
    return not isinstance(env.sound_speed, (SectionSSP, GridSSP)) and env.woa is None


def local_frame(sc: Any) -> Any:
    """The :class:`~aquasim_py.channel.geographic.LocalFrame` of a scenario with an ``origin``, else None."""
    if sc.environment.origin is None:
        return None
    from aquasim_py.channel.geographic import LocalFrame

    return LocalFrame(*sc.environment.origin)


def _files(sc: Any, key: str) -> tuple[Any, Any, Any]:
    """The data path(s) of ``environment.<key>``, the local frame and the volume's footprint."""
    names = getattr(sc.environment, key)
    paths = [_data_path(sc, f"environment.{key}", n) for n in ([names] if isinstance(names, str) else names)]
    frame = local_frame(sc)
    vol = sc.environment.volume
    try:
        box = frame.footprint(vol.lo, vol.hi)
    except ImportError as e:
        raise ScenarioError(sc.path, "environment.origin", str(e)) from None
    return paths, frame, box


def _data_path(sc: Any, key: str, name: str) -> Any:
    from pathlib import Path

    if name.startswith(PACKAGE_PREFIX):
        from aquasim_py.channel.data import sample_path

        try:
            return sample_path(name[len(PACKAGE_PREFIX) :])
        except KeyError as e:
            raise ScenarioError(sc.path, key, str(e)) from None
    p = Path(name)
    if not p.is_absolute() and sc.path is not None:
        p = Path(sc.path).parent / p
    if not p.is_file():
        raise ScenarioError(sc.path, key, f"no such file: {p}")
    return p


def _field(sc: Any, profile: Any) -> Any:
    from aquasim_py.channel import fields

    spec = sc.environment.sound_speed
    key = "environment.sound_speed"
    if sc.environment.woa is not None:
        from aquasim_py.channel.oceanfiles import read_woa

        paths, frame, box = _files(sc, "woa")
        try:
            return read_woa(paths, frame, month=sc.environment.month, season=sc.environment.season, box=box)
        except (ValueError, KeyError, OSError, ImportError) as e:
            raise ScenarioError(sc.path, "environment.woa", str(e)) from None
    try:
        if isinstance(spec, SectionSSP):
            return fields.RangeProfiles(
                spec.ranges_m, spec.depths_m, spec.speeds_mps, (spec.origin_m[0], spec.origin_m[1]), spec.azimuth_deg
            )
        if isinstance(spec, GridSSP):
            path = _data_path(sc, f"{key}.file", spec.file)
            return fields.GriddedField.from_netcdf(
                path,
                x=spec.x,
                y=spec.y,
                depth=spec.depth,
                speed=spec.speed,
                temperature=spec.temperature,
                salinity=spec.salinity,
            )
    except (ValueError, KeyError, OSError) as e:
        raise ScenarioError(sc.path, key, str(e)) from None
    except ImportError as e:
        raise ScenarioError(sc.path, key, str(e)) from None
    return fields.DepthProfile(profile)


def _bathymetry(sc: Any) -> Any:
    from aquasim_py.channel import bathymetry as b

    spec = sc.environment.bathymetry
    key = "environment.bathymetry"
    if sc.environment.gebco is not None:
        from aquasim_py.channel.oceanfiles import read_gebco

        paths, frame, box = _files(sc, "gebco")
        try:
            return read_gebco(paths[0], frame, box=box)
        except (ValueError, KeyError, OSError, ImportError) as e:
            raise ScenarioError(sc.path, "environment.gebco", str(e)) from None
    try:
        if spec is None:
            return None if sc.environment.bottom_m is None else b.Flat(sc.environment.bottom_m)
        if isinstance(spec, FlatBathymetry):
            return b.Flat(spec.depth_m)
        if isinstance(spec, PlaneBathymetry):
            return b.Plane(spec.depth_m, spec.slope_x, spec.slope_y, spec.x0_m, spec.y0_m, spec.max_depth_m)
        if isinstance(spec, SeamountBathymetry):
            return b.Seamount(spec.base_m, spec.height_m, spec.width_m, spec.x0_m, spec.y0_m, spec.resolution_m)
        path = _data_path(sc, f"{key}.file", spec.file)
        return b.GriddedBathymetry.from_netcdf(path, spec.variable, spec.x, spec.y)
    except (ValueError, KeyError, OSError, ImportError) as e:
        raise ScenarioError(sc.path, key, str(e)) from None


def make_environment(sc: Any, profile: Any = None) -> Any:
    """The scenario's :class:`~aquasim_py.channel.environment.Environment`; ``profile`` is the
    scenario's depth profile (:func:`aquasim_py.scenario.build.make_ssp`) where the sound speed
    is one (constant, isogradient, layered, munk, ctd)."""
    from aquasim_py.channel.bathymetry import SEDIMENTS, FluidBottom
    from aquasim_py.channel.environment import Environment

    sed = sc.environment.sediment
    if sed is None:
        bottom = SEDIMENTS["sand"]
    elif sed.name is not None:
        bottom = SEDIMENTS[sed.name]
    else:
        bottom = FluidBottom(sed.sound_speed_mps, sed.density, sed.attenuation_db_per_wavelength)
    return Environment(_field(sc, profile), _bathymetry(sc), bottom)


def centre_profile(sc: Any) -> Any:
    """The depth profile of a range-dependent field at the volume's centre (what the scenario
    checks of the sound speed look at)."""
    from aquasim_py.channel.ssp import Layered

    field = _field(sc, None)
    lo, hi = sc.environment.volume.lo, sc.environment.volume.hi
    col = field.columns(0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]))
    return Layered(field.depths, col, bottom=sc.environment.bottom_m)
