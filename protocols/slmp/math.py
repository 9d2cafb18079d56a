"""Pure maths of SLMP, the baseline of the STVF paper (no SimPy), shared by ``slmp`` and
``multilateration_all_refs``.

SLMP: Z. Zhou, Z. Peng, J.-H. Cui, Z. Shi, A. Bagtzoglou, "Scalable localization with
mobility prediction for underwater sensor networks", IEEE Trans. Mobile Computing 10(3),
2011 (INFOCOM 2008). Its text is not in our seeds: the parts below follow its published
outline and the STVF paper's account of how it was run (Sec. 5.3: 100 s of beacon training,
prediction window 60 s with 20 % overlap, prediction step 15, error threshold 5 % of the
range); docs/stvf.md lists what is our reading.

- Mobility prediction: a node's velocity sequence (finite differences of its positions, one
  per period) is modelled by a linear predictor v_k = sum_{i=1}^{p} a_i v_{k-i} per axis
  (order p = the prediction step), fitted by least squares over the latest window and refitted
  when the window has advanced by (1 - overlap) of its length or when the prediction error
  exceeds the threshold.
- Localization: multilateration (linear least squares, then Gauss-Newton) on the projected
  ranges to the reference nodes, with a confidence from the references' confidence and the
  fit residual; nodes above the confidence threshold become references.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "MobilityPredictor",
    "fit_linear_predictor",
    "in_range",
    "is_stable",
    "predict_velocities",
    "prediction_residual",
    "slmp_confidence",
]

Array = NDArray[np.float64]


def fit_linear_predictor(series: ArrayLike, order: int) -> Array:
    """Least-squares coefficients a (order, d) of v_k = sum_i a_i v_{k-i}, independently per
    axis, from a series (n, d) with n > 2 * order (so the system is overdetermined).
    ``a[0]`` multiplies the most recent sample."""
    v = np.asarray(series, float)
    n, d = v.shape
    if n <= 2 * order:
        raise ValueError(f"need more than {2 * order} samples for order {order}, got {n}")
    # rows: the ``order`` samples before each target, most recent first
    win = sliding_window_view(v[:-1], order, axis=0)[:, :, ::-1]  # (n - order, d, order)
    targets = v[order:]  # (n - order, d)
    coef = np.empty((order, d))
    for j in range(d):  # d = 2 axes, not a hot loop
        coef[:, j] = np.linalg.lstsq(win[:, j, :], targets[:, j], rcond=None)[0]
    return coef


def is_stable(coef: ArrayLike) -> bool:
    """True when every axis' recursion has all characteristic roots inside the unit circle."""
    a = np.asarray(coef, float)
    for j in range(a.shape[1]):
        roots = np.roots(np.r_[1.0, -a[:, j]])
        if roots.size and np.max(np.abs(roots)) >= 1.0:
            return False
    return True


def predict_velocities(history: ArrayLike, coef: ArrayLike, steps: int) -> Array:
    """Run the recursion ``steps`` samples ahead from the last ``order`` samples of ``history``
    (n, d); returns (steps, d)."""
    a = np.asarray(coef, float)
    order = a.shape[0]
    buf = list(np.asarray(history, float)[-order:][::-1])  # most recent first
    out = np.empty((steps, a.shape[1]))
    for k in range(steps):  # sequential by nature (each step feeds the next)
        nxt = np.einsum("id,id->d", a, np.asarray(buf[:order]))
        out[k] = nxt
        buf.insert(0, nxt)
    return out


class MobilityPredictor:
    """A node's own mobility pattern from its past positions (SLMP's linear prediction).

    ``add(t, xy)`` records a position (one per period, ``dt`` s apart); ``velocity()`` is the
    predicted velocity for the next period (m/s). The predictor is refitted on the latest
    ``window`` samples when ``window * (1 - overlap)`` new samples have arrived, or when the
    last one-step position prediction missed by more than ``threshold`` m. An unstable fit
    (roots outside the unit circle: noisy position estimates can give one) falls back to
    the window's mean velocity. ``max_speed`` (m/s, None = no cap): a predicted velocity
    faster than this is scaled down to it (a node drifting in a current moves no faster than
    the current; a stable AR fit to noisy velocities can still predict tens of m/s).
    """

    def __init__(
        self,
        dt: float,
        window: int = 60,
        overlap: float = 0.2,
        order: int = 15,
        threshold: float = 4.0,
        max_speed: float | None = None,
    ) -> None:
        self.dt = float(dt)
        self.max_speed = None if max_speed is None else float(max_speed)
        self.window = int(window)
        self.order = int(order)
        self.refit_every = max(1, int(round(self.window * (1.0 - overlap))))
        self.threshold = float(threshold)
        self.times: list[float] = []
        self.positions: list[Array] = []
        self.coef: Array | None = None
        self.mean_velocity: Array | None = None
        self._since_fit = 0
        self.refits = 0

    def velocities(self) -> Array:
        """Finite-difference velocities (n - 1, 2) of the recorded positions (m/s)."""
        t = np.asarray(self.times)
        p = np.asarray(self.positions)
        if len(t) < 2:
            return np.empty((0, 2))
        return np.diff(p, axis=0) / np.diff(t)[:, None]

    def add(self, t: float, xy: ArrayLike) -> None:
        xy = np.asarray(xy, float)
        miss = False
        if self.times and t > self.times[-1]:
            pred = self.positions[-1] + self.velocity() * (t - self.times[-1])
            miss = bool(np.linalg.norm(pred - xy) > self.threshold)
        self.times.append(float(t))
        self.positions.append(xy)
        keep = self.window + 1
        if len(self.times) > keep:
            del self.times[:-keep]
            del self.positions[:-keep]
        self._since_fit += 1
        if self.coef is None or self._since_fit >= self.refit_every or miss:
            self._fit()

    def _fit(self) -> None:
        v = self.velocities()
        if len(v) == 0:
            return
        self.mean_velocity = v.mean(axis=0)
        self._since_fit = 0
        if len(v) > 2 * self.order:
            coef = fit_linear_predictor(v, self.order)
            self.coef = coef if is_stable(coef) else None
            self.refits += 1

    def velocity(self) -> Array:
        """Predicted velocity (m/s) over the next period (at most ``max_speed``)."""
        v = self.velocities()
        if len(v) == 0:
            return np.zeros(2)
        if self.coef is not None and len(v) >= self.order:
            out = predict_velocities(v, self.coef, 1)[0]
        else:
            out = self.mean_velocity if self.mean_velocity is not None else v[-1]
        if self.max_speed is not None:
            speed = float(np.hypot(out[0], out[1]))
            if speed > self.max_speed:
                out = out * (self.max_speed / speed)
        return out

    def predict(self, t: float) -> Array | None:
        """Predicted position at time ``t`` (m): last position + predicted velocity x elapsed."""
        if not self.times:
            return None
        return self.positions[-1] + self.velocity() * (t - self.times[-1])


def slmp_confidence(ref_confidence: ArrayLike, position: ArrayLike, refs: ArrayLike, ranges: ArrayLike) -> float:
    """Confidence of a multilateration fix: mean reference confidence times
    (1 - sum_i | ||x - a_i|| - r_i | / sum_i r_i), clipped to [0, 1]."""
    rho = np.linalg.norm(np.asarray(position, float) - np.asarray(refs, float), axis=1)
    r = np.asarray(ranges, float)
    denom = r.sum()
    if denom <= 0:
        return 0.0
    eta = float(np.mean(np.asarray(ref_confidence, float))) * (1.0 - np.abs(rho - r).sum() / denom)
    return float(np.clip(eta, 0.0, 1.0))


def prediction_residual(position: ArrayLike, refs: ArrayLike, ranges: ArrayLike) -> float:
    """RMS range residual (m) of a position against measured ranges to references:
    sqrt(mean_i (||x - a_i|| - r_i)^2). SLMP's test of whether a predicted position still
    agrees with what the node hears (a prediction off by d gives about d / sqrt(2))."""
    rho = np.linalg.norm(np.asarray(position, float) - np.asarray(refs, float), axis=-1)
    return float(np.sqrt(np.mean((rho - np.asarray(ranges, float)) ** 2)))


def in_range(position: ArrayLike, refs: ArrayLike, range_m: float, range_std_m: float) -> bool:
    """Whether a fix lies within ``range_m`` (m) of every reference (n, 2), up to 3 std of a
    range measured at ``range_m`` (``range_std_m``, m). A node hears only references in range,
    so a fix well beyond that from one of them is a failed one (ill-conditioned geometry); a
    good fix of a node near the edge of a reference's range exceeds it by its ranging noise."""
    rho = np.linalg.norm(np.asarray(refs, float) - np.asarray(position, float), axis=-1)
    return bool(np.all(rho <= range_m + 3.0 * range_std_m))
