"""One-step posterior Cramer-Rao bound recursion (Tichavsky et al. 1998) for a linear-Gaussian
motion model, and PCRLB-based sensor selection (MSWPF eqs 29-36):

    J_{k+1} = (Q + F J_k^-1 F^T)^-1 + J^D_{k+1},   J^D = sum over selected sensors of E[I_s(x)]

with the measurement information of each candidate estimated over (predicted) particles.
Selection maximizes det J_{k+1} over all subsets of Ns candidates (eq 36, exhaustive). The
batch recursion over a whole trajectory is :func:`aquasim_py.estimation.bounds.pcrb_information`.
"""

from __future__ import annotations

import itertools

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._linalg import spd_inverse, symmetrize

__all__ = ["best_subset", "particle_information", "pcrlb_step", "predicted_information", "subset_determinants"]

Array = NDArray[np.float64]


def predicted_information(J: ArrayLike, F: ArrayLike, Q: ArrayLike) -> Array:
    """Prior information of the next step, (Q + F J^-1 F^T)^-1 (the J^P part of eq 32)."""
    F = np.asarray(F, dtype=float)
    Jinv = spd_inverse(np.asarray(J, dtype=float), "posterior information J_k")
    return spd_inverse(np.asarray(Q, dtype=float) + F @ Jinv @ F.T, "predicted covariance Q + F J^-1 F^T")


def pcrlb_step(J: ArrayLike, F: ArrayLike, Q: ArrayLike, info: ArrayLike) -> Array:
    """J_{k+1} = (Q + F J_k^-1 F^T)^-1 + info (eqs 32-34)."""
    return symmetrize(predicted_information(J, F, Q) + np.asarray(info, dtype=float))


def particle_information(grad: ArrayLike, scale: ArrayLike, index: ArrayLike, n: int) -> Array:
    """E[scale * grad grad^T] over equally weighted particles, embedded in the n x n state FIM.

    grad (..., N, d): dh/d(state entries ``index``) per particle; scale (..., N): the Fisher
    information of the measurement about h (e.g. ``quantized_fisher_scale``). Returns (..., n, n).
    """
    G = np.asarray(grad, dtype=float)
    s = np.asarray(scale, dtype=float)
    blk = np.einsum("...i,...ia,...ib->...ab", s, G, G) / G.shape[-2]
    idx = np.asarray(index, dtype=int)
    out = np.zeros(G.shape[:-2] + (n, n))
    out[..., idx[:, None], idx[None, :]] = blk
    return out


def subset_determinants(J_prior: ArrayLike, infos: ArrayLike, k: int) -> tuple[NDArray[np.intp], Array]:
    """Every k-subset of the candidates (rows of ``infos`` (C, n, n)) and det(J_prior + sum of
    its infos), vectorized over subsets: (subsets (m, k) in lexicographic order, dets (m,))."""
    infos = np.asarray(infos, dtype=float)
    C = infos.shape[0]
    if not 0 < k <= C:
        raise ValueError(f"need 0 < k <= {C} candidates, got k = {k}")
    subs = np.array(list(itertools.combinations(range(C), k)), dtype=np.intp)
    J = np.asarray(J_prior, dtype=float) + infos[subs].sum(axis=1)
    return subs, np.linalg.det(J)


def best_subset(J_prior: ArrayLike, infos: ArrayLike, k: int) -> NDArray[np.intp]:
    """Indices of the k candidates minimizing the PCRLB, i.e. maximizing det J (eq 36); all
    candidates if there are at most k. Ties go to the lexicographically first subset."""
    C = np.asarray(infos).shape[0]
    if k >= C:
        return np.arange(C, dtype=np.intp)
    subs, dets = subset_determinants(J_prior, infos, k)
    return subs[int(np.argmax(dets))]
