"""An ocean environment: a sound-speed field, a sea floor and its sediment.

``Environment(field, bathymetry, bottom)``: c(x, y, z) (:mod:`.fields`), depth(x, y)
(:mod:`.bathymetry`, ``None`` = no sea floor modelled) and the sediment whose Rayleigh
reflection loss each bottom bounce pays (:class:`~.bathymetry.FluidBottom`). The surface is a
flat pressure-release boundary (reflection coefficient -1, no loss).

A range-independent environment (one profile, flat or no floor) is :attr:`range_independent`;
:meth:`profile` then gives the depth profile the exact layered solvers take
(:func:`aquasim_py.channel.travel_time`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .bathymetry import SEDIMENTS, Bathymetry, Flat, FluidBottom
from .fields import DepthProfile, SoundSpeedField
from .ssp import Layered, SoundSpeedProfile

__all__ = ["Environment"]


@dataclass(frozen=True)
class Environment:
    """A sound-speed field over a sea floor of one sediment type."""

    field: SoundSpeedField
    bathymetry: Bathymetry | None = None
    bottom: FluidBottom = SEDIMENTS["sand"]

    def __post_init__(self) -> None:
        if not isinstance(self.field, SoundSpeedField):
            raise TypeError(f"Environment: field must be a SoundSpeedField, got {type(self.field).__name__}")
        if self.bathymetry is not None and not isinstance(self.bathymetry, Bathymetry):
            raise TypeError(f"Environment: bathymetry must be a Bathymetry, got {type(self.bathymetry).__name__}")

    @classmethod
    def from_profile(cls, profile: SoundSpeedProfile, bottom: FluidBottom | None = None) -> Environment:
        """The range-independent environment of a depth profile (its ``bottom`` a flat floor)."""
        bathy = Flat(profile.bottom) if profile.bottom is not None else None
        return cls(DepthProfile(profile), bathy, bottom if bottom is not None else SEDIMENTS["sand"])

    @property
    def range_independent(self) -> bool:
        """One profile everywhere and a flat floor (or none): today's exact solvers apply."""
        return self.field.depth_only and (self.bathymetry is None or self.bathymetry.is_flat)

    def profile(self) -> SoundSpeedProfile:
        """The depth profile (with its flat floor) of a range-independent environment."""
        if not self.range_independent:
            raise ValueError("Environment.profile: the environment is range-dependent")
        bottom = None if self.bathymetry is None else self.bathymetry.max_depth()
        if isinstance(self.field, DepthProfile):
            p = self.field.profile
            if p.bottom == bottom:
                return p
            lay = p.to_layered()
            return Layered(lay.depths, lay.speeds, bottom=bottom)
        cols = self.field.columns(np.zeros(1), np.zeros(1))[0]
        return Layered(self.field.depths, cols, bottom=bottom)

    def speed(self, x: ArrayLike, y: ArrayLike, z: ArrayLike) -> NDArray[np.float64]:
        """Sound speed (m/s) at (x, y, z)."""
        return self.field.speed(x, y, z)

    def depth(self, x: ArrayLike, y: ArrayLike) -> NDArray[np.float64]:
        """Sea-floor depth (m) at (x, y); +inf where no floor is modelled."""
        if self.bathymetry is None:
            return np.full(np.broadcast(np.asarray(x), np.asarray(y)).shape, np.inf)
        return self.bathymetry.depth(x, y)
