"""First-arrival eigenrays through a stack of isogradient layers (piecewise-linear c(z)).

Within a layer c = c_k + g_k (z - z_k) a ray is an arc of a circle (a straight line when
g_k = 0), so for a Snell invariant p = cos(theta) / c the horizontal range, travel time and
arc length across any part of a layer are closed form (Ramezani et al., eqs 4-7, 13, 19,
rewritten without the 1/g factor so that g -> 0 has no cancellation error).

For a pair of depths z_a <= z_b (the shallower point is called A) three ray families join
them without leaving the water and with at most one turning point:

* D, direct: depth changes monotonically from A to B, 0 <= p <= 1 / max c on [z_a, z_b];
* L, lower turn: down past B to the turning depth c(z_t) = 1/p, then back up to B;
* U, upper turn: up from A to the turning depth above it, then down past A to B.

The eigenray invariant solves X_family(p) = horizontal distance. The solver samples each
family on a grid of the grazing angle phi (p = p_max cos phi, which makes the grazing
singularities smooth), brackets every sign change and refines it with a safeguarded
Newton iteration (analytic d X / d p, bisection whenever a step leaves the bracket) to
~1e-13 relative range; the time is then corrected to first order for the residual
(t = p X + tau(p) is stationary in p at an eigenray). The samples and the iterations run
in a compiled kernel (numba, ``_layered_jit``: one loop over the layers a ray crosses per
pair and sample, the same doubles as the numpy ``_family``); the rest works on all pairs
of a block at once.
Several eigenrays (caustics) give several roots: the earliest arrival is kept. Rays whose
turning point would lie above the surface or below the bottom are not direct paths
(eqs 21-22); the boundary-reflected arrivals come from the same solver applied to the
profile mirrored about the boundary, between the source and the image of the receiver.

Arrivals with two or more turning points (rays cycling in a sound channel) are not searched:
in a duct the ray with fewer cycles spends more time in fast water and arrives first, and at
network ranges (a few km) multi-turn rays exist only for pairs close to a channel axis.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .rays import Eigenray, PathKind
from .ssp import Layered

__all__ = [
    "REASON_BOTTOM",
    "REASON_OUTSIDE",
    "REASON_SHADOW",
    "REASON_SURFACE",
    "combine_arrivals",
    "eigenray",
    "reflected_eigenray",
    "straight_line_time",
    "travel_time",
    "travel_time_gradient",
    "why_no_path",
]

Reflections = Literal["none", "fallback", "all"]

REASON_SHADOW = "shadow zone: no direct eigenray"
REASON_SURFACE = "ray would leave the water at the surface"
REASON_BOTTOM = "ray would leave the water at the bottom"
REASON_OUTSIDE = "point outside the water column"

#: extra depth added below the deepest point when a profile without a bottom keeps a
#: positive gradient: a ray turning deeper than this reaches hundreds of km, far beyond
#: any acoustic network
_OPEN_DEPTH_M = 1.0e5
_GRID = 9  # phi samples per turning family (brackets the roots; caustics need >1 sample)
_SAME_DEPTH_M = 1e-9
# a block of pairs: (pairs, samples, layers) = 2^21 elements, about 5 800 pairs at 10 layers
# (the numpy work is on (pairs, samples) and (pairs, layers) arrays; 2 to 8x larger blocks
# were no faster)
_CHUNK_ELEMS = 1 << 21
_RTOL = 1e-13  # relative tolerance on horizontal range
_MAXIT = 80
_FAM_D, _FAM_L, _FAM_U = 0, 1, 2


# ----------------------------------------------------------------------------------------
# the layer stack


@dataclass(frozen=True)
class _Stack:
    """Breakpoints z (K+1,) from 0 to zmax with speeds c, gradients g and thicknesses h (K,)."""

    z: NDArray[np.float64]
    c: NDArray[np.float64]
    g: NDArray[np.float64]
    h: NDArray[np.float64]
    bottom: bool  #: the deepest breakpoint is a real sea floor (not just the profile's end)

    @property
    def zmax(self) -> float:
        return float(self.z[-1])

    @cached_property
    def arrays(self) -> tuple[NDArray[np.float64], ...]:
        """(z, c, g, h, (c_k + c_k+1) h_k) for the compiled kernels (see _layered_jit)."""
        return self.z, self.c, self.g, self.h, (self.c[:-1] + self.c[1:]) * self.h

    @classmethod
    def from_points(cls, z: NDArray[np.float64], c: NDArray[np.float64], bottom: bool) -> _Stack:
        h = np.diff(z)
        return cls(z=z, c=c, g=np.diff(c) / h, h=h, bottom=bottom)

    def speed(self, zq: NDArray[np.float64]) -> NDArray[np.float64]:
        k = self.layer(zq)
        return self.c[k] + self.g[k] * (zq - self.z[k])

    def layer(self, zq: NDArray[np.float64]) -> NDArray[np.intp]:
        return np.clip(np.searchsorted(self.z, zq, side="right") - 1, 0, self.g.size - 1)

    def extended(self, depth: float = 1.0e4) -> tuple[_Stack, float]:
        """The stack continued beyond the surface (and the bottom) with the end gradients,
        shifted down by the returned offset: where would a direct ray leave the water?"""
        g0, gl = self.g[0], self.g[-1]
        up = min(depth, 0.5 * self.c[0] / g0) if g0 > 0.0 else depth
        z = [self.z + up]
        c = [self.c]
        z.insert(0, np.array([0.0]))
        c.insert(0, np.array([self.c[0] - g0 * up]))
        if self.bottom:
            down = min(depth, 0.5 * self.c[-1] / -gl) if gl < 0.0 else depth
            z.append(np.array([self.zmax + up + down]))
            c.append(np.array([self.c[-1] + gl * down]))
        return _Stack.from_points(np.concatenate(z), np.concatenate(c), bottom=False), up

    def mirrored(self, boundary: Literal["surface", "bottom"]) -> _Stack:
        """The profile unfolded about a boundary: one reflection becomes a direct path."""
        zm = self.zmax
        if boundary == "surface":
            z = np.concatenate([zm - self.z[::-1], zm + self.z[1:]])
            c = np.concatenate([self.c[::-1], self.c[1:]])
        else:
            z = np.concatenate([self.z, 2.0 * zm - self.z[-2::-1]])
            c = np.concatenate([self.c, self.c[-2::-1]])
        return _Stack.from_points(z, c, bottom=self.bottom)


def _stack(profile: Layered, z_deepest: float) -> _Stack:
    """The water column [0, zmax] of ``profile`` as layers (bottom, or an open end)."""
    d, c = profile.depths, profile.speeds
    if profile.bottom is not None:
        zmax, bottom = profile.bottom, True
    else:
        g_last = (c[-1] - c[-2]) / (d[-1] - d[-2])
        zmax = max(float(d[-1]), z_deepest)
        if g_last > 0.0:
            zmax += _OPEN_DEPTH_M
        bottom = False
    keep = d < zmax
    z = np.concatenate([d[keep], [zmax]])
    cz = np.concatenate([c[keep], profile.speed(np.array([zmax]))])
    return _Stack.from_points(z, cz, bottom)


# ----------------------------------------------------------------------------------------
# closed forms inside one layer


def _log1p_ratio(u: NDArray[np.float64]) -> NDArray[np.float64]:
    """log(1 + u) / u, = 1 at u = 0, accurate for tiny u."""
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.log1p(u) / u
    return np.where(u == 0.0, 1.0, r)


def _asinc(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """arcsin(v) / v, = 1 at v = 0."""
    v = np.clip(v, -1.0, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.arcsin(v) / v
    return np.where(v == 0.0, 1.0, r)


def _inv(pmax, phi):
    """The Snell invariant p = p_max cos(phi) with its angle: (p, p_max, sin phi, cos phi)."""
    cp = np.cos(phi)
    return (pmax * cp, pmax, np.sin(phi), cp)


def _expand(inv):
    return tuple(np.asarray(v)[..., None] for v in inv)


def _cos_sin(inv, c: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(cos theta, |sin theta|) at speed c for the invariant ``inv``.

    sin^2 = sin^2 phi + cos^2 phi (1 - u)(1 + u), u = c / c_max: exact near grazing (where
    1 - (p c)^2 would lose half the digits), and sin theta = sin phi where c = c_max.
    """
    _, pm, sp, cp = inv
    u = c * pm
    return cp * u, np.sqrt(np.maximum(sp * sp + cp * cp * ((1.0 - u) * (1.0 + u)), 0.0))


def _seg(inv, c1, c2, dz, g, full: bool, deriv: bool = False):
    """Range (and time, arc length) of a monotone ray piece from speed c1 down to c2, dz >= 0.

    Range  X = (sin th1 - sin th2) / (p g) = p (c1 + c2) dz / (sin th1 + sin th2)   (eq 6)
    Time   T = [ln(c2/c1) + ln((1 + sin th1)/(1 + sin th2))] / g                   (eq 13)
    Length L = (arcsin(p c2) - arcsin(p c1)) / (p g)                              (eq 19)
    each written as dz times a bounded factor, so g = 0 (straight line) is exact.
    """
    p = inv[0]
    _, w1 = _cos_sin(inv, c1)
    _, w2 = _cos_sin(inv, c2)
    den = w1 + w2
    pos = dz > 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.where(pos, p * (c1 + c2) * dz / den, 0.0)
        if deriv:  # d X / d p, with d sin(th) / d p = -p c^2 / sin(th)
            return x, np.where(pos, x / p + x * p * (c1 * c1 / w1 + c2 * c2 / w2) / den, 0.0), None
        if not full:
            return x, None, None
        q = p * p * (c1 + c2) * dz / (den * (1.0 + w2))
        t = dz / c1 * _log1p_ratio(g * dz / c1) + q * _log1p_ratio(g * q)
        den2 = c2 * w1 + c1 * w2
        lfac = dz * (c1 + c2) / den2
        arc = lfac * _asinc(p * g * lfac)
        t = np.where(pos, t, 0.0)
        arc = np.where(pos, arc, 0.0)
    return x, t, arc


# ----------------------------------------------------------------------------------------
# ray families


@dataclass
class _Geo:
    """Per-pair geometry (A = shallower point), arrays broadcastable against phi."""

    za: NDArray[np.float64]
    zb: NDArray[np.float64]
    ka: NDArray[np.intp]
    kb: NDArray[np.intp]
    ca: NDArray[np.float64]
    cb: NDArray[np.float64]
    pmax: NDArray[np.float64]  #: 1 / max c on [za, zb]
    phi_l: NDArray[np.float64]  #: grazing-angle extent of the lower-turning family (0: none)
    phi_u: NDArray[np.float64]  #: same for the upper-turning family

    def take(self, idx: NDArray[np.intp]) -> _Geo:
        return _Geo(*(getattr(self, f)[idx] for f in self.__dataclass_fields__))

    def col(self) -> _Geo:
        return _Geo(*(getattr(self, f)[:, None] for f in self.__dataclass_fields__))

    def arrays(self) -> tuple[NDArray, ...]:
        """(za, zb, ka, kb, ca, cb, pmax) as the compiled kernels take them (see _layered_jit)."""
        f, i = np.float64, np.int64
        return tuple(
            np.ascontiguousarray(getattr(self, name), dtype=t)
            for name, t in (("za", f), ("zb", f), ("ka", i), ("kb", i), ("ca", f), ("cb", f), ("pmax", f))
        )


def _geometry(st: _Stack, za: NDArray[np.float64], zb: NDArray[np.float64]) -> _Geo:
    ka, kb = st.layer(za), st.layer(zb)
    ca = st.c[ka] + st.g[ka] * (za - st.z[ka])
    cb = st.c[kb] + st.g[kb] * (zb - st.z[kb])
    zc, cc = st.z[None, :], st.c[None, :]
    inner = np.where((zc > za[:, None]) & (zc < zb[:, None]), cc, -np.inf).max(axis=1)
    cmax = np.maximum(np.maximum(ca, cb), inner)
    below = np.where(zc > zb[:, None], cc, -np.inf).max(axis=1)
    above = np.where(zc < za[:, None], cc, -np.inf).max(axis=1)
    with np.errstate(invalid="ignore"):
        phi_l = np.where(below > cmax, np.arccos(np.clip(cmax / below, -1.0, 1.0)), 0.0)
        phi_u = np.where(above > cmax, np.arccos(np.clip(cmax / above, -1.0, 1.0)), 0.0)
    return _Geo(za, zb, ka, kb, ca, cb, 1.0 / cmax, phi_l, phi_u)


class _Layers:
    """Full-layer closed forms for one array of invariants p (shape S), layers on the last axis."""

    def __init__(self, st: _Stack, inv, full: bool, deriv: bool = False) -> None:
        self.st, self.p, self.full, self.deriv = st, inv, full, deriv
        ie = _expand(inv)
        pe = ie[0]
        if full:
            self.pc = pe * st.c
            self.x, self.t, self.arc = _seg(ie, st.c[:-1], st.c[1:], st.h, st.g, True)
        else:
            # range only (the hot path of the root finder): sin theta once per breakpoint
            self.pc, w = _cos_sin(ie, st.c)
            with np.errstate(divide="ignore", invalid="ignore"):
                den = w[..., :-1] + w[..., 1:]
                self.x = pe * ((st.c[:-1] + st.c[1:]) * st.h) / den
                if deriv:
                    q = st.c**2 / w
                    self.dx = self.x / pe + self.x * pe * (q[..., :-1] + q[..., 1:]) / den

    def interval(self, z1, k1, z2, k2, turn: str | None = None):
        """Range (time, length) of the monotone piece z1 (layer k1) -> z2 (layer k2), z1 <= z2.

        ``turn="bottom"``: z2 is the ray's turning point (only its layer k2 is used);
        ``turn="top"``: z1 is. The turning piece uses its own closed form, which needs no
        turning depth (so no rounding of p * (1/p) enters it)."""
        st, p, full, dv = self.st, self.p, self.full, self.deriv
        same = k1 == k2
        g1, g2 = st.g[k1], st.g[k2]
        c1 = st.c[k1] + g1 * (z1 - st.z[k1])
        c2 = st.c[k2] + g2 * (z2 - st.z[k2])
        if turn is None:
            e1 = np.where(same, z2, st.z[k1 + 1])
            ce = np.where(same, c2, st.c[k1 + 1])
            xa, ta, la = _seg(p, c1, ce, e1 - z1, g1, full, dv)
            xb, tb, lb = _seg(p, st.c[k2], c2, np.where(same, 0.0, z2 - st.z[k2]), g2, full, dv)
        elif turn == "bottom":
            xa, ta, la = _seg(p, c1, st.c[k1 + 1], np.where(same, 0.0, st.z[k1 + 1] - z1), g1, full, dv)
            xb, tb, lb = _turning(p, np.where(same, c1, st.c[k2]), g2, full, dv)
        else:
            xa, ta, la = _turning(p, np.where(same, c2, st.c[k1 + 1]), g1, full, dv)
            xb, tb, lb = _seg(p, st.c[k2], c2, np.where(same, 0.0, z2 - st.z[k2]), g2, full, dv)
        kk = np.arange(st.g.size)
        mid = (kk > k1[..., None]) & (kk < k2[..., None])
        x = xa + xb + np.where(mid, self.x, 0.0).sum(axis=-1)
        if dv:
            return x, ta + tb + np.where(mid, self.dx, 0.0).sum(axis=-1), None
        if not full:
            return x, None, None
        t = ta + tb + np.where(mid, self.t, 0.0).sum(axis=-1)
        arc = la + lb + np.where(mid, self.arc, 0.0).sum(axis=-1)
        return x, t, arc


def _turning(inv, c, g, full: bool, deriv: bool = False):
    """Range, time and arc length from speed c to the turning point c = 1/p in a layer of
    gradient g: X = sin th / (p |g|), T = artanh(sin th) / |g|, L = th / (p |g|) (eqs 6, 13, 19
    with the turning angle 0)."""
    p = inv[0]
    s, w = _cos_sin(inv, c)
    ag = np.abs(g)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = w / (p * ag)
        if deriv:
            return x, -1.0 / (w * p * p * ag), None
        if not full:
            return x, None, None
        return x, np.arctanh(w) / ag, np.arctan2(w, s) / (p * ag)


def _family(st: _Stack, geo: _Geo, fam: int, phi: NDArray[np.float64], full: bool = False, deriv: bool = False):
    """Range X(phi) (NaN where the family has no ray), and when ``full`` also time, arc
    length and turning depth, for invariants p = p_max cos(phi). With ``deriv`` the second
    value is d X / d phi instead. The solver evaluates X and d X / d phi with the compiled
    ``_range``; this numpy version is its reference (tests) and evaluates the roots."""
    inv = _inv(geo.pmax, phi)
    p = inv[0]
    lay = _Layers(st, inv, full, deriv)
    xd, td, ld = lay.interval(geo.za, geo.ka, geo.zb, geo.kb)
    dpdphi = -geo.pmax * np.sin(phi)
    if fam == _FAM_D:
        if deriv:
            return xd, td * dpdphi, None, None
        turn = np.full(np.shape(xd), np.nan)
        return xd, td, ld, turn
    blocked = lay.pc >= 1.0
    nk = st.g.size
    if fam == _FAM_L:
        # the turning layer lies above the first breakpoint below B that the ray cannot pass
        cand = blocked & (st.z > geo.zb[..., None])
        ok = cand.any(axis=-1)
        kt = np.maximum(np.clip(np.argmax(cand, axis=-1) - 1, 0, nk - 1), geo.kb)
        xe, te, le = lay.interval(geo.zb, geo.kb, geo.zb, kt, turn="bottom")
        lo, hi = np.maximum(geo.zb, st.z[kt]), st.z[kt + 1]
    else:
        cand = blocked & (st.z < geo.za[..., None])
        ok = cand.any(axis=-1)
        kt = np.minimum(np.clip(nk - np.argmax(cand[..., ::-1], axis=-1), 0, nk - 1), geo.ka)
        xe, te, le = lay.interval(geo.za, kt, geo.za, geo.ka, turn="top")
        lo, hi = st.z[kt], np.minimum(geo.za, st.z[kt + 1])
    x = np.where(ok, xd + 2.0 * xe, np.nan)
    if deriv:
        with np.errstate(invalid="ignore"):
            return x, (td + 2.0 * te) * dpdphi, None, None
    if not full:
        return x, None, None, None
    with np.errstate(divide="ignore", invalid="ignore"):
        zt = np.clip(st.z[kt] + (1.0 / p - st.c[kt]) / st.g[kt], lo, hi)
    return x, td + 2.0 * te, ld + 2.0 * le, np.where(ok, zt, np.nan)


# ----------------------------------------------------------------------------------------
# root finding


def _kernels():
    """The compiled family evaluations (numba: imported on the first solve, see _layered_jit)."""
    from . import _layered_jit

    return _layered_jit


def _range(st: _Stack, geo: _Geo, fam: int, phi: NDArray[np.float64], deriv: bool = False):
    """Compiled X(phi) (m, NaN where the family has no ray) at phi (pairs, samples), and with
    ``deriv`` also d X / d phi: the same doubles as ``_family(..., deriv=deriv)[:2]``."""
    x, dx = _kernels().family_range(st.arrays, geo.arrays(), fam, phi, deriv)
    return (x, dx) if deriv else x


def _refine(st: _Stack, geo: _Geo, fam: int, target, lo, hi, hlo, hhi, guess=None):
    """Safeguarded Newton iteration on h(phi) = X(phi) - target inside brackets [lo, hi]
    with h(lo) h(hi) <= 0 (bisection whenever a step leaves the bracket or stalls), each
    bracket on its own (compiled: _layered_jit.refine), from ``guess`` or the regula falsi
    point; returns (phi, |h|) at the best point seen."""
    if guess is None:
        with np.errstate(divide="ignore", invalid="ignore"):
            guess = lo - hlo * (hi - lo) / (hhi - hlo)
    return _kernels().refine(st.arrays, geo.arrays(), fam, target, lo, hi, hlo, hhi, guess, _RTOL, _MAXIT)


def _pick_brackets(h: NDArray[np.float64]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """(row, sample) of the sign changes of h (pairs, samples) worth refining: those where the
    range grows with phi, or every one in a row that has none of that kind.

    Along a family t = p X + tau(p) with d tau / d p = -X(p), so the eigenrays are the
    stationary points of t in p; the roots alternate between minima of t (range growing with
    phi) and maxima, and a maximum is always later than a neighbouring minimum: the earliest
    eigenray is among the minima whenever there is one."""
    h0, h1 = h[:, :-1], h[:, 1:]
    fin = np.isfinite(h0) & np.isfinite(h1)
    cross = fin & (h0 * h1 <= 0.0) & ~((h0 == 0.0) & (h1 == 0.0))
    up = cross & (h0 <= 0.0) & (h1 >= 0.0)
    use = np.where(up.any(axis=1, keepdims=True), up, cross)
    rows, cols = np.nonzero(use)
    return rows, cols


@dataclass
class _Arrivals:
    """Direct eigenrays in (A -> B) orientation, one per pair; ok False where none."""

    time: NDArray[np.float64]
    length: NDArray[np.float64]
    ang_a: NDArray[np.float64]
    ang_b: NDArray[np.float64]
    turn: NDArray[np.float64]
    ok: NDArray[np.bool_]

    @classmethod
    def empty(cls, n: int) -> _Arrivals:
        nan = np.full(n, np.nan)
        return cls(np.full(n, np.inf), nan.copy(), nan.copy(), nan.copy(), nan.copy(), np.zeros(n, bool))


def _angles(inv, c, w_sign):
    s, w = _cos_sin(inv, c)
    return w_sign * np.arctan2(w, s)


def _finish(st, geo, fam, phi, target, idx, best: _Arrivals, resid) -> None:
    """Evaluate candidates at their converged invariants and keep the earliest per pair."""
    accept = resid <= 1e-9 * np.maximum(target, 1.0)
    if not np.any(accept):
        return
    phi, idx, target = phi[accept], idx[accept], target[accept]
    g = geo.take(idx)
    x, t, arc, turn = _family(st, g, fam, phi, full=True)
    p = g.pmax * np.cos(phi)
    # t = p X + tau(p) is stationary at the eigenray: correct to first order in the residual
    t = t + p * (target - x)
    sa, sb = {_FAM_D: (1.0, 1.0), _FAM_L: (1.0, -1.0), _FAM_U: (-1.0, 1.0)}[fam]
    # several candidates may share a pair: sort so the earliest is written last
    order = np.argsort(-t, kind="stable")
    idx, t, arc, turn, phi = idx[order], t[order], arc[order], turn[order], phi[order]
    ca, cb, pm = g.ca[order], g.cb[order], g.pmax[order]
    better = t < best.time[idx]
    idx, t, arc, turn, phi, ca, cb, pm = (v[better] for v in (idx, t, arc, turn, phi, ca, cb, pm))
    inv = _inv(pm, phi)
    best.time[idx] = t
    best.length[idx] = arc
    best.turn[idx] = turn
    best.ang_a[idx] = _angles(inv, ca, sa)
    best.ang_b[idx] = _angles(inv, cb, sb)
    best.ok[idx] = True


_CUSP_JUMP = 1.05  # gradient ratio across a breakpoint that gets the extra samples
_CUSP_MAX = 12  # at most this many breakpoints per family and pair (evenly spread)


def _cusp_samples(st: _Stack, geo: _Geo, fam: int, ext) -> NDArray[np.float64] | None:
    """Extra samples where a turning family folds back (a triplication, several eigenrays).

    When the turning point crosses a breakpoint into a layer of steeper gradient (|g_new| >
    |g_old|), the range gains the term -beta sin(th_j), beta = 2 (1/|g_old| - 1/|g_new|) / p,
    with sin(th_j) ~ sqrt(2 tan(phi_j) u), u = phi - phi_j: a dip right after phi_j that a
    uniform grid can step over. Sampling phi_j and the dip's bottom, u* = beta^2 tan(phi_j) /
    (2 S'^2) (S' the range slope just before phi_j), brackets both of its eigenrays."""
    g = st.g
    if fam == _FAM_L:  # breakpoint j between layers j-1 (above, old) and j (below, new)
        j = np.flatnonzero((g[:-1] > 0.0) & (g[1:] > _CUSP_JUMP * g[:-1])) + 1
        g_old, g_new = g[j - 1], g[j]
    else:
        j = np.flatnonzero((g[1:] < 0.0) & (g[:-1] < _CUSP_JUMP * g[1:])) + 1
        g_old, g_new = -g[j], -g[j - 1]
    if j.size == 0:
        return None
    zj, cj = st.z[j], st.c[j]
    side = (zj > geo.zb[:, None]) if fam == _FAM_L else (zj < geo.za[:, None])
    ratio = 1.0 / (geo.pmax[:, None] * cj)  # cos(phi_j) = c_max / c_j
    with np.errstate(invalid="ignore"):
        phj = np.where(side & (ratio < 1.0), np.arccos(np.clip(ratio, -1.0, 1.0)), np.nan)
    phj = np.where(phj < ext[:, None], phj, np.nan)
    if not np.any(np.isfinite(phj)):
        return None
    # the breakpoint's gradients ride along with its phi_j through the per-pair selection
    key = np.broadcast_to(np.arange(j.size), phj.shape)
    order = np.argsort(np.where(np.isfinite(phj), phj, np.inf), axis=1)
    phj = np.take_along_axis(phj, order, axis=1)
    key = np.take_along_axis(key, order, axis=1)
    if j.size > _CUSP_MAX:
        # many thin layers: an even spread of the pair's relevant breakpoints
        m = np.isfinite(phj).sum(axis=1)
        pick = np.round(np.linspace(0.0, 1.0, _CUSP_MAX)[None, :] * np.maximum(m - 1, 0)[:, None]).astype(np.intp)
        phj = np.where(m[:, None] > 0, np.take_along_axis(phj, pick, axis=1), np.nan)
        key = np.take_along_axis(key, pick, axis=1)
    g_old, g_new, cj = g_old[key], g_new[key], cj[key]
    probe = np.where(np.isfinite(phj), phj * (1.0 - 1e-12), 0.0)  # just before: old layer turns
    _, slope = _range(st, geo, fam, probe, deriv=True)
    beta = 2.0 * (1.0 / g_old - 1.0 / g_new) * cj  # 1/p = c_j at phi_j
    with np.errstate(invalid="ignore", divide="ignore"):
        du = beta**2 * np.tan(phj) / (2.0 * slope**2)
    dip = np.where((slope > 0.0) & np.isfinite(du), np.minimum(phj + du, ext[:, None] * (1.0 - 1e-10)), np.nan)
    return np.concatenate([phj, dip], axis=1)


def _direct_block(st: _Stack, za, zb, x) -> _Arrivals:
    """Earliest direct eigenray for one block of pairs with za <= zb, horizontal range x."""
    n = za.size
    best = _Arrivals.empty(n)
    geo = _geometry(st, za, zb)
    allidx = np.arange(n)

    # coincident points, and equal depths inside a constant-speed layer: a horizontal line
    same = (za == zb) & (x == 0.0)
    best.time[same] = 0.0
    best.length[same] = 0.0
    best.ang_a[same] = best.ang_b[same] = 0.0
    best.ok[same] = True
    flat = (
        (za == zb)
        & (x > 0.0)
        & ((st.g[geo.ka] == 0.0) | ((za == st.z[geo.ka]) & (geo.ka > 0) & (st.g[np.maximum(geo.ka - 1, 0)] == 0.0)))
    )
    best.time[flat] = x[flat] / geo.ca[flat]
    best.length[flat] = x[flat]
    best.ang_a[flat] = best.ang_b[flat] = 0.0
    best.ok[flat] = True

    # direct family: X_D increases monotonically from 0 (vertical) to its grazing value
    vert = (zb > za) & (x == 0.0)
    if np.any(vert):
        i = allidx[vert]
        _finish(st, geo, _FAM_D, np.full(i.size, 0.5 * np.pi), x[i], i, best, np.zeros(i.size))
    cand = (zb > za) & (x > 0.0)
    if np.any(cand):
        i = allidx[cand]
        g = geo.take(i)
        xg = _range(st, g, _FAM_D, np.zeros((i.size, 1)))[:, 0]
        reach = xg >= x[i]
        i, xg = i[reach], xg[reach]
        if i.size:
            lo, hi = np.zeros(i.size), np.full(i.size, 0.5 * np.pi)
            # the chord's angle is the root for a uniform speed: a good Newton start
            guess = np.arctan2(zb[i] - za[i], x[i])
            phi, res = _refine(st, geo.take(i), _FAM_D, x[i], lo, hi, xg - x[i], -x[i], guess)
            _finish(st, geo, _FAM_D, phi, x[i], i, best, res)

    # turning families: sample phi, bracket every usable sign change, refine
    # the last sample stays a hair inside the family, where the turning point certainly exists
    u = np.linspace(0.0, 1.0 - 1e-10, _GRID)
    for fam, ext in ((_FAM_L, geo.phi_l), (_FAM_U, geo.phi_u)):
        i = allidx[(ext > 0.0) & (x > 0.0)]
        if i.size == 0:
            continue
        g = geo.take(i)
        grid = ext[i, None] * u[None, :]
        cusp = _cusp_samples(st, g, fam, ext[i])
        if cusp is not None:
            grid = np.sort(np.concatenate([grid, cusp], axis=1), axis=1)  # NaN (unused) last
        h = _range(st, g, fam, grid) - x[i, None]
        rows, s = _pick_brackets(h)
        if rows.size == 0:
            continue
        j = i[rows]
        phi, res = _refine(st, geo.take(j), fam, x[j], grid[rows, s], grid[rows, s + 1], h[rows, s], h[rows, s + 1])
        _finish(st, geo, fam, phi, x[j], j, best, res)
    best.time[~best.ok] = np.nan
    return best


def _direct(st: _Stack, zs, zr, x) -> _Arrivals:
    """Earliest direct eigenray src -> dst for flat arrays (depths zs, zr, horizontal x);
    angles in the src -> dst orientation."""
    n = zs.size
    out = _Arrivals.empty(n)
    out.time[:] = np.nan
    swap = zs > zr
    za, zb = np.where(swap, zr, zs), np.where(swap, zs, zr)
    # depths within a nanometre are equal: below that, c(z_b) rounds to c(z_a) and the
    # direct family's range formula would see a depth step without a speed step
    zb = np.where(zb - za <= _SAME_DEPTH_M, za, zb)
    inside = (za >= 0.0) & (zb <= st.zmax) & np.isfinite(za) & np.isfinite(zb) & np.isfinite(x)
    idx = np.flatnonzero(inside)
    chunk = max(64, _CHUNK_ELEMS // ((_GRID + 2 * _CUSP_MAX) * (st.g.size + 1)))
    for s in range(0, idx.size, chunk):
        i = idx[s : s + chunk]
        r = _direct_block(st, za[i], zb[i], x[i])
        for f in ("time", "length", "turn", "ok"):
            getattr(out, f)[i] = getattr(r, f)
        sw = swap[i]
        # reversing the ray reverses both tangents
        out.ang_a[i] = np.where(sw, -r.ang_b, r.ang_a)
        out.ang_b[i] = np.where(sw, -r.ang_a, r.ang_b)
    return out


# ----------------------------------------------------------------------------------------
# public API


def _pairs(src: ArrayLike, dst: ArrayLike):
    s = np.asarray(src, dtype=float)
    d = np.asarray(dst, dtype=float)
    if s.shape[-1:] != (3,) or d.shape[-1:] != (3,):
        raise ValueError("src and dst must have a last axis of length 3 (x, y, z)")
    s, d = np.broadcast_arrays(s, d)
    shape = s.shape[:-1]
    s, d = s.reshape(-1, 3), d.reshape(-1, 3)
    x = np.hypot(d[:, 0] - s[:, 0], d[:, 1] - s[:, 1])
    return shape, s, d, x


def _deepest(s, d) -> float:
    z = np.concatenate([s[:, 2], d[:, 2]])
    z = z[np.isfinite(z)]
    return float(z.max()) if z.size else 0.0


def _to_eigenray(a: _Arrivals, kind: int, shape) -> Eigenray:
    path = np.where(a.ok, kind, PathKind.NONE).astype(np.int8)
    return Eigenray(
        time=np.where(a.ok, a.time, np.nan).reshape(shape),
        length=np.where(a.ok, a.length, np.nan).reshape(shape),
        launch_angle=np.where(a.ok, a.ang_a, np.nan).reshape(shape),
        arrival_angle=np.where(a.ok, a.ang_b, np.nan).reshape(shape),
        turning_depth=np.where(a.ok, a.turn, np.nan).reshape(shape),
        path=path.reshape(shape),
    )


def _reflected(st: _Stack, zs, zr, x, boundary: Literal["surface", "bottom"]) -> _Arrivals:
    """First arrival with one reflection: the direct ray of the mirrored profile to the image."""
    n = zs.size
    if boundary == "bottom" and not st.bottom:
        return _Arrivals.empty(n)
    zm = st.zmax
    inside = (zs >= 0.0) & (zs <= zm) & (zr >= 0.0) & (zr <= zm)
    mst = st.mirrored(boundary)
    if boundary == "surface":
        zs_i, zr_i = zm - zs, zm + zr
    else:
        zs_i, zr_i = zs, 2.0 * zm - zr
    a = _direct(mst, np.where(inside, zs_i, np.nan), np.where(inside, zr_i, np.nan), x)
    a.ok &= inside
    if boundary == "surface":
        a.ang_a = -a.ang_a  # leaves the image source downwards = the real source upwards
        a.turn = np.abs(a.turn - zm)
    else:
        a.ang_b = -a.ang_b
        a.turn = np.where(a.turn > zm, 2.0 * zm - a.turn, a.turn)
    return a


def combine_arrivals(arrivals: list[tuple[int, Eigenray]], mode: Reflections) -> Eigenray:
    """Merge per-path eigenrays: the first is the direct one; ``mode`` picks how reflected
    paths (the others) are used: "none", "fallback" (only where no direct path) or "all"
    (the earliest of every path)."""
    if mode not in ("none", "fallback", "all"):
        raise ValueError(f"reflections must be 'none', 'fallback' or 'all', got {mode!r}")
    fields = ("time", "length", "launch_angle", "arrival_angle", "turning_depth")
    _, base = arrivals[0]
    out = {f: np.array(getattr(base, f), dtype=float, copy=True) for f in fields}
    path = np.array(base.path, dtype=np.int8, copy=True)
    if mode == "none":
        return Eigenray(path=path, **out)
    direct_ok = path != PathKind.NONE
    for kind, ray in arrivals[1:]:
        t = np.asarray(ray.time)
        cur = np.where(np.isnan(out["time"]), np.inf, out["time"])
        take = np.isfinite(t) & (t < cur)
        if mode == "fallback":
            take &= ~direct_ok
        for f in fields:
            out[f] = np.where(take, getattr(ray, f), out[f])
        path = np.where(take, np.int8(kind), path).astype(np.int8)
    return Eigenray(path=path, **out)


def eigenray(profile: Layered, src: ArrayLike, dst: ArrayLike, *, reflections: Reflections = "fallback") -> Eigenray:
    """First-arrival eigenray from ``src`` to ``dst`` (..., 3) through a layered profile.

    ``reflections``: "none" (direct path only), "fallback" (the first surface- or
    bottom-reflected arrival where there is no direct path), "all" (the earliest of the
    direct and reflected arrivals). ``path`` tells which path each arrival took; NaN and
    ``PathKind.NONE`` where there is none (see :func:`why_no_path`).
    """
    if reflections not in ("none", "fallback", "all"):
        raise ValueError(f"reflections must be 'none', 'fallback' or 'all', got {reflections!r}")
    shape, s, d, x = _pairs(src, dst)
    st = _stack(profile, _deepest(s, d))
    direct = _direct(st, s[:, 2], d[:, 2], x)
    parts: list[tuple[int, Eigenray]] = [(PathKind.DIRECT, _to_eigenray(direct, PathKind.DIRECT, shape))]
    if reflections != "none":
        need = np.ones(x.size, bool) if reflections == "all" else ~direct.ok
        boundaries: tuple[tuple[PathKind, Literal["surface", "bottom"]], ...] = (
            (PathKind.SURFACE, "surface"),
            (PathKind.BOTTOM, "bottom"),
        )
        for kind, name in boundaries:
            r = _Arrivals.empty(x.size)
            r.time[:] = np.nan
            i = np.flatnonzero(need)
            if i.size and (name == "surface" or st.bottom):
                sub = _reflected(st, s[i, 2], d[i, 2], x[i], name)
                for f in ("time", "length", "ang_a", "ang_b", "turn", "ok"):
                    getattr(r, f)[i] = getattr(sub, f)
            parts.append((kind, _to_eigenray(r, kind, shape)))
    return combine_arrivals(parts, reflections)


def travel_time(
    profile: Layered, src: ArrayLike, dst: ArrayLike, *, reflections: Reflections = "fallback"
) -> NDArray[np.float64]:
    """First-arrival travel time (s); NaN where there is no path."""
    return eigenray(profile, src, dst, reflections=reflections).time


def slowness_gradient(profile, src: ArrayLike, dst: ArrayLike, ray: Eigenray) -> NDArray[np.float64]:
    """d t / d dst (s/m) of any eigenray: the slowness vector at the receiver,
    (cos theta_R u_h + sin theta_R e_z) / c(z_R), u_h the horizontal unit vector src -> dst.
    Exact for every eigenray (t is stationary in the path, so only the end point moves)."""
    s = np.asarray(src, dtype=float)
    d = np.asarray(dst, dtype=float)
    s, d = np.broadcast_arrays(s, d)
    dx, dy = d[..., 0] - s[..., 0], d[..., 1] - s[..., 1]
    hor = np.hypot(dx, dy)
    with np.errstate(invalid="ignore", divide="ignore"):
        ux = np.where(hor > 0.0, dx / hor, 0.0)
        uy = np.where(hor > 0.0, dy / hor, 0.0)
    c = np.asarray(profile.speed(d[..., 2]), dtype=float)
    th = np.asarray(ray.arrival_angle)
    ch, sh = np.cos(th) / c, np.sin(th) / c
    return np.stack([ch * ux, ch * uy, sh], axis=-1)


def travel_time_gradient(
    profile: Layered, src: ArrayLike, dst: ArrayLike, *, reflections: Reflections = "fallback"
) -> NDArray[np.float64]:
    """d travel_time / d dst (s/m), shape (..., 3); NaN where there is no path."""
    ray = eigenray(profile, src, dst, reflections=reflections)
    return slowness_gradient(profile, src, dst, ray)


def reflected_eigenray(
    profile: Layered, src: ArrayLike, dst: ArrayLike, boundary: Literal["surface", "bottom"]
) -> Eigenray:
    """First arrival with exactly one reflection off ``boundary`` (profile mirrored about it)."""
    shape, s, d, x = _pairs(src, dst)
    st = _stack(profile, _deepest(s, d))
    kind = PathKind.SURFACE if boundary == "surface" else PathKind.BOTTOM
    return _to_eigenray(_reflected(st, s[:, 2], d[:, 2], x, boundary), kind, shape)


def why_no_path(
    profile: Layered, src: ArrayLike, dst: ArrayLike, *, assume_no_direct: bool = False
) -> NDArray[np.object_]:
    """Why there is no direct eigenray, per pair ("" where there is one): a point outside
    the water; the rays that would connect the points leave the water (only a reflected
    path exists: the reason names the boundary of the earliest one); or a shadow zone.
    ``assume_no_direct``: the caller already knows there is no direct path (skip the solve)."""
    shape, s, d, x = _pairs(src, dst)
    st = _stack(profile, _deepest(s, d))
    out = np.full(x.size, "", dtype=object)
    zs, zr = s[:, 2], d[:, 2]
    outside = ~((np.minimum(zs, zr) >= 0.0) & (np.maximum(zs, zr) <= st.zmax))
    outside |= ~(np.isfinite(s).all(axis=1) & np.isfinite(d).all(axis=1))
    out[outside] = REASON_OUTSIDE
    has_direct = np.zeros(x.size, bool) if assume_no_direct else _direct(st, zs, zr, x).ok
    i = np.flatnonzero(~has_direct & ~outside)
    if i.size:
        # the direct ray in the profile continued past the boundaries: where does it turn?
        ext, off = st.extended()
        a = _direct(ext, zs[i] + off, zr[i] + off, x[i])
        out[i] = np.where(
            a.ok & (a.turn < off),
            REASON_SURFACE,
            np.where(a.ok & (a.turn > st.zmax + off), REASON_BOTTOM, REASON_SHADOW),
        )
    return out.reshape(shape)


def straight_line_time(profile: Layered, src: ArrayLike, dst: ArrayLike) -> NDArray[np.float64]:
    """Straight-ray time (s): distance times the mean slowness over the depth interval,
    t = |d - s| / |dz| * integral dz / c(z) (Ramezani et al., eq 23, layer by layer);
    1 / c(z) when both depths are equal."""
    shape, s, d, _x = _pairs(src, dst)
    st = _stack(profile, _deepest(s, d))
    z1 = np.minimum(s[:, 2], d[:, 2])
    z2 = np.maximum(s[:, 2], d[:, 2])
    dist = np.linalg.norm(d - s, axis=1)
    top = np.maximum(st.z[:-1], z1[:, None])
    bot = np.minimum(st.z[1:], z2[:, None])
    hh = np.maximum(bot - top, 0.0)
    c1 = st.c[:-1] + st.g * (top - st.z[:-1])
    # integral of dz / c over the overlap: log(c2 / c1) / g written without 1/g
    integral = (hh / c1 * _log1p_ratio(st.g * hh / c1)).sum(axis=1)
    dz = z2 - z1
    with np.errstate(divide="ignore", invalid="ignore"):
        # below a nanometre the integral underflows or rounds: the local slowness is exact
        mean_slow = np.where(dz > _SAME_DEPTH_M, integral / dz, 1.0 / st.speed(0.5 * (z1 + z2)))
    out = dist * mean_slow
    outside = (z1 < 0.0) | (z2 > st.zmax)
    return np.where(outside, np.nan, out).reshape(shape)
