"""Channel physics (profiles, eigenrays, losses; plain numpy/scipy) and the SimPy channel."""

from .rays import Eigenray, PathKind
from .raytrace import (
    eigenray,
    reflected_eigenray,
    straight_line_time,
    travel_time,
    travel_time_gradient,
    why_no_path,
)
from .ssp import Constant, Isogradient, Layered, Munk, SoundSpeedProfile, from_ctd, mackenzie

__all__ = [
    "Constant",
    "Eigenray",
    "Isogradient",
    "Layered",
    "Munk",
    "PathKind",
    "SoundSpeedProfile",
    "eigenray",
    "from_ctd",
    "mackenzie",
    "reflected_eigenray",
    "straight_line_time",
    "travel_time",
    "travel_time_gradient",
    "why_no_path",
]
