"""Sound-speed uncertainty: the water a packet crosses is not exactly the nominal profile.

Pure numpy, no SimPy. The channel (``channel/acoustic.py``) asks :class:`SoundSpeedUncertainty`
for one speed deviation per (packet, receiver) and stretches the profile's travel time with
:func:`perturbed_delay`; protocols keep converting delays with their nominal speed, so the
deviation shows up as a range error of range x dc / c.

Model (documented choice, docs/stvf.md): each link i-j carries a deviation dc_ij(t) (m/s) of
the path-mean sound speed from the profile's, a stationary Ornstein-Uhlenbeck process with std
``std_mps`` and correlation time ``corr_s``: dc(t + dt) = rho dc(t) + sqrt(1 - rho^2) std xi,
rho = exp(-dt / corr_s). Both directions of a link share the state (they cross the same
water). ``corr_s = 0`` (the default) draws every packet independently: the ToA model of Hu et
al. (Sensors 2018, Sec. 5.1: speed N(1500, 10^2) per measurement). A positive ``corr_s``
models the slowly varying field of internal waves and mixing (minutes), under which
consecutive ranges on one link share most of their error.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["SoundSpeedUncertainty", "ou_step", "perturbed_delay"]

Array = NDArray[np.float64]


def perturbed_delay(delay_s: ArrayLike, c_ref_mps: ArrayLike, dc_mps: ArrayLike) -> Array:
    """Travel time (s) through water whose path-mean speed is ``c_ref + dc`` instead of ``c_ref``.

    The ray length L = delay x c_ref is kept (a 1 % speed change bends the ray by a
    second-order amount), so the delay becomes L / (c_ref + dc) = delay x c_ref / (c_ref + dc).
    NaN delays (no path) stay NaN; dc = 0 returns ``delay`` bit for bit."""
    t = np.asarray(delay_s, float)
    c = np.asarray(c_ref_mps, float)
    dc = np.asarray(dc_mps, float)
    return np.where(dc == 0.0, t, t * (c / (c + dc)))


def ou_step(previous: ArrayLike, dt_s: ArrayLike, corr_s: float, std: float, xi: ArrayLike) -> Array:
    """One exact Ornstein-Uhlenbeck transition over ``dt_s`` from ``previous`` with standard
    normals ``xi`` (stationary std ``std``); ``corr_s = 0`` or infinite ``dt`` gives fresh draws."""
    x0 = np.asarray(previous, float)
    z = np.asarray(xi, float)
    if corr_s <= 0.0:
        return std * z
    rho = np.exp(-np.asarray(dt_s, float) / corr_s)
    return rho * x0 + np.sqrt(1.0 - rho**2) * std * z


class SoundSpeedUncertainty:
    """Per-link sound-speed deviations (m/s) for the channel, from one keyed random stream.

    ``deviations(t, src, receivers)`` returns dc for the packet ``src`` sends at true time
    ``t`` to each receiver (ints). State is an (n, n) table grown on demand (vectorized over
    the receivers of a packet; no loop over node pairs)."""

    def __init__(self, std_mps: float, corr_s: float, rng: np.random.Generator) -> None:
        if not (math.isfinite(std_mps) and std_mps >= 0.0):
            raise ValueError(f"sound-speed std must be >= 0 and finite, got {std_mps!r}")
        if not corr_s >= 0.0:
            raise ValueError(f"sound-speed correlation time must be >= 0, got {corr_s!r}")
        self.std = float(std_mps)
        self.corr = float(corr_s)
        self.rng = rng
        self._dc = np.zeros((0, 0))
        self._t = np.zeros((0, 0))

    def _grow(self, n: int) -> None:
        m = self._dc.shape[0]
        if n <= m:
            return
        dc = np.zeros((n, n))
        t = np.full((n, n), -np.inf)  # never drawn: the first draw is from the stationary law
        dc[:m, :m] = self._dc
        t[:m, :m] = self._t
        self._dc, self._t = dc, t

    def deviations(self, t: float, src: int, receivers: NDArray[np.intp]) -> Array:
        xi = self.rng.standard_normal(receivers.size)
        if self.corr <= 0.0:
            return self.std * xi
        self._grow(max(int(src), int(receivers.max(initial=0))) + 1)
        i = np.minimum(src, receivers)
        j = np.maximum(src, receivers)
        new = ou_step(self._dc[i, j], t - self._t[i, j], self.corr, self.std, xi)
        self._dc[i, j] = new
        self._t[i, j] = t
        return new

    def apply(
        self,
        delay_s: Array,
        t: float,
        src: int,
        receivers: NDArray[np.intp],
        c_ref_mps: ArrayLike,
    ) -> Array:
        """The delays of one packet to ``receivers``, through the perturbed water."""
        return perturbed_delay(delay_s, c_ref_mps, self.deviations(t, src, receivers))
