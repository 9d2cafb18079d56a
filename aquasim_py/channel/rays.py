"""Result types shared by the ray tracers."""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np
from numpy.typing import NDArray

__all__ = ["Eigenray", "PathKind"]


class PathKind(IntEnum):
    """Which path an arrival took."""

    NONE = -1  #: no eigenray (shadow zone, or the ray would leave the water)
    DIRECT = 0
    SURFACE = 1  #: one reflection off the surface (z = 0)
    BOTTOM = 2  #: one reflection off the bottom


@dataclass(frozen=True)
class Eigenray:
    """Eigenrays between broadcast arrays of sources and destinations (all fields shape (...)).

    Angles are grazing angles in radians measured from the horizontal, positive pointing
    down (towards increasing depth). ``turning_depth`` is NaN when the ray does not turn
    between its end points (Ramezani et al., eqs 21-22).
    """

    time: NDArray[np.float64]  #: travel time, s
    length: NDArray[np.float64]  #: arc length along the ray, m (eq 19)
    launch_angle: NDArray[np.float64]  #: at the source, rad
    arrival_angle: NDArray[np.float64]  #: at the destination, rad
    turning_depth: NDArray[np.float64]  #: m, NaN if none
    path: NDArray[np.int8]  #: PathKind codes
