"""Compiled range evaluations of the layered solver's ray families (numba): the phi scan
(:func:`family_range`) and the Newton refinement (:func:`refine`) of layered.py.

Imported lazily by :mod:`aquasim_py.channel.layered` on its first solve (``import numba``
costs about 64 MiB and 0.15 s, which runs without a layered profile never pay). One family
evaluation is a loop over the layers one ray crosses, per (pair, sample); the numpy version
(``layer_stack.family``) does the same arithmetic as ~25 passes over (pairs x samples x layers)
arrays. Every expression here is written in the numpy version's order, and the layer sums in
numpy's pairwise order (up to 128 layers), so both give the same doubles
(tests/channel/test_layered.py checks it); the time, arc length and turning depth of the
accepted roots stay in numpy (numpy's log1p and arcsin are not libm's on every machine).

Arguments shared by the kernels: the layer stack ``st = (z, c, g, h, chs)``: breakpoint
depths z (m) and speeds c (m/s) (K+1,), gradients g (1/s) and thicknesses h (m) (K,),
chs = (c_k + c_k+1) h_k (m^2/s); the pair geometry ``geo = (za, zb, ka, kb, ca, cb, pmax)``:
depths of the shallower and deeper point (m), their layers, their speeds (m/s) and
p_max = 1 / max c between them (s/m), each (n,). ``fam`` is 0 (direct), 1 (lower turn) or
2 (upper turn), as in layered.py; grazing angles phi are in rad.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

_FAM_D, _FAM_L = 0, 1
_EPS = float(np.finfo(float).eps)
# IEEE division (x / 0 is inf or NaN, as in numpy, not ZeroDivisionError); no fastmath: every
# operation rounds as written, in the written order
_jit = njit(cache=True, error_model="numpy")
# the family evaluation, which takes arrays, is inlined into the kernel's loop (a call that
# passes arrays costs about as much as the arithmetic of a family evaluation)
_inline = njit(cache=True, error_model="numpy", inline="always")


@_jit
def _sin_theta(c: float, pm: float, sp: float, cp: float) -> float:
    """|sin theta| at speed c (m/s) for p = pm cos(phi) (layered._cos_sin)."""
    u = c * pm
    v = sp * sp + cp * cp * ((1.0 - u) * (1.0 + u))
    if v < 0.0:  # np.maximum(v, 0.0): NaN stays NaN
        v = 0.0
    return math.sqrt(v)


@_jit
def _seg(p: float, c1: float, w1: float, c2: float, w2: float, dz: float, deriv: bool) -> tuple[float, float]:
    """Range X (m) of a monotone piece from speed c1 to c2 (|sin theta| w1, w2) over depth
    dz >= 0 (m) and, with ``deriv``, d X / d p (m^2/s) (layered._seg, eq 6)."""
    if not dz > 0.0:
        return 0.0, 0.0
    den = w1 + w2
    x = p * (c1 + c2) * dz / den
    if not deriv:
        return x, 0.0
    return x, x / p + x * p * (c1 * c1 / w1 + c2 * c2 / w2) / den


@_jit
def _turning(p: float, w: float, g: float, deriv: bool) -> tuple[float, float]:
    """Range (m) from |sin theta| = w to the turning point in a layer of gradient g (1/s),
    and d X / d p (layered._turning: X = sin th / (p |g|), eq 6 with the turning angle 0)."""
    ag = abs(g)
    x = w / (p * ag)
    if not deriv:
        return x, 0.0
    return x, -1.0 / (w * p * p * ag)


@_inline
def _family1(z, c, g, chs, za, zb, ka, kb, ca, cb, pm, fam: int, phi: float, deriv: bool, buf) -> tuple[float, float]:
    """Range X(phi) (m; NaN where the family has no ray) of one pair and, with ``deriv``,
    d X / d phi (m/rad) (layer_stack.family with full=False): the direct piece A -> B, and for a
    turning family the piece from B down to its turning layer (L) or from A up to it (U).

    Each piece is two partial layers at its ends plus the full layers k1 < k < k2, whose
    ranges (layered._Layers) are summed as numpy sums ``np.where(mid, x, 0).sum(axis=-1)``
    over K <= 128 layers: 8 accumulators (layer index mod 8) over the largest multiple m of
    8, added as a tree, then the rest in turn; zeros change no sum of finite or NaN terms
    (only the sign of an all-zero one), so only the layers k1 < k < k2 are added. Above 128
    layers numpy splits the sum into halves recursively; the sum here is then a plain loop
    (the same to a few ulps). ``buf``: scratch of 2 K + 16 (the accumulators of X and
    d X / d p, then the layers after m)."""
    sp = math.sin(phi)
    cp = math.cos(phi)
    p = pm * cp
    wa = _sin_theta(ca, pm, sp, cp)
    wb = _sin_theta(cb, pm, sp, cp)
    nk = g.size
    # the turning layer kt: above the first breakpoint below B (L) or below the last one
    # above A (U) that the ray cannot pass
    ok = fam == _FAM_D
    kt = kb if fam == _FAM_L else ka
    if fam == _FAM_L:
        for j in range(kb + 1, nk + 1):
            if z[j] > zb and cp * (c[j] * pm) >= 1.0:
                ok, kt = True, j - 1
                break
    elif fam != _FAM_D:
        for j in range(ka, -1, -1):
            if z[j] < za and cp * (c[j] * pm) >= 1.0:
                ok, kt = True, j
                break
    m = nk - nk % 8 if nk <= 128 else 0
    xd, td, xe, te = 0.0, 0.0, 0.0, 0.0
    for piece in range(1 if fam == _FAM_D else 2):
        if piece == 0:
            k1, k2 = ka, kb
        elif fam == _FAM_L:
            k1, k2 = kb, kt
        else:
            k1, k2 = kt, ka
        # the full layers k1 < k < k2, and |sin theta| at breakpoints k1 + 1 and k2
        sx, sdx = 0.0, 0.0
        w_first = w_last = 0.0
        if k2 > k1:
            w0 = _sin_theta(c[k1 + 1], pm, sp, cp)
            w_first = w0
            if k2 - k1 >= 2:
                buf[:16] = 0.0
                q0 = c[k1 + 1] * c[k1 + 1] / w0
                dx = 0.0
                for k in range(k1 + 1, k2):
                    w1 = _sin_theta(c[k + 1], pm, sp, cp)
                    den = w0 + w1
                    x = p * chs[k] / den
                    if deriv:
                        q1 = c[k + 1] * c[k + 1] / w1
                        dx = x / p + x * p * (q0 + q1) / den
                        q0 = q1
                    w0 = w1
                    if k < m:
                        buf[k % 8] += x
                        buf[8 + k % 8] += dx
                    else:
                        buf[16 + k], buf[16 + nk + k] = x, dx
                sx = ((buf[0] + buf[1]) + (buf[2] + buf[3])) + ((buf[4] + buf[5]) + (buf[6] + buf[7]))
                sdx = ((buf[8] + buf[9]) + (buf[10] + buf[11])) + ((buf[12] + buf[13]) + (buf[14] + buf[15]))
                for k in range(max(k1 + 1, m), k2):
                    sx += buf[16 + k]
                    sdx += buf[16 + nk + k]
            w_last = w0
        # the partial layers at the piece's ends (layered._Layers.interval)
        if piece == 0:
            if ka == kb:
                xa, da = _seg(p, ca, wa, cb, wb, zb - za, deriv)
                xb, db = 0.0, 0.0
            else:
                xa, da = _seg(p, ca, wa, c[ka + 1], w_first, z[ka + 1] - za, deriv)
                xb, db = _seg(p, c[kb], w_last, cb, wb, zb - z[kb], deriv)
            xd, td = xa + xb + sx, da + db + sdx
        else:
            xs, ds = 0.0, 0.0
            if k1 == k2:
                wt = wb if fam == _FAM_L else wa
            elif fam == _FAM_L:
                xs, ds = _seg(p, cb, wb, c[kb + 1], w_first, z[kb + 1] - zb, deriv)
                wt = w_last
            else:
                xs, ds = _seg(p, c[ka], w_last, ca, wa, za - z[ka], deriv)
                wt = w_first
            xt, dt = _turning(p, wt, g[kt], deriv)
            xe, te = xs + xt + sx, ds + dt + sdx
    dpdphi = -pm * sp
    if fam == _FAM_D:
        return xd, td * dpdphi
    x = xd + 2.0 * xe if ok else math.nan
    if not deriv:
        return x, 0.0
    return x, (td + 2.0 * te) * dpdphi


@_jit
def _sign(v: float) -> float:
    if v > 0.0:
        return 1.0
    if v < 0.0:
        return -1.0
    return v  # 0 or NaN, as np.sign


@_jit
def _evaluate(st, geo, fam: int, phi, deriv: bool, newton: bool, target, hlo, hhi, rtol: float, maxit: int):
    """Both kernels in one loop with one call of _family1, so numba inlines (and compiles) the
    family evaluation once: see family_range and refine. Returns two (n, S) arrays."""
    z, c, g, _, chs = st
    za, zb, ka, kb, ca, cb, pm = geo
    n, s = phi.shape
    out = np.empty((n, s))
    dout = np.empty((n, s))
    buf = np.zeros(2 * g.size + 16)
    for i in range(n):
        steps = s
        a = b = x = fa = fb = tol = bst = fbs = 0.0  # numba types every variable on every path
        prev = math.inf
        if newton:
            a, b, x = phi[i, 0], phi[i, 1], phi[i, 2]
            fa, fb = hlo[i], hhi[i]
            tol = rtol * max(target[i], 1.0)
            if not (math.isfinite(x) and min(a, b) < x < max(a, b)):
                x = 0.5 * (a + b)
            bst = a if abs(fa) <= abs(fb) else b
            fbs = min(abs(fa), abs(fb))
            steps = maxit if fbs > tol else 0
        for k in range(steps):
            ph = x if newton else phi[i, k]
            fx, dfx = _family1(z, c, g, chs, za[i], zb[i], ka[i], kb[i], ca[i], cb[i], pm[i], fam, ph, deriv, buf)
            if not newton:
                out[i, k], dout[i, k] = fx, dfx
                continue
            # layered._refine's step
            fx = fx - target[i]
            if _sign(fx) == _sign(fa):
                a, fa = x, fx
            else:
                b = x
            afx = abs(fx)
            if afx < fbs:
                bst, fbs = x, afx
            nx = x - fx / dfx
            lo, hi = min(a, b), max(a, b)
            slow = afx > 0.5 * prev
            if not math.isfinite(nx) or nx <= lo or nx >= hi or (slow and prev < math.inf):
                nx = 0.5 * (a + b)
                prev = math.inf
            else:
                prev = afx
            x = nx
            if afx <= tol or hi - lo <= 4.0 * _EPS * max(hi, 1e-300) or not math.isfinite(fx):
                break
        if newton:
            out[i, 0], dout[i, 0] = bst, fbs
    return out, dout


def family_range(st, geo, fam: int, phi: NDArray[np.float64], deriv: bool):
    """X (m; NaN where the family has no ray or phi is NaN) and, with ``deriv``, d X / d phi
    (m/rad) of family ``fam`` at the grazing angles phi (n, S) of the n pairs of ``geo``."""
    none = np.empty(0)
    return _evaluate(st, geo, fam, np.ascontiguousarray(phi, dtype=float), deriv, False, none, none, none, 0.0, 0)


def refine(st, geo, fam: int, target, lo, hi, hlo, hhi, start, rtol: float, maxit: int):
    """Safeguarded Newton iteration on h(phi) = X(phi) - target (m) in each bracket [lo, hi]
    (rad, h(lo) = hlo and h(hi) = hhi of opposite signs) from ``start`` (the midpoint where
    that is not inside), to |h| <= rtol max(target, 1 m) or at most ``maxit`` steps,
    bisecting whenever a step leaves the bracket or |h| falls by less than half; returns
    (phi, |h|) at the best point of each bracket (layered._refine)."""
    t, fa, fb = (np.ascontiguousarray(v, dtype=float) for v in (target, hlo, hhi))
    rows = np.ascontiguousarray(np.stack([lo, hi, start], axis=1), dtype=float)
    best, fbest = _evaluate(st, geo, fam, rows, True, True, t, fa, fb, rtol, maxit)
    return best[:, 0], fbest[:, 0]
