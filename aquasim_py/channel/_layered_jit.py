"""Compiled range evaluations of the layered solver's ray families (numba).

Imported lazily by :mod:`aquasim_py.channel.layered` on its first solve (``import numba``
costs about 64 MiB and 0.15 s, which runs without a layered profile never pay). One family
evaluation is a loop over the layers one ray crosses, per (pair, sample); the numpy version
(``layered._family``) does the same arithmetic as ~25 passes over (pairs x samples x layers)
arrays. Every expression here is written in the numpy version's order, and the layer sums in
numpy's pairwise order, so both give the same doubles (tests/channel/test_layered.py checks
it); the time, arc length and turning depth of the accepted roots stay in numpy.

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
# the per-evaluation helpers that take arrays are inlined into the kernels' loops (a call
# that passes arrays costs about as much as the arithmetic of a family evaluation)
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
def _leaf_sum(v: NDArray[np.float64], a: int, b: int, lo: int, n: int) -> float:
    """numpy's pairwise sum of the n <= 128 elements v[lo:lo + n] of which only those with
    a <= i < b are kept (the others are zeros): a plain loop below 8 elements, else 8
    accumulators over the largest multiple of 8, a tree, and the rest in turn."""
    a, b = max(a, lo), min(b, lo + n)
    r = np.zeros(8)
    m = lo + n - n % 8
    for i in range(a, min(b, m)):
        r[(i - lo) % 8] += v[i]
    res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    for i in range(max(a, m), b):
        res += v[i]
    return res


@_jit
def _big_sum(v: NDArray[np.float64], k1: int, k2: int) -> float:
    """Sum of v[i] over k1 < i < k2 (the others zeros) in numpy's order for a reduction of
    v.size > 128 elements: numpy halves (at a multiple of 8) and adds the halves' sums, a
    recursion that runs here on an explicit stack (numba 0.68 crashes loading the cached
    machine code of a self-recursive function)."""
    los = np.empty(192, np.int64)
    ns = np.empty(192, np.int64)  # -1: add the two sums on top of the value stack
    vals = np.empty(64)
    top, nv = 0, 0
    los[0], ns[0] = 0, v.size
    while top >= 0:
        lo, m = los[top], ns[top]
        top -= 1
        if m < 0:
            nv -= 1
            vals[nv - 1] = vals[nv - 1] + vals[nv]
        elif m <= 128:
            vals[nv] = _leaf_sum(v, k1 + 1, k2, lo, m)
            nv += 1
        else:
            n2 = m // 2
            n2 -= n2 % 8
            los[top + 1], ns[top + 1] = 0, -1
            los[top + 2], ns[top + 2] = lo + n2, m - n2
            los[top + 3], ns[top + 3] = lo, n2
            top += 3
    return vals[0]


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
def _layers(c, chs, k1: int, k2: int, p: float, pm: float, sp: float, cp: float, deriv: bool, buf):
    """Ranges and d X / d p of the full layers k1 < k < k2 (layered._Layers, range only),
    each summed in numpy's pairwise order for ``np.where(mid, x, 0).sum(axis=-1)`` over the
    K layers, and |sin theta| at breakpoints k1 + 1 and k2 (k1 + 1 twice if k2 <= k1 + 1).

    Up to 128 layers numpy keeps 8 accumulators (layer index mod 8) over the largest multiple
    m of 8, adds them as a tree and then the rest in turn; zeros change no sum of finite or
    NaN terms (only the sign of an all-zero one), so only the layers k1 < k < k2 are added.
    Above 128 layers the values go to ``buf`` (scratch of 2 K + 16) for _big_sum."""
    w0 = _sin_theta(c[k1 + 1], pm, sp, cp)
    if k2 - k1 < 2:
        return 0.0, 0.0, w0, w0
    n = chs.size
    big = n > 128
    m = n - n % 8
    for j in range(16):
        buf[j] = 0.0
    sx, sdx, tree = 0.0, 0.0, False
    wf = w0
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
        if big:
            buf[16 + k], buf[16 + n + k] = x, dx
        elif k < m:
            buf[k % 8] += x
            buf[8 + k % 8] += dx
        else:
            if not tree:
                sx = ((buf[0] + buf[1]) + (buf[2] + buf[3])) + ((buf[4] + buf[5]) + (buf[6] + buf[7]))
                sdx = ((buf[8] + buf[9]) + (buf[10] + buf[11])) + ((buf[12] + buf[13]) + (buf[14] + buf[15]))
                tree = True
            sx += x
            sdx += dx
    if big:
        sx = _big_sum(buf[16 : 16 + n], k1, k2)
        sdx = _big_sum(buf[16 + n :], k1, k2)
    elif not tree:
        sx = ((buf[0] + buf[1]) + (buf[2] + buf[3])) + ((buf[4] + buf[5]) + (buf[6] + buf[7]))
        sdx = ((buf[8] + buf[9]) + (buf[10] + buf[11])) + ((buf[12] + buf[13]) + (buf[14] + buf[15]))
    return sx, sdx, wf, w0


@_inline
def _family1(z, c, g, chs, za, zb, ka, kb, ca, cb, pm, fam: int, phi: float, deriv: bool, buf) -> tuple[float, float]:
    """Range X(phi) (m; NaN where the family has no ray) of one pair and, with ``deriv``,
    d X / d phi (m/rad) (layered._family with full=False)."""
    sp = math.sin(phi)
    cp = math.cos(phi)
    p = pm * cp
    wa = _sin_theta(ca, pm, sp, cp)
    wb = _sin_theta(cb, pm, sp, cp)
    # the direct piece A -> B (layered._Layers.interval without a turn)
    if ka == kb:
        xd, td = _seg(p, ca, wa, cb, wb, zb - za, deriv)
    else:
        sx, sdx, w1, w2 = _layers(c, chs, ka, kb, p, pm, sp, cp, deriv, buf)
        xa, da = _seg(p, ca, wa, c[ka + 1], w1, z[ka + 1] - za, deriv)
        xb, db = _seg(p, c[kb], w2, cb, wb, zb - z[kb], deriv)
        xd, td = xa + xb + sx, da + db + sdx
    dpdphi = -pm * sp
    if fam == _FAM_D:
        return xd, td * dpdphi
    # the turning layer kt: above the first breakpoint below B (L) or below the last one
    # above A (U) that the ray cannot pass
    nk = g.size
    ok = False
    if fam == _FAM_L:
        kt = kb
        for j in range(kb + 1, nk + 1):
            if z[j] > zb and cp * (c[j] * pm) >= 1.0:
                ok, kt = True, j - 1
                break
        k1, k2 = kb, kt
    else:
        kt = ka
        for j in range(ka, -1, -1):
            if z[j] < za and cp * (c[j] * pm) >= 1.0:
                ok, kt = True, j
                break
        k1, k2 = kt, ka
    # the piece between the end point and the turning layer, then the turning piece
    xs, ds, sx, sdx = 0.0, 0.0, 0.0, 0.0
    if k1 == k2:
        wt = wb if fam == _FAM_L else wa
    else:
        sx, sdx, w1, w2 = _layers(c, chs, k1, k2, p, pm, sp, cp, deriv, buf)
        if fam == _FAM_L:
            xs, ds = _seg(p, cb, wb, c[kb + 1], w1, z[kb + 1] - zb, deriv)
            wt = w2
        else:
            xs, ds = _seg(p, c[ka], w2, ca, wa, za - z[ka], deriv)
            wt = w1
    xt, dt = _turning(p, wt, g[kt], deriv)
    x = xd + 2.0 * (xs + xt + sx) if ok else math.nan
    if not deriv:
        return x, 0.0
    return x, (td + 2.0 * (ds + dt + sdx)) * dpdphi


@_jit
def family_range(st, geo, fam: int, phi, deriv: bool):
    """X (m) and, with ``deriv``, d X / d phi (m/rad) of family ``fam`` at phi (n, S) for the
    n pairs of ``geo``; NaN phi gives NaN."""
    z, c, g, _, chs = st
    za, zb, ka, kb, ca, cb, pm = geo
    n, s = phi.shape
    x = np.empty((n, s))
    dx = np.empty((n, s))
    buf = np.zeros(2 * g.size + 16)
    for i in range(n):
        for j in range(s):
            x[i, j], dx[i, j] = _family1(
                z, c, g, chs, za[i], zb[i], ka[i], kb[i], ca[i], cb[i], pm[i], fam, phi[i, j], deriv, buf
            )
    return x, dx


@_jit
def _sign(v: float) -> float:
    if v > 0.0:
        return 1.0
    if v < 0.0:
        return -1.0
    return v  # 0 or NaN, as np.sign


@_jit
def refine(st, geo, fam: int, target, lo, hi, hlo, hhi, guess, use_guess: bool, rtol: float, maxit: int):
    """Safeguarded Newton iteration on h(phi) = X(phi) - target (m) in each bracket [lo, hi]
    (rad, h(lo) h(hi) <= 0) from ``guess`` or the regula falsi point, to |h| <= rtol
    max(target, 1 m) or at most ``maxit`` steps, bisecting whenever a step leaves the
    bracket or |h| falls by less than half; returns (phi, |h|) at the best point of each."""
    z, c, g, _, chs = st
    za, zb, ka, kb, ca, cb, pm = geo
    m = target.size
    best = np.empty(m)
    fbest = np.empty(m)
    buf = np.zeros(2 * g.size + 16)
    for r in range(m):
        a, b, fa, fb = lo[r], hi[r], hlo[r], hhi[r]
        tol = rtol * max(target[r], 1.0)
        x = guess[r] if use_guess else a - fa * (b - a) / (fb - fa)  # regula falsi start
        if not (math.isfinite(x) and min(a, b) < x < max(a, b)):
            x = 0.5 * (a + b)
        bst = a if abs(fa) <= abs(fb) else b
        fbs = min(abs(fa), abs(fb))
        prev = math.inf
        if fbs > tol:
            for _ in range(maxit):
                # deriv = True, typed as a plain bool (a literal would compile _seg and
                # _turning a second time)
                fx, dfx = _family1(
                    z, c, g, chs, za[r], zb[r], ka[r], kb[r], ca[r], cb[r], pm[r], fam, x, maxit > 0, buf
                )
                fx = fx - target[r]
                if _sign(fx) == _sign(fa):
                    a, fa = x, fx
                else:
                    b = x
                afx = abs(fx)
                if afx < fbs:
                    bst, fbs = x, afx
                nx = x - fx / dfx
                lo_, hi_ = min(a, b), max(a, b)
                slow = afx > 0.5 * prev
                if not math.isfinite(nx) or nx <= lo_ or nx >= hi_ or (slow and prev < math.inf):
                    nx = 0.5 * (a + b)
                    prev = math.inf
                else:
                    prev = afx
                x = nx
                if afx <= tol or hi_ - lo_ <= 4.0 * _EPS * max(hi_, 1e-300) or not math.isfinite(fx):
                    break
        best[r] = bst
        fbest[r] = fbs
    return best, fbest
