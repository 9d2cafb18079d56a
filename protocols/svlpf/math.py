"""SVL-PF maths (Li, Zhang, Yan, Han, Guan, Sensors 18:8, 2018): pure numpy / scipy / sklearn.

- node selection: a per-sensor SVM on the measured distance (eqs 13-14), trained with
  scikit-learn's SVC and evaluated here from its support vectors (eq 14 plus the intercept);
- the LSSVR observation function (eqs 15-20): the KKT system (17) solved with scipy.linalg;
- the diagnosis of excessive sensing noise by propagation loss (eqs 23-25), the weights delta
  (eq 26) and the iterative regression with the termination rule (21, 27);
- the particle-filter log-likelihoods of ToA-PF (eq 29) and SVL-PF / LSSVR-PF (eq 31);
- the Consensus Estimation baseline (the SVL-PF paper's ref. [14]);
- a training cache keyed by a hash of everything a trained model depends on.

Open choices (the paper leaves them open) are documented in docs/svlpf.md and at each function.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from aquasim_py.estimation.errors import DegenerateGeometryError
from aquasim_py.estimation.lsq import multilaterate

__all__ = [
    "LssvrModel",
    "SvmModel",
    "TrainingCache",
    "consensus_estimate",
    "delta_weights",
    "diagnose",
    "iterative_regression",
    "lssvr_fit",
    "lssvr_predict",
    "lssvr_training_set",
    "observation_loglik",
    "propagation_loss_db",
    "range_loglik",
    "rbf_kernel",
    "svm_discriminant",
    "svm_train",
    "svm_training_set",
    "training_rng",
]

Array = NDArray[np.float64]

#: bump when a training routine changes, so that cached models are retrained
CACHE_VERSION = 1


# ------------------------------------------------------------------------- training randomness
def training_rng(seed: int, key: str) -> np.random.Generator:
    """A Generator for one trained model: a function of (seed, key) only, so a model does not
    depend on which other models were trained before it (nor on whether it came from the cache)."""
    words = [int.from_bytes(hashlib.blake2b(key.encode(), digest_size=8).digest()[i : i + 4], "little") for i in (0, 4)]
    return np.random.default_rng(np.random.SeedSequence([int(seed), *words]))


def cache_key(kind: str, parts: Mapping[str, Any]) -> str:
    """SHA-256 of everything a trained model depends on (floats by repr, so exact)."""

    def norm(v: Any) -> Any:
        if isinstance(v, np.ndarray):
            return [norm(x) for x in v.tolist()]
        if isinstance(v, (list, tuple)):
            return [norm(x) for x in v]
        if isinstance(v, float):
            return repr(v)
        return v

    blob = json.dumps(
        {"kind": kind, "version": CACHE_VERSION, **{k: norm(v) for k, v in parts.items()}}, sort_keys=True
    )
    return hashlib.sha256(blob.encode()).hexdigest()


class TrainingCache:
    """Trained models as dicts of arrays: in-process memo, plus an on-disk ``.npz`` store.

    ``directory`` None: memory only. The default directory is ``$AQUASIM_CACHE_DIR/svlpf`` or
    ``$XDG_CACHE_HOME/aquasim-py/svlpf`` (``~/.cache/aquasim-py/svlpf``). Entries are written
    atomically (temporary file + rename), so parallel sweep workers may share the directory.
    A hit returns exactly the arrays the training produced (float64 round-trips through npz),
    so the cache changes run time, never results.
    """

    _memo: ClassVar[dict[str, dict[str, Array]]] = {}  # contract: deterministic cache (keyed by inputs)

    def __init__(self, directory: str | Path | None) -> None:
        self.directory = None if directory is None else Path(directory)

    @staticmethod
    def default_directory() -> Path:
        base = os.environ.get("AQUASIM_CACHE_DIR")
        if base:
            return Path(base) / "svlpf"
        xdg = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
        return Path(xdg) / "aquasim-py" / "svlpf"

    def get(self, key: str, train: Callable[[], dict[str, Array]]) -> dict[str, Array]:
        hit = self._memo.get(key)
        if hit is not None:
            return hit
        path = None if self.directory is None else self.directory / f"{key}.npz"
        if path is not None and path.is_file():
            try:
                with np.load(path) as z:
                    hit = {k: z[k] for k in z.files}
            except (OSError, ValueError):
                hit = None  # unreadable entry: retrain and overwrite
        if hit is None:
            hit = train()
            if path is not None:
                try:
                    path.parent.mkdir(parents=True, exist_ok=True)
                    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp.npz")
                    with os.fdopen(fd, "wb") as fh:
                        np.savez(fh, **hit)  # type: ignore[arg-type]  # numpy's stub types **kwds oddly
                    os.replace(tmp, path)
                except OSError:
                    pass  # a read-only cache directory only costs time
        self._memo[key] = hit
        return hit


# ------------------------------------------------------------------------- node selection (SVM)
@dataclass(frozen=True)
class SvmModel:
    """A trained per-sensor discriminant (eq 14): f(r) = sum_i coef_i k(r, d_i) + intercept,
    k(r, d) = exp(-gamma ((r - d) / scale)^2); coef_i = lambda_i y_i."""

    support: Array
    coef: Array
    intercept: float
    gamma: float
    scale: float

    def arrays(self) -> dict[str, Array]:
        return {
            "support": self.support,
            "coef": self.coef,
            "meta": np.array([self.intercept, self.gamma, self.scale]),
        }

    @classmethod
    def from_arrays(cls, a: Mapping[str, Array]) -> SvmModel:
        m = a["meta"]
        return cls(a["support"], a["coef"], float(m[0]), float(m[1]), float(m[2]))


def svm_training_set(
    sensor: ArrayLike, lo: ArrayLike, hi: ArrayLike, n: int, theta_m: float, range_m: float, rng: np.random.Generator
) -> tuple[Array, Array]:
    """{d_i, y_i} of eq 13 for one sensor: distances (m) from ``n`` synthetic target positions
    uniform in the region [lo, hi] to the sensor, kept within the distance parameter theta
    (0 <= d_i <= theta); label +1 within the efficient range, -1 beyond."""
    p = rng.uniform(np.asarray(lo, float), np.asarray(hi, float), size=(n, 3))
    d = np.linalg.norm(p - np.asarray(sensor, float), axis=1)
    d = d[d <= theta_m]
    return d, np.where(d <= range_m, 1.0, -1.0)


def svm_train(d: ArrayLike, y: ArrayLike, *, c: float, gamma: float, scale: float) -> SvmModel:
    """Solve the dual (13) with scikit-learn's SVC (RBF kernel on d / scale)."""
    from sklearn.svm import SVC

    d = np.asarray(d, float)
    y = np.asarray(y, float)
    if np.unique(y).size < 2:
        # one class only (the sensor can never / always be in range): a constant discriminant
        return SvmModel(np.zeros(0), np.zeros(0), float(y[0]) if y.size else -1.0, gamma, scale)
    clf = SVC(C=c, kernel="rbf", gamma=gamma).fit((d / scale)[:, None], y)
    return SvmModel(
        clf.support_vectors_[:, 0] * scale,
        clf.dual_coef_[0].astype(float),
        float(clf.intercept_[0]),
        gamma,
        scale,
    )


def svm_discriminant(model: SvmModel, r: ArrayLike) -> Array:
    """Eq 14 (with the SVC's intercept): > 0 = the sensor lies within the efficient range."""
    r = np.asarray(r, float)
    u = (r[..., None] - model.support) / model.scale
    return np.exp(-model.gamma * u * u) @ model.coef + model.intercept


# ------------------------------------------------------------------------- LSSVR (eqs 15-20)
@dataclass(frozen=True)
class LssvrModel:
    """Eq 20: Z(x) = sum_m alpha_m k(x_m, x) + b, one column of alpha / entry of b per output
    coordinate. ``mean_input`` is S-bar of eq 26 (the training inputs' column means)."""

    X: Array  # (J, M) training inputs
    alpha: Array  # (J, 3)
    b: Array  # (3,)
    width: float  # RBF kernel width (m)
    mean_input: Array  # (M,)

    def arrays(self) -> dict[str, Array]:
        return {
            "X": self.X,
            "alpha": self.alpha,
            "b": self.b,
            "width": np.array([self.width]),
            "mean_input": self.mean_input,
        }

    @classmethod
    def from_arrays(cls, a: Mapping[str, Array]) -> LssvrModel:
        return cls(a["X"], a["alpha"], a["b"], float(a["width"][0]), a["mean_input"])


def rbf_kernel(A: ArrayLike, B: ArrayLike, width: float) -> Array:
    """phi(a)^T phi(b) = exp(-|a - b|^2 / (2 width^2)) for rows of A (n, M) and B (m, M)."""
    A = np.atleast_2d(np.asarray(A, float))
    B = np.atleast_2d(np.asarray(B, float))
    d2 = np.sum(A * A, 1)[:, None] + np.sum(B * B, 1)[None, :] - 2.0 * A @ B.T
    return np.exp(-np.maximum(d2, 0.0) / (2.0 * width * width))


def lssvr_fit(X: ArrayLike, Y: ArrayLike, *, c: float, width: float) -> LssvrModel:
    """Solve the KKT system (17) [[0, 1^T], [1, H]] [b; alpha] = [0; y], H = K + I/C (eqs 18-19),
    for all output columns of Y (J, q) at once.

    By block elimination (Suykens' LS-SVM solution, the same [b; alpha] as (17)): with H
    symmetric positive definite, eta = H^-1 1, nu = H^-1 y, b = 1^T nu / 1^T eta,
    alpha = nu - eta b; one Cholesky factorization (scipy.linalg.cho_factor), on one BLAS
    thread (BLAS threads contend badly on shared machines for matrices this small).
    """
    from scipy import linalg
    from threadpoolctl import threadpool_limits

    X = np.asarray(X, float)
    Y = np.asarray(Y, float)
    if Y.ndim == 1:
        Y = Y[:, None]
    J = X.shape[0]
    H = rbf_kernel(X, X, width) + np.eye(J) / c
    with threadpool_limits(1, user_api="blas"):
        cf = linalg.cho_factor(H, lower=True, check_finite=False)
        sol = linalg.cho_solve(cf, np.column_stack([np.ones(J), Y]), check_finite=False)
    eta, nu = sol[:, 0], sol[:, 1:]
    b = nu.sum(axis=0) / eta.sum()
    return LssvrModel(X, nu - eta[:, None] * b, b, float(width), X.mean(axis=0))


def lssvr_predict(model: LssvrModel, x: ArrayLike) -> Array:
    """Eq 20 for one input (M,) -> (q,) or a batch (n, M) -> (n, q)."""
    x = np.asarray(x, float)
    k = rbf_kernel(np.atleast_2d(x), model.X, model.width)
    out = k @ model.alpha + model.b
    return out[0] if x.ndim == 1 else out


def lssvr_training_set(
    sensors: ArrayLike,
    lo: ArrayLike,
    hi: ArrayLike,
    n: int,
    rng: np.random.Generator,
    *,
    noise_ratio: float = 0.0,
    max_range_m: float | None = None,
    oversample: int = 20,
) -> tuple[Array, Array]:
    """Dataset D of the LSSVR for the selected sensors (M, 3): ``n`` synthetic target positions
    and their distances to the sensors (plus Gaussian noise of std ``noise_ratio`` x distance).

    Positions are uniform in [lo, hi], kept where every selected sensor is within
    ``max_range_m`` (the region where that subset is the one selected); if fewer than ``n``
    such positions turn up among ``oversample * n`` draws, the ``n`` with the smallest largest
    distance are used.
    """
    S = np.asarray(sensors, float)
    P = rng.uniform(np.asarray(lo, float), np.asarray(hi, float), size=(oversample * n, 3))
    D = np.linalg.norm(P[:, None, :] - S[None, :, :], axis=2)
    if max_range_m is not None:
        far = D.max(axis=1)
        ok = np.flatnonzero(far <= max_range_m)
        idx = ok[:n] if ok.size >= n else np.argsort(far, kind="stable")[:n]
    else:
        idx = np.arange(n)
    P, D = P[idx], D[idx]
    noise = rng.standard_normal(D.shape)
    return D + noise_ratio * D * noise, P


# ------------------------------------------------------------------------- diagnosis, eqs 23-27
def propagation_loss_db(r: ArrayLike, beta_db_per_km: float) -> Array:
    """Eq 24: PL = 20 log10 r + beta r 1e-3 (r in m, beta in dB/km)."""
    d: Array = np.maximum(np.asarray(r, float), 1e-3)
    return 20.0 * np.log10(d) + beta_db_per_km * 1e-3 * d


def diagnose(
    loss_db: ArrayLike, R: ArrayLike, *, p_hat: float, beta_db_per_km: float, excess: bool = False
) -> NDArray[np.bool_]:
    """Eq 25: which distances carry excessive sensing noise, from the observed loss TIL - RIL.

    As printed (``excess=False``): flagged iff TIL - RIL >= p tau(R), 0 < p <= 1, which flags
    every link, since TIL - RIL is about tau(R) itself. ``excess=True`` (a repair) reads the
    left side as the loss in excess of the one the measured distance predicts: flagged iff
    (TIL - RIL) - tau(R) >= p tau(R) (docs/svlpf.md).
    """
    tau = propagation_loss_db(R, beta_db_per_km)
    loss = np.asarray(loss_db, float)
    return (loss - tau if excess else loss) >= p_hat * tau


def delta_weights(R: ArrayLike, mean_input: ArrayLike, flagged: ArrayLike, *, clip: bool = False) -> Array:
    """Eq 26: delta_l = |R_l - S_l| / R_l for a flagged link, 1 otherwise, as printed;
    ``clip=True`` (a repair) clips it to [0, 1], a weight on the measured value (the printed
    ratio exceeds 1 for R_l < S_l / 2)."""
    R = np.asarray(R, float)
    d = np.abs(R - np.asarray(mean_input, float)) / np.maximum(R, 1e-9)
    return np.where(np.asarray(flagged, bool), np.clip(d, 0.0, 1.0) if clip else d, 1.0)


@dataclass(frozen=True)
class RegressionResult:
    z: Array  # the observation Z_k (3,)
    iterations: int  # nu + 1 at termination
    converged: bool  # eq 27 met (else max_iter reached)
    dist_b: Array  # |Z^(nu+1) - b| per iteration (m)
    steps: Array  # |Z^(nu+1) - Z^(nu)| per iteration (m)


def iterative_regression(
    model: LssvrModel,
    R: ArrayLike,
    sensors: ArrayLike,
    delta: ArrayLike,
    *,
    eps_b: float = 1.0,
    eps_step: float = 0.2,
    max_iter: int = 50,
    repaired: bool = False,
) -> RegressionResult:
    """Eqs 21 and 27: Z^(nu+1) = Q(Z^(nu)) until |Z^(nu+1) - b| >= eps_b and
    |Z^(nu+1) - Z^(nu)| <= eps_step (Euclidean norms); Z^(0) = f(R) (eq 20).

    As printed (``repaired=False``), "Z^(nu+1) = Z^(nu)(delta R)": the observation function
    evaluated at the reweighted data, Z^(nu+1) = f(delta R), which does not depend on nu (the
    loop stops at the second step unless eq 27's first condition fails). ``repaired=True``
    (our reading of Q, docs/svlpf.md): the regression input keeps delta_l of each measured
    distance and takes the rest from the distance the current observation predicts,
    x^(nu+1) = delta R + (1 - delta) |Z^(nu) - s|, Z^(nu+1) = f(x^(nu+1)). With no link flagged
    (delta = 1) Q is constant either way and the loop stops after one step (unless f(R) lies
    within eps_b of b, which eq 27 treats as premature: then max_iter applies).
    """
    R = np.asarray(R, float)
    S = np.asarray(sensors, float)
    dl = np.asarray(delta, float)
    z = lssvr_predict(model, R)
    dist_b: list[float] = []
    steps: list[float] = []
    for it in range(1, max_iter + 1):
        x = dl * R + (1.0 - dl) * np.linalg.norm(z[None, :] - S, axis=1) if repaired else dl * R
        z_new = lssvr_predict(model, x)
        dist_b.append(float(np.linalg.norm(z_new - model.b)))
        steps.append(float(np.linalg.norm(z_new - z)))
        z = z_new
        if dist_b[-1] >= eps_b and steps[-1] <= eps_step:
            return RegressionResult(z, it, True, np.array(dist_b), np.array(steps))
    return RegressionResult(z, max_iter, False, np.array(dist_b), np.array(steps))


# ------------------------------------------------------------------------- PF likelihoods
def range_loglik(particles: ArrayLike, sensors: ArrayLike, R: ArrayLike, sigma: float) -> Array:
    """Log of eq 29's product (constants dropped): -sum_j (R_j - |x_i - s_j|)^2 / (2 sigma^2)."""
    X = np.asarray(particles, float)[:, :3]
    d = np.linalg.norm(X[:, None, :] - np.asarray(sensors, float)[None, :, :], axis=2)
    e = np.asarray(R, float)[None, :] - d
    return -np.einsum("ij,ij->i", e, e) / (2.0 * sigma * sigma)


def observation_loglik(particles: ArrayLike, z: ArrayLike, sigma: float) -> Array:
    """Log of eq 31 (constants dropped): -|Z_k - x_i|^2 / (2 sigma^2)."""
    e = np.asarray(particles, float)[:, :3] - np.asarray(z, float)
    return -np.einsum("ij,ij->i", e, e) / (2.0 * sigma * sigma)


# ------------------------------------------------------------------------- Consensus Estimation
def _regional_solution(S: Array, R: Array, lo: Array, hi: Array) -> Array:
    """A subnetwork's local estimate: the range least-squares fix constrained to the monitored
    region [lo, hi] (always exists: the "regional optimal solution" that avoids the
    no-solution case), started from the linear multilateration fix clipped to the region."""
    from scipy.optimize import least_squares

    try:
        x0 = multilaterate(S, R) if S.shape[0] >= 4 else S.mean(axis=0)
    except (DegenerateGeometryError, ValueError, np.linalg.LinAlgError):
        x0 = S.mean(axis=0)
    x0 = np.clip(np.where(np.isfinite(x0), x0, S.mean(axis=0)), lo + 1e-6, hi - 1e-6)

    def jac(x: Array) -> Array:
        d = x - S
        return d / np.maximum(np.linalg.norm(d, axis=1), 1e-9)[:, None]

    res = least_squares(lambda x: np.linalg.norm(S - x, axis=1) - R, x0, jac=jac, bounds=(lo, hi), method="trf")
    return np.asarray(res.x, float)


def consensus_estimate(
    sensors: ArrayLike, R: ArrayLike, lo: ArrayLike, hi: ArrayLike, *, group_size: int = 4, iterations: int = 20
) -> Array:
    """Consensus Estimation (the SVL-PF paper's ref. [14]) as we implement it (docs/svlpf.md).

    The selected sensors form overlapping subnetworks (each sensor with its ``group_size - 1``
    nearest selected neighbours); each subnetwork computes its regional least-squares fix
    (:func:`_regional_solution`); the fixes are then averaged by ``iterations`` rounds of
    average consensus with Metropolis-Hastings weights over the graph whose edges join
    subnetworks that share a sensor. Returns the mean of the final subnetwork states (the
    network average once consensus has converged).
    """
    S = np.asarray(sensors, float)
    R = np.asarray(R, float)
    lo = np.asarray(lo, float)
    hi = np.asarray(hi, float)
    m = S.shape[0]
    g = min(group_size, m)
    D = np.linalg.norm(S[:, None, :] - S[None, :, :], axis=2)
    groups = [tuple(sorted(np.argsort(D[i], kind="stable")[:g].tolist())) for i in range(m)]
    groups = list(dict.fromkeys(groups))  # drop duplicate subnetworks, keep order
    X = np.array([_regional_solution(S[list(grp)], R[list(grp)], lo, hi) for grp in groups])
    # subnetworks sharing a sensor talk to each other; Metropolis-Hastings weights make W
    # symmetric and doubly stochastic, so the iteration converges to the average
    B = np.zeros((len(groups), m))
    for i, grp in enumerate(groups):
        B[i, list(grp)] = 1.0
    A = (B @ B.T > 0) & ~np.eye(len(groups), dtype=bool)
    deg = A.sum(axis=1)
    W = np.where(A, 1.0 / (1.0 + np.maximum(deg[:, None], deg[None, :])), 0.0)
    W[np.diag_indices_from(W)] = 1.0 - W.sum(axis=1)
    for _ in range(iterations):
        X = W @ X
    return X.mean(axis=0)
