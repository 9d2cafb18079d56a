"""Closed-form eigenrays for an isogradient sound-speed profile c(z) = b + a z.

Ramezani, Jamali-Rad and Leus (IEEE TSP 2013), eqs 1-26. Depth z is positive down (m), b is
the surface speed (m/s), a the gradient (1/s, any sign). All functions are pure numpy and
broadcast over any leading shape of ``src``/``dst`` (..., 3); ``b`` and ``a`` may be scalars
or arrays broadcasting with that leading shape.

Why these forms rather than the paper's angle-first recipe (eqs 10-13): with h = c(z)/|a|
(the distance to the depth where c would vanish) the slowness is 1/(|a| h), which is the
Poincare half-plane metric scaled by 1/|a|. Eigenrays are its geodesics, i.e. the circular
arcs of the paper, and the travel time is the hyperbolic distance over |a|:

    t = (2/|a|) asinh(|a| D / (2 sqrt(c1 c2)))                      (equivalent to eq 13)

with D the Euclidean distance and c1, c2 the end-point speeds. It has no difference of large
numbers: asinh(y) ~ y keeps full relative precision for tiny y, so the factor a cancels in
floating point too, and equal depths (eq 12), one node above the other (eq 14), a -> 0
(t -> D / c) and a < 0 all come out of one expression to a few ulps. The angles follow from the circle through
both end points (centre on the c = 0 line): with R the horizontal range, dz = z2 - z1 and
S = c1 + c2,

    tan(theta_1) = (a R^2 + dz S) / (2 R c1),   tan(theta_2) = (dz S - a R^2) / (2 R c2),

which satisfy Snell's law (eq 3) and the geometry of eqs 8-11 identically. The arc length
(eq 19, l = (theta_1 - theta_2) / (a xi)) is evaluated with tan(theta_1 - theta_2) = 2 R a S D^2
/ (4 R^2 c1 c2 + N1 N2), where the factor a cancels analytically.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .rays import Eigenray, PathKind

__all__ = [
    "arc_length",
    "eigenray",
    "straight_line_time",
    "travel_time",
    "travel_time_gradient",
    "turning_depth",
]

FloatArray = NDArray[np.float64]

_F = TypeVar("_F", bound=Callable[..., Any])


def _quiet(fn: _F) -> _F:
    """Run ``fn`` with numpy's divide / invalid / overflow warnings off: the forms below divide
    by zero and take the root of negatives on purpose and select the valid results (one
    ``np.errstate`` per public call, not one per helper)."""

    @functools.wraps(fn)
    def quiet(*args: Any, **kwargs: Any) -> Any:
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            return fn(*args, **kwargs)

    return quiet  # type: ignore[return-value]


def _split(src: ArrayLike, dst: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """(dx, dy, z1, z2, R^2) for broadcast src/dst (..., 3)."""
    s = np.asarray(src, dtype=float)
    d = np.asarray(dst, dtype=float)
    if s.shape[-1:] != (3,) or d.shape[-1:] != (3,):
        raise ValueError("src and dst must have a last axis of length 3 (x, y, z)")
    dx = d[..., 0] - s[..., 0]
    dy = d[..., 1] - s[..., 1]
    z1 = s[..., 2]
    z2 = d[..., 2]
    if z1.shape != z2.shape:
        z1, z2 = np.broadcast_arrays(z1, z2)
    return dx, dy, z1, z2, dx * dx + dy * dy


def _profile(b: ArrayLike, a: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Surface speed b (m/s) and gradient a (1/s) as float arrays (0-d for scalars)."""
    return np.asarray(b, dtype=float), np.asarray(a, dtype=float)


def _ratio(num: FloatArray, den: FloatArray, at_zero: float = 1.0) -> FloatArray:
    """num / den, with ``at_zero`` where den == 0 (the removable singularities below). The
    division runs everywhere (its warnings are off, :func:`_quiet`)."""
    return np.where(den != 0.0, num / den, at_zero)


# Below this |a| the arc equals the straight line to far beyond double precision
# ((a D / c)^2 < 1e-390), and 2/|a| could overflow: treat it as a = 0.
_A_TINY = 1e-200


def _time(a: FloatArray, D: FloatArray, c1: FloatArray, c2: FloatArray) -> FloatArray:
    """Arc travel time (s): (2/|a|) asinh(y), y = |a| D / (2 sqrt(c1 c2)) (equivalent to eq 13).

    No cancellation: asinh keeps full relative precision for tiny y, so for |a| -> 0 this is
    D / sqrt(c1 c2) to a few ulps (the products and quotients only add rounding).
    """
    g = np.sqrt(c1 * c2)
    if np.ndim(a) == 0:
        a0 = abs(float(a))
        if a0 < _A_TINY:
            return D / g
        return np.arcsinh(D * (0.5 * a0) / g) * (2.0 / a0)
    aa = np.abs(a)
    aa = np.where(aa < _A_TINY, 0.0, aa)
    return np.where(aa > 0.0, 2.0 * np.arcsinh(aa * D / (2.0 * g)) / aa, D / g)


def _turning(
    a: FloatArray, R2: FloatArray, dz: FloatArray, z1: FloatArray, c1: FloatArray, S: FloatArray
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Depth of the arc's vertex (eqs 21-22) and whether it lies strictly between the end points.

    The vertex is strictly inside the arc iff theta_1 theta_2 < 0, i.e. |dz| S < |a| R^2.
    Its depth z1 + (c1/a)(1/cos(theta_1) - 1) is written as z1 + c1 T^2 / (a (1 + sqrt(1 + T^2)))
    with T = tan(theta_1) to avoid the difference of nearly equal numbers.
    """
    has = np.abs(dz) * S < np.abs(a) * R2
    N1 = a * R2 + dz * S
    T2 = _ratio(N1 * N1, 4.0 * R2 * c1 * c1, 0.0)
    zv = z1 + _ratio(c1 * T2, a * (1.0 + np.sqrt(1.0 + T2)), 0.0)
    return np.where(has, zv, np.nan), has


def _blocked(
    a: FloatArray,
    b: FloatArray,
    z1: FloatArray,
    z2: FloatArray,
    zv: FloatArray | float,
    c1: FloatArray,
    c2: FloatArray,
    bottom: float | None,
) -> NDArray[np.bool_]:
    """True where the direct arc is not in the water column [0, bottom] or the speed is not positive.

    ``zv`` is the turning depth (NaN where none; NaN compares False).
    """
    if np.ndim(a) == 0 and np.ndim(b) == 0 and float(b) > 0.0:
        # scalar profile: c > 0 <=> z above the depth -b/a where c vanishes (a < 0 only)
        af, bf = float(a), float(b)
        bad = np.minimum(z1, z2) < 0.0
        if af < 0.0 or bottom is not None:
            z_hi = np.maximum(z1, z2)
            if af < 0.0:
                bad |= z_hi >= -bf / af
                bad |= zv < 0.0  # with a < 0 the vertex is the shallowest point
            if bottom is not None:
                bad |= z_hi > bottom
                if af > 0.0:
                    bad |= zv > bottom  # with a > 0 it is the deepest
        return bad
    bad = (z1 < 0.0) | (z2 < 0.0) | ~(c1 > 0.0) | ~(c2 > 0.0)
    bad |= zv < 0.0
    if bottom is not None:
        bad |= (z1 > bottom) | (z2 > bottom) | (zv > bottom)
    return bad


def _vertex_if_needed(
    a: FloatArray, R2: FloatArray, dz: FloatArray, z1: FloatArray, c1: FloatArray, c2: FloatArray, bottom: float | None
) -> FloatArray | float:
    """Turning depth for the water-column check, skipped (NaN) when it cannot matter: with
    a > 0 the vertex is the deepest point of the arc, so without a bottom it never leaves."""
    if bottom is None and not (float(a) < 0.0 if np.ndim(a) == 0 else bool((a < 0.0).any())):
        return np.nan
    return _turning(a, R2, dz, z1, c1, c1 + c2)[0]


@_quiet
def travel_time(b: ArrayLike, a: ArrayLike, src: ArrayLike, dst: ArrayLike, bottom: float | None = None) -> FloatArray:
    """Direct-arc travel time (s) from ``src`` to ``dst`` (..., 3) in c = b + a z (eq 13).

    NaN where the direct arc would leave the water (above z = 0 or below ``bottom``, m), or
    where the speed is not positive. Exact for equal depths (eq 12), vertical pairs (eq 14),
    a -> 0 and coincident points (t = 0).
    """
    _dx, _dy, z1, z2, R2 = _split(src, dst)
    b, a = _profile(b, a)
    dz = z2 - z1
    c1 = b + a * z1
    c2 = b + a * z2
    D = np.sqrt(R2 + dz * dz)
    t = _time(a, D, c1, c2)
    bad = _blocked(a, b, z1, z2, _vertex_if_needed(a, R2, dz, z1, c1, c2, bottom), c1, c2, bottom)
    return np.where(bad, np.nan, t)


@_quiet
def turning_depth(b: ArrayLike, a: ArrayLike, src: ArrayLike, dst: ArrayLike) -> FloatArray:
    """Depth (m) of the arc's vertex when it lies strictly between the end points, else NaN (eqs 21-22).

    With a > 0 it is the deepest point of the arc, with a < 0 the shallowest.
    """
    _dx, _dy, z1, z2, R2 = _split(src, dst)
    b, a = _profile(b, a)
    c1 = b + a * z1
    c2 = b + a * z2
    return _turning(a, R2, z2 - z1, z1, c1, c1 + c2)[0]


def _angles_length(
    a: FloatArray, R2: FloatArray, dz: FloatArray, c1: FloatArray, c2: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Launch angle, arrival angle (rad, from horizontal, positive down) and arc length (m, eq 19)."""
    S = c1 + c2
    R = np.sqrt(R2)
    D2 = R2 + dz * dz
    N1 = a * R2 + dz * S
    N2 = dz * S - a * R2
    th1 = np.arctan2(N1, 2.0 * R * c1)
    th2 = np.arctan2(N2, 2.0 * R * c2)
    # theta_1 - theta_2 = atan2(y, x): y = 2 R a S D^2, x = 4 R^2 c1 c2 + N1 N2 (both times a
    # positive factor). l = |theta_1 - theta_2| / (|a| xi), 1/xi = sqrt(4 R^2 c1^2 + N1^2) / (2R).
    x = 4.0 * R2 * c1 * c2 + N1 * N2
    hyp = np.sqrt(4.0 * R2 * c1 * c1 + N1 * N1)
    # x > 0 (|theta_1 - theta_2| < pi/2): l = S D^2 hyp / x * atan(u)/u, u = y/x, no 1/a.
    u = _ratio(2.0 * R * a * S * D2, x, 0.0)
    small = _ratio(S * D2 * hyp, x, 0.0) * _ratio(np.arctan(u), u)
    # x <= 0: strongly bent arcs (ranges of order c/|a|), where a is far from 0.
    big = _ratio(hyp * np.abs(np.arctan2(2.0 * R * a * S * D2, x)), 2.0 * R * np.abs(a), 0.0)
    length = np.where(x > 0.0, small, big)
    length = np.where(D2 == 0.0, 0.0, length)
    return th1, th2, length


@_quiet
def arc_length(b: ArrayLike, a: ArrayLike, src: ArrayLike, dst: ArrayLike) -> FloatArray:
    """Arc length (m) of the direct eigenray (eq 19), without the water-column check."""
    _dx, _dy, z1, z2, R2 = _split(src, dst)
    b, a = _profile(b, a)
    c1 = b + a * z1
    c2 = b + a * z2
    return _angles_length(a, R2, z2 - z1, c1, c2)[2]


@_quiet
def eigenray(b: ArrayLike, a: ArrayLike, src: ArrayLike, dst: ArrayLike, bottom: float | None = None) -> Eigenray:
    """Direct eigenray from ``src`` to ``dst`` (..., 3) in c = b + a z (eqs 3-22).

    Fields: time (s, eq 13), length (m, eq 19), launch/arrival grazing angles (rad, from the
    horizontal, positive down, along the direction of travel), turning depth (m, eqs 21-22,
    NaN when the vertex is not strictly between the end points) and path. Where the arc would
    leave the water column [0, ``bottom``] the path is ``PathKind.NONE`` and time, length and
    angles are NaN; ``turning_depth`` then still reports the offending vertex (why there is no
    direct path).
    """
    _dx, _dy, z1, z2, R2 = _split(src, dst)
    b, a = _profile(b, a)
    dz = z2 - z1
    c1 = b + a * z1
    c2 = b + a * z2
    D = np.sqrt(R2 + dz * dz)
    t = _time(a, D, c1, c2)
    th1, th2, length = _angles_length(a, R2, dz, c1, c2)
    zv, _ = _turning(a, R2, dz, z1, c1, c1 + c2)
    bad = _blocked(a, b, z1, z2, zv, c1, c2, bottom)
    shape = bad.shape
    nan = np.nan

    def full(a: FloatArray) -> FloatArray:
        return a if a.shape == shape else np.broadcast_to(a, shape)

    return Eigenray(
        time=np.where(bad, nan, t),
        length=np.where(bad, nan, full(length)),
        launch_angle=np.where(bad, nan, full(th1)),
        arrival_angle=np.where(bad, nan, full(th2)),
        turning_depth=np.array(full(zv)),
        path=np.where(bad, np.int8(PathKind.NONE), np.int8(PathKind.DIRECT)).astype(np.int8),
    )


@_quiet
def travel_time_gradient(
    b: ArrayLike, a: ArrayLike, src: ArrayLike, dst: ArrayLike, bottom: float | None = None
) -> FloatArray:
    """d t / d dst (s/m), shape (..., 3): exact derivative of eq 13 (what eqs 15-18 compute).

    Equals the slowness vector at the receiver, (cos(theta_2) e_h, sin(theta_2)) / c2.
    Differentiating t = (2/|a|) asinh(|a| D / (2 sqrt(c1 c2))) gives
    ((dx, dy, dz)/D - (0, 0, a D / (2 c2))) / (sqrt(c1 c2) sqrt(1 + y^2)).
    NaN where there is no direct path; 0 at coincident points (t is not differentiable there).
    """
    dx, dy, z1, z2, R2 = _split(src, dst)
    b, a = _profile(b, a)
    dz = z2 - z1
    c1 = b + a * z1
    c2 = b + a * z2
    D = np.sqrt(R2 + dz * dz)
    g = np.sqrt(c1 * c2)
    y = np.abs(a) * D / (2.0 * g)
    k = 1.0 / (g * np.sqrt(1.0 + y * y))
    ux, uy, uz = _ratio(dx, D, 0.0), _ratio(dy, D, 0.0), _ratio(dz, D, 0.0)
    gz = uz - np.multiply(a, D) / (2.0 * c2)
    gz = np.where(D == 0.0, 0.0, gz)
    bad = _blocked(a, b, z1, z2, _vertex_if_needed(a, R2, dz, z1, c1, c2, bottom), c1, c2, bottom)
    k = np.where(bad, np.nan, k)
    return np.stack(np.broadcast_arrays(k * ux, k * uy, k * gz), axis=-1)


@_quiet
def straight_line_time(b: ArrayLike, a: ArrayLike, src: ArrayLike, dst: ArrayLike) -> FloatArray:
    """Straight-ray travel time (s) with the exact line integral of 1/c along the chord (eqs 23-24).

    t_sl = D ln(c2/c1) / (c2 - c1) = D / v_sl, v_sl the logarithmic mean of the end speeds
    (eq 24); evaluated as (D / c1) log1p(d) / d with d = a dz / c1, so equal depths give D / c(z)
    and a = 0 gives D / b exactly.
    """
    _dx, _dy, z1, z2, R2 = _split(src, dst)
    b, a = _profile(b, a)
    dz = z2 - z1
    c1 = b + a * z1
    D = np.sqrt(R2 + dz * dz)
    d = np.multiply(a, dz) / c1
    return D / c1 * _ratio(np.log1p(d), d)
