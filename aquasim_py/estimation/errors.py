"""Exceptions raised by the estimators when the input cannot determine an answer.

Every estimator in :mod:`aquasim_py.estimation` raises one of these instead of returning NaN,
so a protocol can catch them (e.g. wait for more measurements) rather than propagate garbage.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "DegenerateGeometryError",
    "EstimationError",
    "InsufficientMeasurementsError",
    "SingularMatrixError",
]


class EstimationError(ValueError):
    """Base class: the estimation problem as posed has no well-defined answer."""


class DegenerateGeometryError(EstimationError):
    """The anchors' geometry cannot fix the position (collinear / coplanar anchors, a target on
    the anchors' plane, a rank-deficient Jacobian at the solution)."""


class InsufficientMeasurementsError(DegenerateGeometryError):
    """Fewer independent measurements than unknowns."""


class SingularMatrixError(EstimationError, np.linalg.LinAlgError):
    """A covariance, innovation or information matrix is singular or not positive definite."""
