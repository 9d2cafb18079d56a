"""The layer stack of a piecewise-linear profile and the closed forms of a ray inside it.

Within a layer c = c_k + g_k (z - z_k) a ray is an arc of a circle (a straight line when
g_k = 0), so for a Snell invariant p = cos(theta) / c the horizontal range, travel time and
arc length across any part of a layer are closed form (Ramezani et al., eqs 4-7, 13, 19,
rewritten without the 1/g factor so that g -> 0 has no cancellation error); summed over the
layers a ray crosses they give each ray family's range, time and arc length
(:func:`family`), which the eigenray solver (:mod:`.layered`) inverts.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .ssp import Layered

__all__ = [
    "FAM_D",
    "FAM_L",
    "FAM_U",
    "OPEN_DEPTH_M",
    "Geo",
    "Layers",
    "Stack",
    "family",
    "geometry",
    "seg",
    "stack",
    "turning",
]

#: extra depth added below the deepest point when a profile without a bottom keeps a
#: positive gradient: a ray turning deeper than this reaches hundreds of km, far beyond
#: any acoustic network
OPEN_DEPTH_M = 1.0e5
#: the ray families between two depths (see :mod:`.layered`): direct, lower turn, upper turn
FAM_D, FAM_L, FAM_U = 0, 1, 2
# the layer stack


@dataclass(frozen=True)
class Stack:
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
    def from_points(cls, z: NDArray[np.float64], c: NDArray[np.float64], bottom: bool) -> Stack:
        h = np.diff(z)
        return cls(z=z, c=c, g=np.diff(c) / h, h=h, bottom=bottom)

    def speed(self, zq: NDArray[np.float64]) -> NDArray[np.float64]:
        k = self.layer(zq)
        return self.c[k] + self.g[k] * (zq - self.z[k])

    def layer(self, zq: NDArray[np.float64]) -> NDArray[np.intp]:
        return np.clip(np.searchsorted(self.z, zq, side="right") - 1, 0, self.g.size - 1)

    def extended(self, depth: float = 1.0e4) -> tuple[Stack, float]:
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
        return Stack.from_points(np.concatenate(z), np.concatenate(c), bottom=False), up

    def mirrored(self, boundary: Literal["surface", "bottom"]) -> Stack:
        """The profile unfolded about a boundary: one reflection becomes a direct path."""
        zm = self.zmax
        if boundary == "surface":
            z = np.concatenate([zm - self.z[::-1], zm + self.z[1:]])
            c = np.concatenate([self.c[::-1], self.c[1:]])
        else:
            z = np.concatenate([self.z, 2.0 * zm - self.z[-2::-1]])
            c = np.concatenate([self.c, self.c[-2::-1]])
        return Stack.from_points(z, c, bottom=self.bottom)


def stack(profile: Layered, z_deepest: float) -> Stack:
    """The water column [0, zmax] of ``profile`` as layers (bottom, or an open end)."""
    d, c = profile.depths, profile.speeds
    if profile.bottom is not None:
        zmax, bottom = profile.bottom, True
    else:
        g_last = (c[-1] - c[-2]) / (d[-1] - d[-2])
        zmax = max(float(d[-1]), z_deepest)
        if g_last > 0.0:
            zmax += OPEN_DEPTH_M
        bottom = False
    keep = d < zmax
    z = np.concatenate([d[keep], [zmax]])
    cz = np.concatenate([c[keep], profile.speed(np.array([zmax]))])
    return Stack.from_points(z, cz, bottom)


# ----------------------------------------------------------------------------------------
# closed forms inside one layer


def log1p_ratio(u: NDArray[np.float64]) -> NDArray[np.float64]:
    """log(1 + u) / u, = 1 at u = 0, accurate for tiny u."""
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.log1p(u) / u
    return np.where(u == 0.0, 1.0, r)


def asinc(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """arcsin(v) / v, = 1 at v = 0."""
    v = np.clip(v, -1.0, 1.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.arcsin(v) / v
    return np.where(v == 0.0, 1.0, r)


def inv_p(pmax, phi):
    """The Snell invariant p = p_max cos(phi) with its angle: (p, p_max, sin phi, cos phi)."""
    cp = np.cos(phi)
    return (pmax * cp, pmax, np.sin(phi), cp)


def expand(inv):
    return tuple(np.asarray(v)[..., None] for v in inv)


def cos_sin(inv, c: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(cos theta, |sin theta|) at speed c for the invariant ``inv``.

    sin^2 = sin^2 phi + cos^2 phi (1 - u)(1 + u), u = c / c_max: exact near grazing (where
    1 - (p c)^2 would lose half the digits), and sin theta = sin phi where c = c_max.
    """
    _, pm, sp, cp = inv
    u = c * pm
    return cp * u, np.sqrt(np.maximum(sp * sp + cp * cp * ((1.0 - u) * (1.0 + u)), 0.0))


def seg(inv, c1, c2, dz, g, full: bool, deriv: bool = False):
    """Range (and time, arc length) of a monotone ray piece from speed c1 down to c2, dz >= 0.

    Range  X = (sin th1 - sin th2) / (p g) = p (c1 + c2) dz / (sin th1 + sin th2)   (eq 6)
    Time   T = [ln(c2/c1) + ln((1 + sin th1)/(1 + sin th2))] / g                   (eq 13)
    Length L = (arcsin(p c2) - arcsin(p c1)) / (p g)                              (eq 19)
    each written as dz times a bounded factor, so g = 0 (straight line) is exact.
    """
    p = inv[0]
    _, w1 = cos_sin(inv, c1)
    _, w2 = cos_sin(inv, c2)
    den = w1 + w2
    pos = dz > 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.where(pos, p * (c1 + c2) * dz / den, 0.0)
        if deriv:  # d X / d p, with d sin(th) / d p = -p c^2 / sin(th)
            return x, np.where(pos, x / p + x * p * (c1 * c1 / w1 + c2 * c2 / w2) / den, 0.0), None
        if not full:
            return x, None, None
        q = p * p * (c1 + c2) * dz / (den * (1.0 + w2))
        t = dz / c1 * log1p_ratio(g * dz / c1) + q * log1p_ratio(g * q)
        den2 = c2 * w1 + c1 * w2
        lfac = dz * (c1 + c2) / den2
        arc = lfac * asinc(p * g * lfac)
        t = np.where(pos, t, 0.0)
        arc = np.where(pos, arc, 0.0)
    return x, t, arc


# ----------------------------------------------------------------------------------------
# ray families


@dataclass
class Geo:
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

    def take(self, idx: NDArray[np.intp]) -> Geo:
        return Geo(*(getattr(self, f)[idx] for f in self.__dataclass_fields__))

    def col(self) -> Geo:
        return Geo(*(getattr(self, f)[:, None] for f in self.__dataclass_fields__))

    def arrays(self) -> tuple[NDArray, ...]:
        """(za, zb, ka, kb, ca, cb, pmax) as the compiled kernels take them (see _layered_jit)."""
        f, i = np.float64, np.int64
        return tuple(
            np.ascontiguousarray(getattr(self, name), dtype=t)
            for name, t in (("za", f), ("zb", f), ("ka", i), ("kb", i), ("ca", f), ("cb", f), ("pmax", f))
        )


def geometry(st: Stack, za: NDArray[np.float64], zb: NDArray[np.float64]) -> Geo:
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
    return Geo(za, zb, ka, kb, ca, cb, 1.0 / cmax, phi_l, phi_u)


class Layers:
    """Full-layer closed forms for one array of invariants p (shape S), layers on the last axis."""

    def __init__(self, st: Stack, inv, full: bool, deriv: bool = False) -> None:
        self.st, self.p, self.full, self.deriv = st, inv, full, deriv
        ie = expand(inv)
        pe = ie[0]
        if full:
            self.pc = pe * st.c
            self.x, self.t, self.arc = seg(ie, st.c[:-1], st.c[1:], st.h, st.g, True)
        else:
            # range only (the hot path of the root finder): sin theta once per breakpoint
            self.pc, w = cos_sin(ie, st.c)
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
            xa, ta, la = seg(p, c1, ce, e1 - z1, g1, full, dv)
            xb, tb, lb = seg(p, st.c[k2], c2, np.where(same, 0.0, z2 - st.z[k2]), g2, full, dv)
        elif turn == "bottom":
            xa, ta, la = seg(p, c1, st.c[k1 + 1], np.where(same, 0.0, st.z[k1 + 1] - z1), g1, full, dv)
            xb, tb, lb = turning(p, np.where(same, c1, st.c[k2]), g2, full, dv)
        else:
            xa, ta, la = turning(p, np.where(same, c2, st.c[k1 + 1]), g1, full, dv)
            xb, tb, lb = seg(p, st.c[k2], c2, np.where(same, 0.0, z2 - st.z[k2]), g2, full, dv)
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


def turning(inv, c, g, full: bool, deriv: bool = False):
    """Range, time and arc length from speed c to the turning point c = 1/p in a layer of
    gradient g: X = sin th / (p |g|), T = artanh(sin th) / |g|, L = th / (p |g|) (eqs 6, 13, 19
    with the turning angle 0)."""
    p = inv[0]
    s, w = cos_sin(inv, c)
    ag = np.abs(g)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = w / (p * ag)
        if deriv:
            return x, -1.0 / (w * p * p * ag), None
        if not full:
            return x, None, None
        return x, np.arctanh(w) / ag, np.arctan2(w, s) / (p * ag)


def family(st: Stack, geo: Geo, fam: int, phi: NDArray[np.float64], full: bool = False, deriv: bool = False):
    """Range X(phi) (NaN where the family has no ray), and when ``full`` also time, arc
    length and turning depth, for invariants p = p_max cos(phi). With ``deriv`` the second
    value is d X / d phi instead. The solver evaluates X and d X / d phi with the compiled
    ``_range``; this numpy version is its reference (tests) and evaluates the roots."""
    inv = inv_p(geo.pmax, phi)
    p = inv[0]
    lay = Layers(st, inv, full, deriv)
    xd, td, ld = lay.interval(geo.za, geo.ka, geo.zb, geo.kb)
    dpdphi = -geo.pmax * np.sin(phi)
    if fam == FAM_D:
        if deriv:
            return xd, td * dpdphi, None, None
        turn = np.full(np.shape(xd), np.nan)
        return xd, td, ld, turn
    blocked = lay.pc >= 1.0
    nk = st.g.size
    if fam == FAM_L:
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
