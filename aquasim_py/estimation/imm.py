"""Interacting multiple model (IMM) estimator: any number of motion models, each filtered by
a Kalman filter (linear model) or an extended Kalman filter (nonlinear model).

Why our own: filterpy's ``IMMEstimator`` cannot mix a linear KF and an EKF without wrapper
classes, and requires every model to share one state vector; Stone Soup has no IMM. This one
works on plain (x, P) arrays through :mod:`.kalman`.

State embedding (models of different dimension). All models live in one *joint* state space
of size ``n`` (for CV + CT: the CT layout ``[p, v, omega]``). Model j uses the components
``index[j]`` of the joint state (CV: the first 2d; CT: all). To mix, each model's estimate is
embedded in the joint space with the missing components set to ``fill_mean`` (0: a CV target
does not turn) and variance ``fill_var`` (default 0: the CV hypothesis asserts omega = 0 exactly;
the turn model's own process noise supplies the spread it needs); the mixed joint estimate is
then restricted back to each model's components. Measurements are written once, on the joint
state; each model sees them through its embedding, so a position measurement means the same
thing to every model.

Cycle (Bar-Shalom, Li, Kirubarajan, *Estimation with Applications to Tracking*, ch. 11.6):
:meth:`IMM.predict` does mixing and model-matched prediction, :meth:`IMM.update` the
model-matched updates, model-probability update and combination.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._linalg import symmetrize
from .kalman import ekf_predict, ekf_update, kf_predict, kf_update
from .motion import MotionModel

__all__ = ["IMM", "IMMModel"]

Array = NDArray[np.float64]
IndexArray = NDArray[np.intp]


@dataclass(frozen=True)
class IMMModel:
    """One mode: its motion model and which joint-state components it uses."""

    motion: MotionModel
    index: IndexArray  #: int indices into the joint state, length motion.n


class IMM:
    """IMM over ``models`` with Markov transition matrix ``transition`` (rows sum to 1:
    ``transition[i, j]`` = P(mode j at k | mode i at k-1)).

    ``x0``/``P0`` are in the joint space (size ``n``); ``mu0`` the initial mode probabilities.
    After construction and each call, ``x``/``P`` hold the combined joint estimate, ``mu`` the
    mode probabilities, ``xs``/``Ps`` the model-matched estimates (model dimensions).
    """

    def __init__(
        self,
        models: Sequence[MotionModel | IMMModel],
        transition: ArrayLike,
        x0: ArrayLike,
        P0: ArrayLike,
        mu0: ArrayLike | None = None,
        *,
        fill_mean: ArrayLike | float = 0.0,
        fill_var: ArrayLike | float = 0.0,
    ) -> None:
        x0 = np.asarray(x0, dtype=float).reshape(-1)
        P0 = np.asarray(P0, dtype=float)
        self.n = x0.size
        if P0.shape != (self.n, self.n):
            raise ValueError(f"P0 must be ({self.n}, {self.n}), got {P0.shape}")
        self.models: list[IMMModel] = []
        for m in models:
            if isinstance(m, MotionModel):
                # default embedding: the model's state is the leading part of the joint state
                m = IMMModel(m, np.arange(m.n))
            idx = np.asarray(m.index, dtype=int)
            if idx.size != m.motion.n or np.any(idx < 0) or np.any(idx >= self.n) or np.unique(idx).size != idx.size:
                raise ValueError(
                    f"model {type(m.motion).__name__}: index must be {m.motion.n} distinct joint indices < {self.n}"
                )
            self.models.append(IMMModel(m.motion, idx))
        r = len(self.models)
        if r < 1:
            raise ValueError("IMM needs at least one model")
        Pi = np.asarray(transition, dtype=float)
        if Pi.shape != (r, r) or np.any(Pi < 0) or not np.allclose(Pi.sum(axis=1), 1.0):
            raise ValueError(f"transition must be a ({r}, {r}) row-stochastic matrix")
        self.transition = Pi
        mu = np.full(r, 1.0 / r) if mu0 is None else np.asarray(mu0, dtype=float).reshape(-1)
        if mu.shape != (r,) or np.any(mu < 0) or not np.isclose(mu.sum(), 1.0):
            raise ValueError(f"mu0 must be {r} probabilities summing to 1")
        self.mu = mu / mu.sum()
        self.fill_mean = np.broadcast_to(np.asarray(fill_mean, dtype=float), (self.n,)).copy()
        self.fill_var = np.broadcast_to(np.asarray(fill_var, dtype=float), (self.n,)).copy()
        self.xs = [x0[m.index].copy() for m in self.models]
        self.Ps = [P0[np.ix_(m.index, m.index)].copy() for m in self.models]
        self.log_likelihoods = np.zeros(r)
        self._combine()

    # -- embedding -----------------------------------------------------------------------
    def _embed(self, j: int, x: Array, P: Array) -> tuple[Array, Array]:
        idx = self.models[j].index
        X = self.fill_mean.copy()
        PP = np.diag(self.fill_var)
        X[idx] = x
        PP[np.ix_(idx, idx)] = P
        return X, PP

    def _embed_all(self) -> tuple[Array, Array]:
        X = np.empty((len(self.models), self.n))
        PP = np.empty((len(self.models), self.n, self.n))
        for j in range(len(self.models)):
            X[j], PP[j] = self._embed(j, self.xs[j], self.Ps[j])
        return X, PP

    @staticmethod
    def _moment_match(w: Array, X: Array, PP: Array) -> tuple[Array, Array]:
        """Mean and covariance of the Gaussian mixture sum_j w_j N(X_j, PP_j)."""
        m = w @ X
        D = X - m
        return m, symmetrize(np.einsum("j,jab->ab", w, PP) + np.einsum("j,ja,jb->ab", w, D, D))

    def _combine(self) -> None:
        X, PP = self._embed_all()
        self.x, self.P = self._moment_match(self.mu, X, PP)

    # -- cycle ---------------------------------------------------------------------------
    def predict(self) -> None:
        """Mixing (interaction) and model-matched prediction."""
        c = self.mu @ self.transition  # predicted mode probabilities
        if np.any(c <= 0):
            c = np.maximum(c, np.finfo(float).tiny)
        W = self.mu[:, None] * self.transition / c[None, :]  # W[i, j] = P(i at k-1 | j at k)
        X, PP = self._embed_all()
        for j, m in enumerate(self.models):
            xm, Pm = self._moment_match(W[:, j], X, PP)
            xj, Pj = xm[m.index], Pm[np.ix_(m.index, m.index)]
            mot = m.motion
            if mot.linear:
                self.xs[j], self.Ps[j] = kf_predict(xj, Pj, mot.F, mot.Q)
            else:
                self.xs[j], self.Ps[j] = ekf_predict(xj, Pj, mot.transition, mot.jacobian, mot.Q)
        self.mu = c / c.sum()
        self._combine()

    def _model_measurement(
        self, j: int, h: Callable[[Array], Array], H_jac: Callable[[Array], Array]
    ) -> tuple[Callable[[Array], Array], Callable[[Array], Array]]:
        """``h`` and its Jacobian as model j sees them: of its state embedded in the joint one."""
        idx = self.models[j].index

        def hj(xj: Array) -> Array:
            return h(self._embed(j, xj, self.Ps[j])[0])

        def Hjj(xj: Array) -> Array:
            return np.atleast_2d(H_jac(self._embed(j, xj, self.Ps[j])[0]))[:, idx]

        return hj, Hjj

    def update(
        self,
        z: ArrayLike,
        R: ArrayLike,
        *,
        H: ArrayLike | None = None,
        h: Callable[[Array], Array] | None = None,
        H_jac: Callable[[Array], Array] | None = None,
    ) -> None:
        """Model-matched updates with a measurement on the joint state, then mode probabilities
        and combination. Give either a matrix ``H`` (m, n) for z = H x + v, or ``h`` and its
        Jacobian ``H_jac`` (functions of the joint state) for z = h(x) + v."""
        # the measurement: a matrix (m, n), or (h, H_jac)
        meas: Array | tuple[Callable[[Array], Array], Callable[[Array], Array]]
        if H is not None and h is None:
            meas = np.atleast_2d(np.asarray(H, dtype=float))
        elif H is None and h is not None:
            if H_jac is None:
                raise ValueError("h needs its Jacobian H_jac")
            meas = (h, H_jac)
        else:
            raise ValueError("give either H or (h, H_jac)")
        ll = np.empty(len(self.models))
        for j, m in enumerate(self.models):
            idx = m.index
            if isinstance(meas, np.ndarray):
                Hj = meas[:, idx]
                res = kf_update(self.xs[j], self.Ps[j], z, Hj, R)
            else:
                hj, Hjj = self._model_measurement(j, *meas)
                res = ekf_update(self.xs[j], self.Ps[j], z, hj, Hjj, R)
            self.xs[j], self.Ps[j], ll[j] = res.x, res.P, res.log_likelihood
        self.log_likelihoods = ll
        # Bayes on the modes in log space: likelihoods of a good fit can underflow exp()
        logp = np.log(np.maximum(self.mu, np.finfo(float).tiny)) + ll
        logp -= logp.max()
        p = np.exp(logp)
        self.mu = p / p.sum()
        self._combine()
