"""Small dense linear-algebra helpers shared by the estimators (Cholesky with clear errors)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import SingularMatrixError

__all__ = ["cho_factor", "cho_solve", "spd_inverse", "symmetrize"]


def symmetrize(A: NDArray[np.float64]) -> NDArray[np.float64]:
    """(A + A^T) / 2 over the last two axes: round-off makes updated covariances drift asymmetric."""
    return 0.5 * (A + np.swapaxes(A, -1, -2))


def cho_factor(S: ArrayLike, what: str = "matrix") -> tuple[NDArray[np.float64], bool]:
    """Cholesky factor of a symmetric positive-definite matrix; SingularMatrixError otherwise."""
    import scipy.linalg as sla

    S = np.asarray(S, dtype=float)
    if not np.all(np.isfinite(S)):
        raise SingularMatrixError(f"{what} has non-finite entries")
    try:
        return sla.cho_factor(S, lower=True, check_finite=False)
    except np.linalg.LinAlgError as exc:
        raise SingularMatrixError(f"{what} is not positive definite: {exc}") from None


def cho_solve(c: tuple[NDArray[np.float64], bool], b: ArrayLike) -> NDArray[np.float64]:
    import scipy.linalg as sla

    return sla.cho_solve(c, np.asarray(b, dtype=float), check_finite=False)


def spd_inverse(A: ArrayLike, what: str = "matrix") -> NDArray[np.float64]:
    """Inverse of a symmetric positive-definite matrix (..., n, n), batched over leading axes.

    The matrix is first scaled to unit diagonal, so mixed units (m vs m/s in a PCRB) do not
    count as ill-conditioning; SingularMatrixError if the scaled matrix is numerically singular.
    """
    A = np.asarray(A, dtype=float)
    if not np.all(np.isfinite(A)):
        raise SingularMatrixError(f"{what} has non-finite entries")
    d = np.diagonal(A, axis1=-2, axis2=-1)
    if np.any(d <= 0):
        raise SingularMatrixError(f"{what} has a non-positive diagonal entry")
    s = 1.0 / np.sqrt(d)
    As = A * s[..., :, None] * s[..., None, :]
    try:
        L = np.linalg.cholesky(As)
    except np.linalg.LinAlgError:
        raise SingularMatrixError(f"{what} is not positive definite") from None
    # numpy's cholesky does not reject a numerically singular matrix: check the pivots
    if np.any(np.diagonal(L, axis1=-2, axis2=-1) <= np.sqrt(np.finfo(float).eps)):
        raise SingularMatrixError(f"{what} is numerically singular")
    n = A.shape[-1]
    Linv = np.linalg.solve(L, np.broadcast_to(np.eye(n), A.shape))
    inv = np.swapaxes(Linv, -1, -2) @ Linv
    return symmetrize(inv * s[..., :, None] * s[..., None, :])
