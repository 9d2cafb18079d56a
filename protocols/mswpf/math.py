"""The MSWPF paper's own maths (Zhang et al., multi-sensor weighted particle filter with mutual
information fusion weights and PCRLB node selection), pure numpy: the sensor measurement model
with location uncertainty (eqs 5-10), the quantizer (eq 11), fusion weights (eq 27, and the EW /
BW comparison schemes of Sec. 5), the weighted multi-sensor likelihood (eq 25), and the
fusion-centre tracker of Algorithm 1 with PCRLB selection (eqs 29-36) as a SimPy-free class.

Generic parts live in :mod:`aquasim_py.estimation` (particle core, quantized-Gaussian
probabilities / MI / Fisher information, PCRLB recursion) and :mod:`aquasim_py.channel.pressure`
(h = S / D^k).

State layout: the library's CV layout [p (dim), v (dim)], i.e. [x, y, vx, vy] in 2-D (the paper
orders [x, vx, y, vy]; same model). In 2-D the target's depth is known (``target_depth``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from aquasim_py.channel.pressure import received_pressure_and_gradient
from aquasim_py.estimation import (
    ConstantVelocityModel,
    best_subset,
    particle_information,
    predicted_information,
    propagate,
    quantized_fisher_scale,
    quantized_log_likelihood,
    quantized_mutual_information,
    sir_update,
)

__all__ = [
    "MswpfConfig",
    "MswpfTracker",
    "equivalent_std",
    "fusion_weights",
    "sensor_mi",
    "sensor_model",
    "thresholds",
    "weighted_log_likelihood",
]

Array = NDArray[np.float64]
WeightScheme = Literal["gw", "ew", "bw"]

#: MI floor (nats) for inverse weights: a sensor with no information gets a huge but finite BW weight
_MI_FLOOR = 1e-12


def thresholds(
    L: int, source_level: float, exponent: float, near_m: float, far_m: float, scheme: str = "pressure"
) -> Array:
    """The L-1 interior thresholds gamma_1 < ... < gamma_{L-1} of eq 11 (not given in the paper).

    "pressure": evenly spaced in pressure between h(far_m) and h(near_m), i.e. L equal bins over
    the pressures a sensor sees inside its sensing range (outer bins open-ended);
    "distance": the pressures at L-1 evenly spaced distances between far_m and near_m.
    """
    if L < 2:
        raise ValueError(f"need L >= 2 quantization levels, got {L}")
    if not 0 < near_m < far_m:
        raise ValueError(f"need 0 < near_m < far_m, got {near_m}, {far_m}")
    lv = np.arange(1, L) / L
    if scheme == "pressure":
        lo, hi = source_level / far_m**exponent, source_level / near_m**exponent
        return np.asarray(lo + lv * (hi - lo))
    if scheme == "distance":
        d = far_m - lv * (far_m - near_m)
        return np.asarray(source_level / d**exponent)
    raise ValueError(f"unknown threshold scheme {scheme!r} (pressure, distance)")


def sensor_model(targets: ArrayLike, sensors: ArrayLike, source_level: float, exponent: float) -> tuple[Array, Array]:
    """h (S, N) and dh/d target position (S, N, 3) of eq 6 at believed sensor positions (S, 3)
    for target positions (N, 3)."""
    P = np.asarray(targets, dtype=float)[None, :, :]
    Sp = np.asarray(sensors, dtype=float)[:, None, :]
    return received_pressure_and_gradient(P, Sp, source_level, exponent)


def equivalent_std(r: float, grad: ArrayLike, loc_std: ArrayLike) -> Array:
    """r_m of eq 10: sqrt(r^2 + (dh/dx_s)^2 r_x^2 + (dh/dy_s)^2 r_y^2), with r_x = r_y = loc_std
    per sensor (S,) and grad (S, N, 3) = dh/d target (dh/d sensor is its negative)."""
    g = np.asarray(grad, dtype=float)
    rx = np.asarray(loc_std, dtype=float).reshape(-1, 1)
    return np.asarray(np.sqrt(r * r + (g[..., 0] ** 2 + g[..., 1] ** 2) * rx**2))


def sensor_mi(
    targets: ArrayLike,
    sensors: ArrayLike,
    loc_std: ArrayLike,
    source_level: float,
    exponent: float,
    r: float,
    gammas: ArrayLike,
) -> Array:
    """Predicted MI (nats) between each sensor's quantized measurement and the state, from
    equally weighted predicted target positions (N, 3) (eqs 10, 12, 19-23): (S,)."""
    h, g = sensor_model(targets, sensors, source_level, exponent)
    rm = equivalent_std(r, g, loc_std)
    return quantized_mutual_information(h, rm, gammas)


def fusion_weights(mi: ArrayLike, scheme: WeightScheme) -> Array:
    """Fusion weights alpha_s, summing to one: "gw" I_s / sum I (eq 27); "ew" 1/Ns; "bw" inverse
    to MI, (1/I_s) / sum (1/I) (Sec. 5's bad-weight comparison). GW with all MI zero falls back
    to equal weights."""
    I = np.asarray(mi, dtype=float).reshape(-1)
    n = I.size
    if n == 0:
        return np.zeros(0)
    if scheme == "ew":
        return np.full(n, 1.0 / n)
    if scheme == "gw":
        tot = I.sum()
        return I / tot if tot > 0 else np.full(n, 1.0 / n)
    if scheme == "bw":
        inv = 1.0 / np.maximum(I, _MI_FLOOR)
        return np.asarray(inv / inv.sum())
    raise ValueError(f"unknown weight scheme {scheme!r} (gw, ew, bw)")


def weighted_log_likelihood(
    levels: ArrayLike, h: ArrayLike, rm: ArrayLike, gammas: ArrayLike, alpha: ArrayLike
) -> Array:
    """log of eq 25, sum_s alpha_s log P(m_s | x_i), per particle: levels (S,), h / rm (S, N)."""
    ll = quantized_log_likelihood(np.asarray(levels, dtype=np.int64)[:, None], h, rm, gammas)
    return np.asarray(np.asarray(alpha, dtype=float) @ ll)


@dataclass(frozen=True)
class MswpfConfig:
    """Fusion-centre model: dimension, CV noise q (m^2/s^3), interval T (s), particles N, pressure
    model (S, k, noise r), thresholds, weights scheme, Ns, sensing range (m), known target depth
    (2-D, m), resampling method."""

    dim: int = 2
    q: float = 1.0
    T: float = 1.0
    n_particles: int = 1000
    source_level: float = 5e4
    exponent: float = 1.0
    r: float = 5.0
    gammas: tuple[float, ...] = ()
    weights: WeightScheme = "gw"
    n_select: int = 3
    sensing_range_m: float = 160.0
    target_depth_m: float = 50.0
    resample: str = "systematic"


class MswpfTracker:
    """Algorithm 1 plus PCRLB selection, vectorized over particles and sensors.

    Cycle per interval k: ``predicted`` holds the particles of x_k given reports up to k-1;
    :meth:`select` picks the Ns sensors for k (eqs 35-36); sensors report (level, MI);
    :meth:`update` weights by eq 25 with the weights of eq 27, resamples, advances the PCRLB
    information with the sensors that did report, and predicts x_{k+1}.
    """

    def __init__(self, cfg: MswpfConfig, x0: ArrayLike, P0: ArrayLike, rng: np.random.Generator) -> None:
        self.cfg = cfg
        self.model = ConstantVelocityModel(dim=cfg.dim, dt=cfg.T, q=cfg.q)
        self.F, self.Q = self.model.F, self.model.Q  # built once (the model rebuilds them per access)
        self.rng = rng
        x0 = np.asarray(x0, dtype=float)
        P0 = np.asarray(P0, dtype=float)
        self.predicted: Array = rng.multivariate_normal(x0, P0, size=cfg.n_particles)
        self.logw: Array = np.full(cfg.n_particles, -np.log(cfg.n_particles))
        # PCRLB information of the current prediction; J_0 from the prior covariance
        self.J_prior: Array = np.linalg.inv(P0)
        self.mean: Array = x0.copy()
        self.cov: Array = P0.copy()
        self.gammas = np.asarray(cfg.gammas, dtype=float)

    def positions(self, X: ArrayLike | None = None) -> Array:
        """Target positions (N, 3) of particles (predicted by default); 2-D adds the known depth."""
        X = self.predicted if X is None else np.asarray(X, dtype=float)
        d = self.cfg.dim
        if d == 3:
            return np.asarray(X[:, :3])
        return np.column_stack([X[:, 0], X[:, 1], np.full(len(X), self.cfg.target_depth_m)])

    def candidates(self, sensors: ArrayLike, X: ArrayLike | None = None) -> NDArray[np.intp]:
        """Qualified candidates (eq 35): believed sensor positions within the sensing range of the
        predicted target position; if fewer than Ns qualify, the Ns nearest."""
        S = np.asarray(sensors, dtype=float)
        d = np.linalg.norm(S - self.positions(X).mean(axis=0), axis=1)
        inside = np.flatnonzero(d <= self.cfg.sensing_range_m)
        if inside.size >= self.cfg.n_select:
            return inside
        return np.sort(np.argsort(d, kind="stable")[: self.cfg.n_select])

    def information(self, sensors: ArrayLike, loc_std: ArrayLike, X: ArrayLike | None = None) -> Array:
        """Expected measurement FIM (S, n, n) of each sensor over predicted particles."""
        h, g = sensor_model(self.positions(X), sensors, self.cfg.source_level, self.cfg.exponent)
        rm = equivalent_std(self.cfg.r, g, loc_std)
        scale = quantized_fisher_scale(h, rm, self.gammas)
        d = self.cfg.dim
        return particle_information(g[..., :d], scale, np.arange(d), self.model.n)

    def select(
        self, sensors: ArrayLike, loc_std: ArrayLike, X: ArrayLike | None = None, J_prior: ArrayLike | None = None
    ) -> tuple[NDArray[np.intp], Array]:
        """Indices (into ``sensors``) of the Ns candidates maximizing det J_k (eq 36), and their
        expected FIMs (Ns, n, n) (reusable in :meth:`update`). ``X`` / ``J_prior``: predicted
        particles and prior information of the interval (default: the next one)."""
        S = np.asarray(sensors, dtype=float)
        Xp = self.predicted if X is None else np.asarray(X, dtype=float)
        Jp = self.J_prior if J_prior is None else np.asarray(J_prior, dtype=float)
        cand = self.candidates(S, Xp)
        infos = self.information(S[cand], np.asarray(loc_std, dtype=float)[cand], Xp)
        best = best_subset(Jp, infos, self.cfg.n_select)
        return np.asarray(cand[best]), infos[best]

    def lookahead(self, infos: ArrayLike) -> tuple[Array, Array]:
        """Particles and prior information two intervals ahead (for a network whose task must
        leave before the next fusion): the next prediction moved once more, and
        (Q + F (J_prior + expected info of the sensors already tasked)^-1 F^T)^-1."""
        X2 = propagate(self.predicted, self.model.transition, self.Q, self.rng)
        J1 = self.J_prior + np.asarray(infos, dtype=float).reshape(-1, self.model.n, self.model.n).sum(axis=0)
        return X2, predicted_information(J1, self.F, self.Q)

    def mi(self, sensors: ArrayLike, loc_std: ArrayLike) -> Array:
        """Predicted MI of sensors from the predicted particles (what the fusion centre would
        compute; the network's sensors compute their own from what the task packet carries)."""
        c = self.cfg
        return sensor_mi(self.positions(), sensors, loc_std, c.source_level, c.exponent, c.r, self.gammas)

    def update(
        self,
        sensors: ArrayLike,
        loc_std: ArrayLike,
        levels: ArrayLike,
        mi: ArrayLike,
        info: ArrayLike | None = None,
    ) -> tuple[Array, Array, Array]:
        """Fuse the reports that arrived (possibly none), then predict the next interval.

        ``info`` (S, n, n): the reporting sensors' expected FIMs if already computed at selection
        (same predicted particles); else computed here. Returns (fusion weights, posterior mean,
        posterior covariance) of x_k."""
        c = self.cfg
        S = np.asarray(sensors, dtype=float).reshape(-1, 3)
        loc = np.asarray(loc_std, dtype=float).reshape(-1)
        X = self.predicted
        info_sum = np.zeros_like(self.J_prior)
        if len(S):
            alpha = fusion_weights(mi, c.weights)
            h, g = sensor_model(self.positions(X), S, c.source_level, c.exponent)
            rm = equivalent_std(c.r, g, loc)
            loglik = weighted_log_likelihood(levels, h, rm, self.gammas, alpha)
            Xr, lw, mean, cov = sir_update(X, self.logw, loglik, self.rng, c.resample)
            if info is None:
                scale = quantized_fisher_scale(h, rm, self.gammas)
                info = particle_information(g[..., : c.dim], scale, np.arange(c.dim), self.model.n)
            info_sum = np.asarray(info, dtype=float).sum(axis=0)
        else:  # nothing arrived: the prediction is the estimate
            alpha = np.zeros(0)
            Xr, lw = X, self.logw
            w = np.exp(lw)
            mean = w @ X
            D = X - mean
            cov = (D * w[:, None]).T @ D
        self.mean, self.cov = mean, cov
        J_post = self.J_prior + info_sum
        self.J_prior = predicted_information(J_post, self.F, self.Q)
        self.J_post = J_post
        self.predicted = propagate(Xr, self.model.transition, self.Q, self.rng)
        self.logw = lw
        return alpha, mean, cov
