"""Channel physics (profiles, eigenrays, losses, link geometry; plain numpy/scipy, no SimPy) and
the SimPy channel (:mod:`.acoustic`, imported by the kernel, not here)."""

from .config import ChannelConfig, LossModel, no_snr, physical_snr
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
    "ChannelConfig",
    "Constant",
    "Eigenray",
    "Isogradient",
    "Layered",
    "LossModel",
    "Munk",
    "PathKind",
    "SoundSpeedProfile",
    "eigenray",
    "from_ctd",
    "mackenzie",
    "no_snr",
    "physical_snr",
    "reflected_eigenray",
    "straight_line_time",
    "travel_time",
    "travel_time_gradient",
    "why_no_path",
]
