"""Small dense linear-algebra helpers shared by the estimators (Cholesky with clear errors)."""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
from numpy.typing import ArrayLike, NDArray

from .errors import SingularMatrixError

__all__ = ["cho_factor", "cho_solve", "spd_inverse", "symmetrize"]


def symmetrize(A: NDArray[np.float64]) -> NDArray[np.float64]:
    """(A + A^T) / 2 over the last two axes: round-off makes updated covariances drift asymmetric."""
    return 0.5 * (A + np.swapaxes(A, -1, -2))


def cho_factor(S: ArrayLike, what: str = "matrix") -> tuple[NDArray[np.float64], bool]:
    """Cholesky factor of a symmetric positive-definite matrix; SingularMatrixError otherwise."""
    S = np.asarray(S, dtype=float)
    if not np.all(np.isfinite(S)):
        raise SingularMatrixError(f"{what} has non-finite entries")
    try:
        return sla.cho_factor(S, lower=True, check_finite=False)
    except np.linalg.LinAlgError as exc:
        raise SingularMatrixError(f"{what} is not positive definite: {exc}") from None


def cho_solve(c: tuple[NDArray[np.float64], bool], b: ArrayLike) -> NDArray[np.float64]:
    return sla.cho_solve(c, np.asarray(b, dtype=float), check_finite=False)


def spd_inverse(A: ArrayLike, what: str = "matrix") -> NDArray[np.float64]:
    """Inverse of a symmetric positive-definite matrix (..., n, n), batched over leading axes."""
    A = np.asarray(A, dtype=float)
    if not np.all(np.isfinite(A)):
        raise SingularMatrixError(f"{what} has non-finite entries")
    try:
        L = np.linalg.cholesky(A)
    except np.linalg.LinAlgError:
        raise SingularMatrixError(f"{what} is not positive definite") from None
    n = A.shape[-1]
    eye = np.broadcast_to(np.eye(n), A.shape)
    # numpy's cholesky does not reject a numerically singular matrix: check the pivots
    d = np.diagonal(L, axis1=-2, axis2=-1)
    if np.any(d <= np.finfo(float).eps ** 0.5 * np.sqrt(np.max(np.abs(np.diagonal(A, axis1=-2, axis2=-1)), axis=-1, keepdims=True))):
        raise SingularMatrixError(f"{what} is numerically singular")
    Linv = np.linalg.solve(L, eye)
    return symmetrize(np.swapaxes(Linv, -1, -2) @ Linv)
