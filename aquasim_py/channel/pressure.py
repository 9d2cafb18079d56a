"""Received acoustic pressure of a sound source (Zhang et al., MSWPF, eq 6), pure numpy.

h = S / D^k with D^2 = |p_src - p_rx|^2 (squared distance including the depth offset): S is
the source-level pressure and k the decay exponent (k = 1 is spherical spreading of the
pressure amplitude; the paper's printed exponent is not legible, so it is a parameter).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["received_pressure", "received_pressure_and_gradient", "received_pressure_gradient"]

Array = NDArray[np.float64]


def received_pressure(src: ArrayLike, rx: ArrayLike, source_level: float, exponent: float = 1.0) -> Array:
    """h = S / (|src - rx|^2)^(k/2) (eq 6), src/rx (..., 3) in m -> (...)."""
    d = np.asarray(src, dtype=float) - np.asarray(rx, dtype=float)
    d2 = np.einsum("...i,...i->...", d, d)
    return np.asarray(source_level / d2 ** (0.5 * exponent), dtype=float)


def received_pressure_gradient(src: ArrayLike, rx: ArrayLike, source_level: float, exponent: float = 1.0) -> Array:
    """dh/d src (..., 3): -k S (src - rx) / D^(k+2). The gradient w.r.t. rx is its negative."""
    return received_pressure_and_gradient(src, rx, source_level, exponent)[1]


def received_pressure_and_gradient(
    src: ArrayLike, rx: ArrayLike, source_level: float, exponent: float = 1.0
) -> tuple[Array, Array]:
    """h (...) and dh/d src (..., 3) = -k h (src - rx) / D^2 together, sharing the distance
    terms (a particle filter needs both for every particle)."""
    d = np.asarray(src, dtype=float) - np.asarray(rx, dtype=float)
    d2 = d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2]
    h = source_level / (np.sqrt(d2) if exponent == 1.0 else d2 ** (0.5 * exponent))
    return h, (-exponent * h / d2)[..., None] * d
