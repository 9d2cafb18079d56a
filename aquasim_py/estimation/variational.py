"""Spatial-temporal variational filtering (STVF) maths: Hu, Sun, Luo, Zhou, Guo, Sensors 2018.

Pure numpy, no SimPy. Notation follows the paper (see docs/stvf.md):

- State ``s = [x, vx, y, vy]`` (m, m/s) in the unknown node's depth plane; ``A`` picks (x, y).
- Gaussians are ``N(mean, precision)``; the Gamma is ``Gam(shape, rate)``.
- Measurements ``z`` are one-way delays in **milliseconds** (``z_scale = 1e3`` ms per s), so the
  Table-1 prior ``Gam(3, 200)`` on the noise precision means a noise std of about 8 ms.
- ``s ~ N(mu, lam)``, ``mu ~ N(mu_prev, Lambda)``, ``lam ~ Wishart(W, n)`` (eq 3);
  ``z_i ~ N(z_scale * r_i(s) / v, zeta)``, ``v ~ N(v0, V)``, ``zeta ~ Gam(alpha, beta)`` (eq 5).

The functions: variational prediction (eq 11), the variational update of Algorithm 1 with
importance sampling for <s> (eq 21) and <v> (eq 20) and the Wishart / Gamma updates
(eqs 18-19, 22-23) iterated to convergence, the localization confidence (eqs 24-26), the
measurement confidence used to rank references (eqs 27-29) and reference promotion.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import DegenerateGeometryError, InsufficientMeasurementsError
from .lsq import multilaterate, multilateration_covariance

__all__ = [
    "POS",
    "STVFPrior",
    "VariationalResult",
    "gamma_update",
    "initial_fix",
    "initial_prior",
    "localization_confidence",
    "mean_update",
    "measurement_confidence",
    "predict",
    "project_delay",
    "select_references",
    "speed_moment",
    "state_moments",
    "variational_update",
    "variational_update_batch",
    "wishart_update",
]

#: indices of (x, y) in the state [x, vx, y, vy]: the paper's selection matrix A.
POS = np.array([0, 2])


@dataclass(frozen=True)
class STVFPrior:
    """Fixed parameters of the STVF model (Table 1 defaults).

    ``transition`` is the precision Lambda of mu_t | mu_{t-1} (1/m^2, 1/(m/s)^2), ``wishart_scale``
    W and ``wishart_dof`` n the Wishart prior of the state precision, ``speed`` v (m/s) and
    ``speed_precision`` V (1/(m/s)^2) the sound-speed prior, ``noise_shape`` alpha and
    ``noise_rate`` beta (ms^2) the Gamma prior of the delay-noise precision (1/ms^2).
    ``tol`` (m) stops the iteration when the position part of mu* moves less than that.
    Algorithm 1 draws new samples in every pass of its while-loop (the default);
    ``common_random_numbers`` reuses one set of standard-normal draws for all passes of one
    localization instead, which makes the iteration a deterministic map (used by tests of the
    fixed point) but repeats the same Monte Carlo error in every pass, so the mean drifts in
    one direction (docs/stvf.md, "Why STVF trails SLMP").
    """

    transition: NDArray[np.float64] = field(default_factory=lambda: np.eye(4) / 900.0)
    wishart_scale: NDArray[np.float64] = field(default_factory=lambda: 5.0 * np.eye(4))
    wishart_dof: float = 10.0
    speed: float = 1500.0
    speed_precision: float = 1.0 / 100.0
    noise_shape: float = 3.0
    noise_rate: float = 200.0
    n_state_samples: int = 200
    n_speed_samples: int = 200
    z_scale: float = 1e3
    tol: float = 0.1
    max_iter: int = 50
    common_random_numbers: bool = False


@dataclass(frozen=True)
class VariationalResult:
    """Output of one variational update (Algorithm 1, inner loop).

    ``state`` is <s>_{t|t} (the location estimate is ``state[POS]``), ``mu`` / ``mu_precision``
    the parameters of q(mu_t) carried to the next period, ``speed`` <v> (m/s), ``zeta`` <zeta>
    (1/ms^2), ``iterations`` the number of passes of the while-loop, ``converged`` whether the
    tolerance was met before ``max_iter``.
    """

    state: NDArray[np.float64]
    state_second_moment: NDArray[np.float64]
    mu: NDArray[np.float64]
    mu_precision: NDArray[np.float64]
    lam: NDArray[np.float64]
    speed: float
    zeta: float
    noise_shape: float
    noise_rate: float
    iterations: int
    converged: bool

    @property
    def position(self) -> NDArray[np.float64]:
        """Estimated (x, y), m."""
        return self.state[POS]


_F64 = NDArray[np.float64]  # module level: a subscripted alias in a hot cast costs typing work per call


def _inv(m: NDArray[np.float64]) -> NDArray[np.float64]:
    """Inverse of one matrix or of a stack (each matrix inverted exactly as on its own)."""
    # numpy's stubs widen inv's result to NDArray[floating]; for float64 input it is float64
    return cast(_F64, np.linalg.inv(m))


def _sym(m: NDArray[np.float64]) -> NDArray[np.float64]:
    return 0.5 * (m + m.swapaxes(-1, -2))


def predict(
    mu_prev: ArrayLike, mu_precision_prev: ArrayLike, transition: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Variational prediction of q(mu_t) (eq 11): mu^p = mu*_{t-1},
    Lambda^p = (Lambda*_{t-1}^-1 + Lambda^-1)^-1 (precisions). Also for stacks ((B, 4),
    (B, 4, 4), (B, 4, 4)): each node's result has the bits of its prediction alone."""
    mu_p = np.array(mu_prev, dtype=float)
    prev_cov, trans_cov = _inv(np.stack((np.asarray(mu_precision_prev, float), np.asarray(transition, float))))
    return mu_p, _sym(_inv(prev_cov + trans_cov))


def initial_prior(position: ArrayLike, std: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """q(mu_0) for a node with no previous estimate: N([x, 0, y, 0], I / std^2).

    Algorithm 1 takes mu*_0, Lambda*_0 as inputs without saying where they come from; the
    protocol supplies a coarse position (e.g. a multilateration fix) and its std (m)."""
    p = np.asarray(position, float)
    mu = np.array([p[0], 0.0, p[1], 0.0])
    return mu, np.eye(4) / std**2


def initial_fix(
    refs: ArrayLike, ranges: ArrayLike, rel_std: float, max_std: float, range_m: float
) -> NDArray[np.float64] | None:
    """A coarse (x, y) (m) for :func:`initial_prior` with std ``max_std``, or None when the
    references cannot give one that good.

    The linear multilateration fix on ``ranges`` (m) to ``refs`` (N, 2), kept only if (a) its
    first-order covariance for range errors of std ``rel_std`` x range has std at most
    ``max_std`` in its worst direction (q(mu_0) is isotropic; references near one line, which
    Sec. 3.1 excludes, make the fix a possible mirror image and that std large), and (b) it
    lies within ``range_m`` of every reference, up to 3 std of the range error and of the
    fix's own error, since a node hears only references in range."""
    refs = np.asarray(refs, float)
    r = np.asarray(ranges, float)
    try:
        fix = multilaterate(refs, r)
        cov = multilateration_covariance(refs, r, rel_std * r)
    except (DegenerateGeometryError, InsufficientMeasurementsError):
        return None
    worst = float(np.linalg.eigvalsh(cov)[-1])
    if worst > max_std**2:
        return None
    # its distance to a reference is uncertain by the range error and the fix's own error
    if np.any(np.linalg.norm(refs - fix, axis=1) > range_m + 3.0 * np.sqrt((rel_std * range_m) ** 2 + worst)):
        return None
    return fix


def _sample_gaussian(
    mean: NDArray[np.float64], precision: NDArray[np.float64], eps: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Rows mean + L^-T eps with precision = L L^T, i.e. draws of N(mean, precision): ``mean``
    (..., 4), ``precision`` (..., 4, 4), ``eps`` (..., Ns, 4), leading axes a batch."""
    chol_cov = cast(_F64, np.linalg.cholesky(_sym(_inv(precision))))
    return mean[..., None, :] + _matvec(chol_cov[..., None, :, :], eps)


def _normalized_weights(logw: NDArray[np.float64]) -> NDArray[np.float64]:
    w = np.exp(logw - logw.max(axis=-1, keepdims=True))
    return w / w.sum(axis=-1, keepdims=True)


# Products and sums without BLAS: a node's update gives the same bits alone or in a batch, on
# any CPU. A BLAS kernel may sum in an order that depends on where a row starts in memory (an
# SSE kernel peels an unaligned first element), and a row of a batch starts where a node alone
# does not; numpy's reduction over a contiguous last axis (np.add.reduce: pairwise, fixed
# order) does not depend on either. Measured: with OpenBLAS's Prescott kernels the batched and
# one-node updates differed in the last bits of a third of the estimates before.


def _sum_last(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Sum over the last axis in numpy's pairwise order, whatever the leading axes."""
    return cast(_F64, np.add.reduce(np.ascontiguousarray(x), axis=-1))


def _row_sq(res: NDArray[np.float64]) -> NDArray[np.float64]:
    """Sum of squares over the last axis; leading axes are a batch."""
    return _sum_last(res * res)


def _vec_dot(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """a . b over the last axis; leading axes are a batch."""
    return _sum_last(a * b)


def _matvec(m: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    """m v for matrices m (..., k, j) and vectors v (..., j), broadcast over leading axes."""
    return _sum_last(m * v[..., None, :])


def _delays(
    positions: NDArray[np.float64], refs: NDArray[np.float64], speed: ArrayLike, z_scale: float
) -> NDArray[np.float64]:
    """Predicted delays z_scale * ||A(s - s_i)|| / v: ``positions`` and ``refs`` (..., 2) and
    ``speed`` broadcast against each other (the callers line up the axes)."""
    r = np.linalg.norm(positions - refs, axis=-1)
    return z_scale * r / np.asarray(speed)


def state_moments(
    mean: ArrayLike,
    precision: ArrayLike,
    z: ArrayLike,
    refs: ArrayLike,
    speed: ArrayLike,
    zeta: ArrayLike,
    eps: NDArray[np.float64],
    z_scale: float = 1e3,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Importance-sampling moments of q(s) (eq 21).

    Proposal N(mean, precision) (4-D), weights prod_i N(z_i | z_scale r_i(s)/<v>, <zeta>);
    ``eps`` (Ns, 4) standard normals. Returns <s> (4,) and <s s^T> (4, 4). Leading axes of
    every argument (``speed``, ``zeta``: shape (...)) are a batch of independent nodes."""
    mean = np.asarray(mean, float)
    s = _sample_gaussian(mean, np.asarray(precision, float), eps)
    pos = s[..., POS]
    delay = _delays(
        pos[..., None, :], np.asarray(refs, float)[..., None, :, :], np.asarray(speed)[..., None, None], z_scale
    )
    res = np.asarray(z, float)[..., None, :] - delay
    w = _normalized_weights(-0.5 * np.asarray(zeta)[..., None] * _row_sq(res))
    ws = s * w[..., :, None]  # the weighted samples (..., Ns, 4)
    m1 = _sum_last(ws.swapaxes(-1, -2))
    m2 = _sum_last(ws.swapaxes(-1, -2)[..., :, None, :] * s.swapaxes(-1, -2)[..., None, :, :])
    return m1, _sym(m2)


def speed_moment(
    position: ArrayLike,
    z: ArrayLike,
    refs: ArrayLike,
    speed_mean: float,
    speed_precision: float,
    zeta: ArrayLike,
    eps: NDArray[np.float64],
    z_scale: float = 1e3,
) -> NDArray[np.float64]:
    """Importance-sampling mean of q(v) (eq 20): v_k ~ N(v0, V), weights
    prod_i N(z_i | z_scale r_i(<s>)/v_k, <zeta>); ``eps`` (Nv,) standard normals. Leading axes
    (``zeta``: shape (...)) are a batch; one node gives a numpy scalar."""
    v = speed_mean + eps / np.sqrt(speed_precision)
    r = z_scale * np.linalg.norm(np.asarray(position, float)[..., None, :] - np.asarray(refs, float), axis=-1)
    res = np.asarray(z, float)[..., None, :] - r[..., None, :] / v[..., :, None]
    w = _normalized_weights(-0.5 * np.asarray(zeta)[..., None] * _row_sq(res))
    return _vec_dot(w, v)


def gamma_update(
    shape: float,
    rate: float,
    z: ArrayLike,
    refs: ArrayLike,
    position: ArrayLike,
    speed: ArrayLike,
    z_scale: float = 1e3,
) -> tuple[float, NDArray[np.float64]]:
    """Gamma update of q(zeta) (eq 22): alpha* = alpha + Nr/2,
    beta* = beta + 1/2 sum_i (z_i - z_scale r_i(<s>)/<v>)^2. Leading axes are a batch."""
    z = np.asarray(z, float)
    pos = np.asarray(position, float)[..., None, :]
    res = z - _delays(pos, np.asarray(refs, float), np.asarray(speed)[..., None], z_scale)
    return shape + 0.5 * z.shape[-1], np.float64(rate) + 0.5 * _vec_dot(res, res)


def mean_update(
    lam: ArrayLike, state: ArrayLike, mu_p: ArrayLike, mu_p_precision: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """q(mu_t) = N(mu*, Lambda*) (eqs 13, 18): Lambda* = <lam> + Lambda^p,
    mu* = Lambda*^-1 (<lam> <s> + Lambda^p mu^p). Leading axes are a batch."""
    lam = np.asarray(lam, float)
    lp = np.asarray(mu_p_precision, float)
    prec = _sym(lam + lp)
    rhs = _matvec(lam, np.asarray(state, float)) + _matvec(lp, np.asarray(mu_p, float))
    return cast(_F64, np.linalg.solve(prec, rhs[..., None])[..., 0]), prec


def _outer(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """a b^T over the last axis (``np.outer``'s products, with leading batch axes)."""
    return a[..., :, None] * b[..., None, :]


def _wishart_matrix(
    second_moment: ArrayLike, state: ArrayLike, mu: ArrayLike, mu_second_moment: ArrayLike, scale_inv: ArrayLike
) -> NDArray[np.float64]:
    """<ss^T> - <s><mu>^T - <mu><s>^T + <mu mu^T> + W^-1, symmetrized: W*^-1 of eq 18."""
    s = np.asarray(state, float)
    m = np.asarray(mu, float)
    mat = (
        np.asarray(second_moment, float) - _outer(s, m) - _outer(m, s) + np.asarray(mu_second_moment, float) + scale_inv
    )
    return _sym(mat)


def wishart_update(
    second_moment: ArrayLike,
    state: ArrayLike,
    mu: ArrayLike,
    mu_second_moment: ArrayLike,
    scale: ArrayLike,
    *,
    scale_inv: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """Wishart scale of q(lam_t) (eqs 14, 18):
    W* = (<ss^T> - <s><mu>^T - <mu><s>^T + <mu mu^T> + W^-1)^-1 (dof n* = n + 1).
    ``scale_inv`` (W^-1) may be passed to save an inversion per iteration."""
    w_inv = _inv(np.asarray(scale, float)) if scale_inv is None else scale_inv
    return _sym(_inv(_wishart_matrix(second_moment, state, mu, mu_second_moment, w_inv)))


def variational_update(
    z: ArrayLike,
    refs: ArrayLike,
    mu_p: ArrayLike,
    mu_p_precision: ArrayLike,
    prior: STVFPrior,
    rng: np.random.Generator,
) -> VariationalResult:
    """Variational update of Algorithm 1 for one node and one period.

    ``z`` (Nr,) delays (ms), ``refs`` (Nr, 2) reference positions projected on the node's depth
    plane (m), ``mu_p``, ``mu_p_precision`` the predicted q(mu_t) from :func:`predict`.
    Initialization as printed in Algorithm 1 (Lambda* = 2 Lambda^p,
    W* = [(2 Lambda^p)^-1 + W^-1]^-1, beta* = beta / 2, <v> = v0); then <s>, <ss^T> and <v>
    by importance sampling and the closed-form updates, until the position part of mu* moves
    less than ``prior.tol`` m or ``prior.max_iter`` passes. A batch of one of
    :func:`variational_update_batch`."""
    one = variational_update_batch(
        np.asarray(z, float)[None],
        np.asarray(refs, float)[None],
        np.asarray(mu_p, float)[None],
        np.asarray(mu_p_precision, float)[None],
        prior,
        [rng],
    )
    return one[0]


def _draw(rngs: list[np.random.Generator], rows: NDArray[np.intp], ns: int, nv: int) -> tuple[_F64, _F64]:
    """This pass's standard normals of the nodes ``rows``: each node's (Ns, 4) state draws, then
    its (Nv,) speed draws, from its own generator (the order of a node run alone)."""
    eps_s = np.empty((rows.size, ns, 4))
    eps_v = np.empty((rows.size, nv))
    for j, i in enumerate(rows.tolist()):
        rngs[i].standard_normal(out=eps_s[j])
        rngs[i].standard_normal(out=eps_v[j])
    return eps_s, eps_v


def variational_update_batch(
    z: ArrayLike,
    refs: ArrayLike,
    mu_p: ArrayLike,
    mu_p_precision: ArrayLike,
    prior: STVFPrior,
    rngs: Sequence[np.random.Generator],
) -> list[VariationalResult]:
    """:func:`variational_update` for n nodes at once, each node's result bit-identical to its
    update run alone on any CPU (the same operations: elementwise, sums in numpy's fixed order,
    one LAPACK call per node; no BLAS product, whose order may depend on alignment).

    ``z`` (n, Nr), ``refs`` (n, Nr, 2), ``mu_p`` (n, 4), ``mu_p_precision`` (n, 4, 4); ``rngs``
    one distinct generator per node, from which the node draws exactly what it would alone.
    Every numpy call covers the nodes still iterating: a node leaves the batch at the pass where
    its own tolerance is met (or at ``prior.max_iter``), so its draws and pass count are its own."""
    z = np.asarray(z, float)
    refs = np.asarray(refs, float)
    mu_p = np.asarray(mu_p, float)
    lp = np.asarray(mu_p_precision, float)
    rngs = list(rngs)
    n, nr = z.shape
    if len(rngs) != n or len({id(r) for r in rngs}) != n:
        raise ValueError("variational_update_batch: one distinct generator per node is needed")
    if prior.max_iter < 1:
        raise ValueError(f"variational_update_batch: max_iter must be >= 1, got {prior.max_iter}")
    dof = prior.wishart_dof + 1.0
    ns, nv = prior.n_state_samples, prior.n_speed_samples

    mu_prec = 2.0 * lp
    mu = mu_p.copy()
    w_inv = _inv(prior.wishart_scale)
    mu_cov = _inv(mu_prec)  # (2 Lambda^p)^-1, used twice below
    w_star = _sym(_inv(mu_cov + w_inv))
    shape = prior.noise_shape + 0.5 * nr
    rate = np.full(n, 0.5 * prior.noise_rate)
    speed = np.full(n, prior.speed)
    lam = dof * w_star
    zeta = shape / rate
    mu_mu = _outer(mu, mu) + mu_cov

    rows = np.arange(n)  # the nodes still iterating; every array below has one row per node of it
    results: list[VariationalResult | None] = [None] * n
    eps_s, eps_v = _draw(rngs, rows, ns, nv)
    for it in range(1, prior.max_iter + 1):
        if not prior.common_random_numbers and it > 1:
            eps_s, eps_v = _draw(rngs, rows, ns, nv)
        s1, s2 = state_moments(mu, lam, z, refs, speed, zeta, eps_s, prior.z_scale)
        speed = speed_moment(s1[:, POS], z, refs, prior.speed, prior.speed_precision, zeta, eps_v, prior.z_scale)
        # Parameters from the current expectations, then the expectations (Algorithm 1 order).
        new_mu, mu_prec = mean_update(lam, s1, mu_p, lp)
        # W* (eq 18) and <mu mu^T> need two 4x4 inverses per node: one call on the stack of all
        w_star_inv, mu_cov = _inv(np.stack((_wishart_matrix(s2, s1, mu, mu_mu, w_inv), mu_prec)))
        w_star = _sym(w_star_inv)
        shape, rate = gamma_update(prior.noise_shape, prior.noise_rate, z, refs, s1[:, POS], speed, prior.z_scale)
        d = new_mu[:, POS] - mu[:, POS]
        step = np.sqrt(_vec_dot(d, d))  # np.linalg.norm of each node's 2-vector: sqrt(x.dot(x))
        mu = new_mu
        mu_mu = _outer(mu, mu) + mu_cov
        lam = dof * w_star
        zeta = shape / rate
        done = step < prior.tol
        last = it == prior.max_iter
        if last or done.any():
            for j in np.flatnonzero(done | last).tolist():
                results[rows[j]] = VariationalResult(
                    state=s1[j],
                    state_second_moment=s2[j],
                    mu=mu[j],
                    mu_precision=mu_prec[j],
                    lam=lam[j],
                    speed=float(speed[j]),
                    zeta=float(zeta[j]),
                    noise_shape=shape,
                    noise_rate=float(rate[j]),
                    iterations=it,
                    converged=bool(done[j]),
                )
            if last:
                break
            keep = ~done
            rows = rows[keep]
            if rows.size == 0:
                break
            z, refs, mu_p, lp = z[keep], refs[keep], mu_p[keep], lp[keep]
            mu, mu_mu, lam, zeta, speed = mu[keep], mu_mu[keep], lam[keep], zeta[keep], speed[keep]
            if prior.common_random_numbers:
                eps_s, eps_v = eps_s[keep], eps_v[keep]
    return cast(list[VariationalResult], results)


def localization_confidence(
    ref_confidence: ArrayLike,
    position: ArrayLike,
    refs: ArrayLike,
    z: ArrayLike,
    speed: float,
    z_scale: float = 1e3,
    absolute: bool = True,
) -> float:
    """Confidence of a localized node (eqs 24-26): eta = mean(eta_i) (1 - E / D),
    D = sum_i ||A(<s> - s_i)||^2, E = sum_i (||A(<s> - s_i)||^2 - (z_i <v>)^2).

    ``absolute=True`` sums |.| of each term of E: the paper prints a signed sum, which lets errors
    of opposite sign cancel and can push eta above the references' mean (even above 1); the
    text calls E "the sum of errors", so by default each error counts. Clipped to [0, 1]."""
    # np.add.reduce is what np.sum, ndarray.sum and np.mean reduce with (the same bits), without
    # their Python wrappers: this runs once per localization
    add = np.add.reduce
    d2 = add((np.asarray(position, float) - np.asarray(refs, float)) ** 2, axis=-1)
    m2 = (np.asarray(z, float) * speed / z_scale) ** 2
    err = d2 - m2
    e = add(np.abs(err)) if absolute else add(err)
    eta_r = np.asarray(ref_confidence, float)
    eta = float(add(eta_r) / eta_r.size) * (1.0 - e / add(d2))
    # strictly inside (0, 1) the clip is the identity; its edge cases (-0.0, NaN) stay numpy's
    return float(eta) if 0.0 < eta < 1.0 else float(np.clip(eta, 0.0, 1.0))


def _normalize(a: NDArray[np.float64]) -> NDArray[np.float64]:
    span = a.max() - a.min()
    # All equal: the term cannot rank anything; 0 keeps gamma in [0, 1].
    return np.zeros_like(a) if span <= 0 else (a - a.min()) / span


def measurement_confidence(
    ref_confidence: ArrayLike,
    z: ArrayLike,
    ref_speed: ArrayLike,
    weights: tuple[float, float, float] = (0.7, 0.2, 0.1),
    penalize: bool = True,
) -> NDArray[np.float64]:
    """Measurement confidence gamma_i (eqs 27-29) from reference confidence eta_i, delay z_i and
    reference speed |v_i| = sqrt(vx^2 + vy^2), min-max normalized over the candidates.

    ``penalize=False`` is eq 27 as printed: gamma = C1 eta + C2 f_z + C3 f_v, which gives the
    *farthest* and *fastest* references the highest confidence. The text motivating eq 27 says
    the opposite (long distances and high speeds incur larger errors), so by default the
    normalized terms enter as (1 - f_z) and (1 - f_v)."""
    c1, c2, c3 = weights
    fz = _normalize(np.asarray(z, float))
    fv = _normalize(np.asarray(ref_speed, float))
    if penalize:
        fz, fv = 1.0 - fz, 1.0 - fv
    return c1 * np.asarray(ref_confidence, float) + c2 * fz + c3 * fv


def select_references(gamma: ArrayLike, n_r: int) -> NDArray[np.intp]:
    """Indices of the ``n_r`` largest gamma, best first (ties keep arrival order)."""
    g = np.asarray(gamma, float)
    return np.argsort(-g, kind="stable")[:n_r]


def project_delay(z: ArrayLike, depth_difference: ArrayLike, speed: float, z_scale: float = 1e3) -> NDArray[np.float64]:
    """Delay (same unit as ``z``) of the horizontal component of a 3-D path, for the projection
    of a neighbour onto the receiver's depth plane: sqrt(z^2 - (z_scale dz / v)^2), floored at 0
    (noise can make z shorter than the vertical separation)."""
    zv = z_scale * np.asarray(depth_difference, float) / speed
    z = np.asarray(z, float)
    return np.sqrt(np.maximum(z * z - zv * zv, 0.0))
