"""Discrete-time motion models for tracking: constant velocity (CV) and coordinated turn (CT)
with unknown turn rate, in 2-D and 3-D.

State layouts (positions first, as in Ramezani et al. s = [x^T, xdot^T]^T, eq 38):

- CV: ``[p_1..p_d, v_1..v_d]`` (n = 2d)
- CT: ``[p_1..p_d, v_1..v_d, omega]`` (n = 2d + 1), turning in the horizontal (x, y) plane at
  omega rad/s (positive = counter-clockwise seen from above in x-y); in 3-D the depth moves
  with constant velocity.

So a CV state is the leading 2d entries of the CT state of the same dimension: the IMM embeds
CV into CT by appending omega = 0 (see :mod:`.imm`).

Process noise: continuous white-noise acceleration of spectral density ``q`` (m^2/s^3) on each
axis, discretized exactly for the CV model; the CT model uses the same position/velocity block
(the usual approximation, exact for omega = 0) plus a turn-rate random walk of density
``q_turn`` (rad^2/s^3).

These are a filter's *transition models* (F, Q, Jacobians). The trajectories that nodes really
follow (ground truth) are :mod:`aquasim_py.mobility`'s ``ConstantVelocity`` / ``CoordinatedTurn``:
hence the ``...Model`` names here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["ConstantVelocityModel", "CoordinatedTurnModel", "MotionModel", "cv_matrices", "cwna_noise"]

Array = NDArray[np.float64]
IndexArray = NDArray[np.intp]


def _kron(a: Array, b: Array) -> Array:
    # numpy's stubs type kron of two float64 arrays as NDArray[floating]; it is float64
    return cast(Array, np.kron(a, b))


def cwna_noise(dim: int, dt: float, q: float) -> Array:
    """Continuous white-noise acceleration covariance for the CV layout [p, v] (2d x 2d)."""
    blk = np.array([[dt**3 / 3.0, dt**2 / 2.0], [dt**2 / 2.0, dt]]) * q
    return _kron(blk, np.eye(dim))


def cv_matrices(dim: int, dt: float, q: float) -> tuple[Array, Array]:
    """(F, Q) of the CV model in the layout [p, v] (Ramezani's Phi and Q_k, eq 38)."""
    F = _kron(np.array([[1.0, dt], [0.0, 1.0]]), np.eye(dim))
    return F, cwna_noise(dim, dt, q)


def _check_dim(dim: int) -> int:
    if dim not in (2, 3):
        raise ValueError(f"dim must be 2 or 3, got {dim!r}")
    return dim


@dataclass(frozen=True)
class MotionModel:
    """Common interface: ``transition(x)`` (vectorized over leading axes), ``jacobian(x)``,
    process noise ``Q``, and whether the model is linear (then ``F`` is its matrix)."""

    dim: int
    dt: float

    @property
    def n(self) -> int:
        raise NotImplementedError

    @property
    def Q(self) -> Array:
        raise NotImplementedError

    linear: bool = field(default=False, init=False)

    def transition(self, x: ArrayLike) -> Array:
        raise NotImplementedError

    def jacobian(self, x: ArrayLike) -> Array:
        raise NotImplementedError

    @property
    def F(self) -> Array:
        """Transition matrix (linear models only)."""
        raise NotImplementedError(f"{type(self).__name__} is not linear: it has no transition matrix")

    @property
    def position_index(self) -> IndexArray:
        return np.arange(self.dim)

    @property
    def velocity_index(self) -> IndexArray:
        return np.arange(self.dim, 2 * self.dim)


@dataclass(frozen=True)
class ConstantVelocityModel(MotionModel):
    """Nearly constant velocity, state [p, v]; ``q`` in m^2/s^3."""

    q: float = 1e-3
    linear: bool = field(default=True, init=False)

    def __post_init__(self) -> None:
        _check_dim(self.dim)

    @property
    def n(self) -> int:
        return 2 * self.dim

    @property
    def F(self) -> Array:
        return cv_matrices(self.dim, self.dt, self.q)[0]

    @property
    def Q(self) -> Array:
        return cwna_noise(self.dim, self.dt, self.q)

    def transition(self, x: ArrayLike) -> Array:
        # p + dt v written out: equals F x exactly, and avoids a tall-skinny BLAS call that is
        # slow for (M, n) particle arrays
        x = np.asarray(x, dtype=float)
        out = x.copy()
        out[..., : self.dim] += self.dt * x[..., self.dim :]
        return out

    def jacobian(self, x: ArrayLike) -> Array:
        return self.F


# Below this |omega dt| the turn coefficients use their Taylor series: the closed forms lose
# ~eps/(omega dt)^3 relative accuracy through cancellation; the series kept here are accurate
# to ~(omega dt)^10/10! there, so both sides are at round-off level at the switch.
_SERIES_BELOW = 0.1


def _turn_coefficients(w: Array, T: float) -> tuple[Array, Array, Array, Array]:
    """s = sin(wT)/w, c = (1 - cos(wT))/w and their derivatives ds/dw, dc/dw (limits at w = 0)."""
    u = w * T
    small = np.abs(u) < _SERIES_BELOW
    ws = np.where(small, 1.0, w)  # avoids 0/0 in the branch that np.where discards
    us = ws * T
    sn, cs = np.sin(us), np.cos(us)
    s_cf = sn / ws
    c_cf = (1.0 - cs) / ws
    ds_cf = (us * cs - sn) / ws**2
    dc_cf = (us * sn - (1.0 - cs)) / ws**2
    u2 = u * u
    # sin(u)/u, (1-cos u)/u, and their u-derivatives as alternating series in u
    s_se = T * (1 - u2 / 6 * (1 - u2 / 20 * (1 - u2 / 42 * (1 - u2 / 72))))
    c_se = T * u / 2 * (1 - u2 / 12 * (1 - u2 / 30 * (1 - u2 / 56 * (1 - u2 / 90))))
    # d/dw = T d/du; d/du[sin u / u] = -u/3 + u^3/30 - u^5/840 + u^7/45360
    ds_se = T * T * (-u / 3 + u * u2 / 30 - u * u2**2 / 840 + u * u2**3 / 45360)
    # d/du[(1-cos u)/u] = 1/2 - u^2/8 + u^4/144 - u^6/5760 + u^8/403200
    dc_se = T * T * (0.5 - u2 / 8 + u2**2 / 144 - u2**3 / 5760 + u2**4 / 403200)
    return (
        np.where(small, s_se, s_cf),
        np.where(small, c_se, c_cf),
        np.where(small, ds_se, ds_cf),
        np.where(small, dc_se, dc_cf),
    )


@dataclass(frozen=True)
class CoordinatedTurnModel(MotionModel):
    """Coordinated turn with unknown turn rate, state [p, v, omega] (EKF model).

    ``q`` (m^2/s^3): acceleration noise density on each axis; ``q_turn`` (rad^2/s^3):
    turn-rate random-walk density.
    """

    q: float = 1e-3
    q_turn: float = 1e-6

    def __post_init__(self) -> None:
        _check_dim(self.dim)

    @property
    def n(self) -> int:
        return 2 * self.dim + 1

    @property
    def Q(self) -> Array:
        Q = np.zeros((self.n, self.n))
        Q[:-1, :-1] = cwna_noise(self.dim, self.dt, self.q)
        Q[-1, -1] = self.q_turn * self.dt
        return Q

    def transition(self, x: ArrayLike) -> Array:
        x = np.asarray(x, dtype=float)
        d, T = self.dim, self.dt
        w = x[..., -1]
        s, c, _, _ = _turn_coefficients(w, T)
        cw, sw = np.cos(w * T), np.sin(w * T)
        vx, vy = x[..., d], x[..., d + 1]
        out = x.copy()
        out[..., 0] = x[..., 0] + s * vx - c * vy
        out[..., 1] = x[..., 1] + c * vx + s * vy
        out[..., d] = cw * vx - sw * vy
        out[..., d + 1] = sw * vx + cw * vy
        if d == 3:
            out[..., 2] = x[..., 2] + T * x[..., 5]
        return out

    def jacobian(self, x: ArrayLike) -> Array:
        x = np.asarray(x, dtype=float).reshape(-1)
        d, T = self.dim, self.dt
        w = x[-1]
        s, c, ds, dc = (float(v) for v in _turn_coefficients(np.asarray(w), T))
        cw, sw = np.cos(w * T), np.sin(w * T)
        vx, vy = x[d], x[d + 1]
        F = np.eye(self.n)
        F[0, d], F[0, d + 1], F[0, -1] = s, -c, ds * vx - dc * vy
        F[1, d], F[1, d + 1], F[1, -1] = c, s, dc * vx + ds * vy
        F[d, d], F[d, d + 1], F[d, -1] = cw, -sw, -T * (sw * vx + cw * vy)
        F[d + 1, d], F[d + 1, d + 1], F[d + 1, -1] = sw, cw, T * (cw * vx - sw * vy)
        if d == 3:
            F[2, 5] = T
        return F
