"""Compiled kernels of the range-dependent ray tracer (numba): the exact cell-by-cell ray walk
through a (range, depth) section and the per-link eigenray search. See :mod:`.rangedep` for
the model and the public API; this module is imported lazily on the first range-dependent solve.

The section of one link: column ranges ``rr`` (J,) from 0 (the source) to R (the receiver),
depth nodes ``zz`` (K,) from 0, speeds ``cc`` (J, K), sea-floor depths ``bb`` (J,) at the
columns (a polyline between them). Each grid rectangle is one cell where its four speeds lie on
a plane (always so for a depth-only profile) and two triangles otherwise, cut along the diagonal
whose end speeds differ least (so that the section of a link reversed is the mirror image: the
medium does not depend on which end transmits); c is linear on every cell, so inside a cell a ray is an
exact arc of a circle (Snell's law in the frame of the cell's gradient; the isogradient case
rotated) and every crossing, reflection point, travel time and arc length is closed form.

Angles: the ray direction is the unit vector (cos theta, sin theta) in (range, depth), theta the
grazing angle positive down, as everywhere in aquasim_py.channel.
"""

from __future__ import annotations

import cmath
import math

import numpy as np
from numba import njit

_jit = njit(cache=True, error_model="numpy")

# edge codes of a cell
E_TOP, E_RIGHT, E_BOTTOM, E_LEFT, E_DIAG, E_FLOOR, E_TARGET, E_NONE = 0, 1, 2, 3, 4, 5, 6, -1
# cell parts: the whole (planar) rectangle; the two triangles of the diagonal (r_j, z_k) -
# (r_j+1, z_k+1) above / below it; the two of the other diagonal above-left / below-right
P_WHOLE, P_UPPER, P_LOWER, P_UL, P_LR = 0, 1, 2, 3, 4
# ray status
S_REACHED, S_LOST = 1, 0
MAX_STEPS = 200000


@_jit
def rayleigh(grazing: float, cw: float, cb: float, rho: float, delta: float) -> complex:
    """Plane-wave reflection coefficient of a fluid half-space (speed cb, density ratio rho,
    loss tangent delta) at a grazing angle (rad) from water of speed cw and unit density."""
    kw = 1.0 / cw
    kzw = kw * math.sin(abs(grazing))
    kr = kw * math.cos(grazing)
    kb = complex(1.0, delta) / cb
    kzb = cmath.sqrt(kb * kb - kr * kr)
    if kzb.imag < 0.0:
        kzb = -kzb
    return (rho * kzw - kzb) / (rho * kzw + kzb)


@_jit
def rayleigh_array(th, cw, cb, rho, delta):
    out = np.empty(th.size, np.complex128)
    for i in range(th.size):
        out[i] = rayleigh(th[i], cw[i], cb, rho, delta)
    return out


@_jit
def _log1p_ratio(x: float) -> float:
    """log(1 + x) / x, 1 at 0."""
    if x == 0.0:
        return 1.0
    return math.log1p(x) / x


@_jit
def _sinc(x: float) -> float:
    if abs(x) < 1e-8:
        return 1.0 - x * x / 6.0
    return math.sin(x) / x


@_jit
def _atanc(x: float) -> float:
    if abs(x) < 1e-8:
        return 1.0 - x * x / 3.0
    return math.atan(x) / x


@_jit
def _planar(cc, j, k) -> bool:
    return cc[j, k] - cc[j + 1, k] - cc[j, k + 1] + cc[j + 1, k + 1] == 0.0


@_jit
def _anti(cc, j, k) -> bool:
    """A non-planar rectangle is cut along the diagonal whose end speeds differ least (a rule
    that does not depend on the direction of the link, so the section of d -> s is the mirror
    image of that of s -> d); on a tie along (r_j, z_k) - (r_j+1, z_k+1)."""
    return abs(cc[j + 1, k] - cc[j, k + 1]) < abs(cc[j, k] - cc[j + 1, k + 1])


@_jit
def _plane(rr, zz, cc, j, k, part):
    """(c at (r_j, z_k) on the cell's plane, dc/dr, dc/dz) of a cell (m/s, 1/s, 1/s)."""
    dr = rr[j + 1] - rr[j]
    dz = zz[k + 1] - zz[k]
    c00, c10, c01, c11 = cc[j, k], cc[j + 1, k], cc[j, k + 1], cc[j + 1, k + 1]
    if part == P_WHOLE:
        return c00, (c10 - c00) / dr, (c01 - c00) / dz
    if part == P_UPPER:
        return c00, (c10 - c00) / dr, (c11 - c10) / dz
    if part == P_LOWER:
        return c00, (c11 - c01) / dr, (c01 - c00) / dz
    if part == P_UL:
        return c00, (c10 - c00) / dr, (c01 - c00) / dz
    return c01 + c10 - c11, (c11 - c01) / dr, (c11 - c10) / dz


@_jit
def _part_entering(cc, j, k, edge):
    """The part of rectangle (j, k) that a ray entering through ``edge`` is in."""
    if _planar(cc, j, k):
        return P_WHOLE
    if _anti(cc, j, k):
        return P_UL if edge in (E_TOP, E_LEFT) else P_LR
    return P_UPPER if edge in (E_TOP, E_RIGHT) else P_LOWER


@_jit
def _part_at(rr, zz, cc, j, k, r, z):
    if _planar(cc, j, k):
        return P_WHOLE
    u = (r - rr[j]) / (rr[j + 1] - rr[j])
    v = (z - zz[k]) / (zz[k + 1] - zz[k])
    if _anti(cc, j, k):
        return P_UL if u + v <= 1.0 else P_LR
    return P_UPPER if v <= u else P_LOWER


@_jit
def _exit_s(e, A, B, kap, entry):
    """Smallest positive arc length to the line (outward normal n, signed offset e = n.(X - P))
    along the arc X(s) = X + (t sin u + m (1 - cos u)) / kappa, u = kappa s, with A = n.t,
    B = n.m (m the left normal of t). ``entry``: the ray sits on this line (only the far root)."""
    best = math.inf
    ek = e * kap
    if entry:
        # roots tau = 0 and tau = -A / B
        if kap != 0.0 and B != 0.0:
            s = 2.0 * math.atan(-A / B) / kap
            if s > 0.0:
                best = s
        return best
    if e >= 0.0 and A > 0.0:
        return 0.0  # on the line (rounding) and heading out
    disc = A * A - ek * (ek + 2.0 * B)
    if disc < 0.0:
        return best
    sq = math.sqrt(disc)
    q = -(A + sq) if A >= 0.0 else -(A - sq)
    if q != 0.0:
        ta = ek / q
        s = 2.0 * e / q * _atanc(ta)
        if s > 0.0:
            best = s
    den = ek + 2.0 * B
    if kap != 0.0:
        if den != 0.0:
            s = 2.0 * math.atan(q / den) / kap
        else:
            s = math.pi / abs(kap)
        if s > 0.0 and s < best:
            best = s
    return best


@_jit
def _arc_time(tr, tz, s, kap, gr, gz, c1, dxr, dxz):
    """Travel time (s) along a circular arc of length s (m) and curvature kap in a medium of
    constant gradient (gr, gz), speed c1 at the start, start direction (tr, tz), chord (dxr,
    dxz). T = (F1 - F2) / a, F = atanh(sin th'), written as differences of log1p of small ratios
    (no cancellation) and without dividing by the gradient a (exact as a -> 0)."""
    a = math.hypot(gr, gz)
    if a == 0.0:
        return s / c1
    ur, uz = gr / a, gz / a  # unit gradient
    s1 = ur * tr + uz * tz
    h = 0.5 * kap * s
    cm, sm = math.cos(h), math.sin(h)
    mr, mz = tr * cm - tz * sm, tr * sm + tz * cm  # direction at mid-arc
    kap_a = -(tr * uz - tz * ur) / c1  # kappa / a
    n_a = (ur * -mz + uz * mr) * kap_a * s * _sinc(h)  # (s2 - s1) / a
    dc_a = ur * dxr + uz * dxz  # (c2 - c1) / a
    smid = ur * mr + uz * mz
    x1 = a * dc_a / c1
    if smid >= 0.0:
        y = a * n_a / (1.0 + s1)
        return dc_a / c1 * _log1p_ratio(x1) - n_a / (1.0 + s1) * _log1p_ratio(y)
    y = -a * n_a / (1.0 - s1)
    return -n_a / (1.0 - s1) * _log1p_ratio(y) - dc_a / c1 * _log1p_ratio(x1)


@_jit
def trace(rr, zz, cc, bb, floor, z0, theta0, R, maxb, bottom_par, want_path, path):
    """Trace one ray from (0, z0) at launch angle theta0 until it reaches r = R (rr[0] <= 0,
    rr[-1] >= R: both ends lie inside the section).

    Returns (status, z_end, time, theta_end, arc, n_surface, n_bottom, code, bottom_loss_db,
    n_turns, n_path, c_end, kink): ``kink`` the distance in range from the nearest bottom
    reflection point to a kink of the floor polyline (inf without a bottom bounce). ``code`` encodes the bounce sequence (base 3: 1 surface, 2 bottom, first
    bounce least significant); ``bottom_par`` = (cb, rho, delta) of the sediment; ``floor``:
    a sea floor reflects (False: the bottom of the grid absorbs). With ``want_path`` the
    vertices (r, z, t) of the walk go to ``path`` (n, 3)."""
    J = rr.size
    K = zz.size
    tr, tz = math.cos(theta0), math.sin(theta0)
    r, z = 0.0, z0
    # starting cell: nudge along the ray to pick the side of a node line the ray enters
    zn = z0 + 1e-9 * tz * max(1.0, abs(z0))
    rn = 1e-9 * tr * max(1.0, R)
    k = 0
    while k < K - 2 and zz[k + 1] <= zn:
        k += 1
    j = 0
    while j < J - 2 and rr[j + 1] <= rn:
        j += 1
    part = _part_at(rr, zz, cc, j, k, rn, zn)
    entry = E_NONE
    c_end = math.nan
    kink = math.inf
    t = 0.0
    arc = 0.0
    ns = 0
    nb = 0
    code = 0
    p3 = 1
    loss = 0.0
    nturn = 0
    npath = 0
    if want_path:
        path[0, 0], path[0, 1], path[0, 2] = r, z, t
        npath = 1
    for _ in range(MAX_STEPS):
        dr = rr[j + 1] - rr[j]
        dz = zz[k + 1] - zz[k]
        c0, gr, gz = _plane(rr, zz, cc, j, k, part)
        c1 = c0 + gr * (r - rr[j]) + gz * (z - zz[k])
        kap = -(tr * gz - tz * gr) / c1
        mr, mz = -tz, tr
        best = math.inf
        which = E_NONE
        # candidate lines: (code, normal, point)
        for ed in range(7):
            if ed == E_TARGET:
                if not (rr[j] < R <= rr[j + 1]):
                    continue
                nr, nz, pr, pz = 1.0, 0.0, R, zz[k]
            elif ed == E_TOP:
                if part in (P_LOWER, P_LR):
                    continue
                nr, nz, pr, pz = 0.0, -1.0, rr[j], zz[k]
            elif ed == E_RIGHT:
                if part in (P_LOWER, P_UL):
                    continue
                nr, nz, pr, pz = 1.0, 0.0, rr[j + 1], zz[k]
            elif ed == E_BOTTOM:
                if part in (P_UPPER, P_UL):
                    continue
                nr, nz, pr, pz = 0.0, 1.0, rr[j], zz[k + 1]
            elif ed == E_LEFT:
                if part in (P_UPPER, P_LR):
                    continue
                nr, nz, pr, pz = -1.0, 0.0, rr[j], zz[k]
            elif ed == E_DIAG:
                if part == P_WHOLE:
                    continue
                dn = math.hypot(dr, dz)
                if part in (P_UPPER, P_LOWER):
                    nr, nz = -dz / dn, dr / dn  # out of the upper triangle
                    if part == P_LOWER:
                        nr, nz = -nr, -nz
                    pr, pz = rr[j], zz[k]
                else:
                    nr, nz = dz / dn, dr / dn  # out of the upper-left triangle
                    if part == P_LR:
                        nr, nz = -nr, -nz
                    pr, pz = rr[j], zz[k + 1]
            else:
                db = bb[j + 1] - bb[j]
                dn = math.hypot(dr, db)
                nr, nz = -db / dn, dr / dn
                pr, pz = rr[j], bb[j]
            e = nr * (r - pr) + nz * (z - pz)
            A = nr * tr + nz * tz
            B = nr * mr + nz * mz
            s = _exit_s(e, A, B, kap, ed == entry)
            if s < best or (ed == E_TARGET and s == best):
                best = s
                which = ed
        if which == E_NONE or not math.isfinite(best):
            return S_LOST, z, t, math.atan2(tz, tr), arc, ns, nb, code, loss, nturn, npath, c_end, kink
        # advance along the arc
        s = best
        h = 0.5 * kap * s
        sc = s * _sinc(h)
        cm, sm = math.cos(h), math.sin(h)
        dxr = sc * (tr * cm - tz * sm)
        dxz = sc * (tr * sm + tz * cm)
        t += _arc_time(tr, tz, s, kap, gr, gz, c1, dxr, dxz)
        arc += s
        c2, s2 = math.cos(2.0 * h), math.sin(2.0 * h)
        tz_old = tz
        tr, tz = tr * c2 - tz * s2, tr * s2 + tz * c2
        r += dxr
        z += dxz
        if (tz_old > 0.0) != (tz > 0.0) and tz != 0.0 and tz_old != 0.0:
            nturn += 1
        if want_path and npath < path.shape[0]:
            path[npath, 0], path[npath, 1], path[npath, 2] = r, z, t
            npath += 1
        # cross or reflect
        if which == E_TARGET:
            c_end = c0 + gr * (R - rr[j]) + gz * (z - zz[k])
            return S_REACHED, z, t, math.atan2(tz, tr), arc, ns, nb, code, loss, nturn, npath, c_end, kink
        if which == E_FLOOR:
            if not floor:
                return S_LOST, z, t, math.atan2(tz, tr), arc, ns, nb, code, loss, nturn, npath, c_end, kink
            db = bb[j + 1] - bb[j]
            dn = math.hypot(dr, db)
            nr, nz = -db / dn, dr / dn
            a_n = tr * nr + tz * nz
            cw = c0 + gr * (r - rr[j]) + gz * (z - zz[k])
            rc = rayleigh(math.asin(min(abs(a_n), 1.0)), cw, bottom_par[0], bottom_par[1], bottom_par[2])
            for jv in (j, j + 1):
                if 0 < jv < J - 1:
                    sl = (bb[jv] - bb[jv - 1]) / (rr[jv] - rr[jv - 1])
                    sr = (bb[jv + 1] - bb[jv]) / (rr[jv + 1] - rr[jv])
                    if sl != sr:
                        kink = min(kink, abs(r - rr[jv]))
            loss += -20.0 * math.log10(max(abs(rc), 1e-300))
            tr, tz = tr - 2.0 * a_n * nr, tz - 2.0 * a_n * nz
            nb += 1
            code += 2 * p3
            p3 *= 3
            entry = E_FLOOR
        elif which == E_TOP:
            if k == 0:
                z = 0.0
                tz = -tz
                ns += 1
                code += p3
                p3 *= 3
                entry = E_TOP
            else:
                z = zz[k]
                k -= 1
                part = _part_entering(cc, j, k, E_BOTTOM)
                entry = E_BOTTOM
        elif which == E_BOTTOM:
            z = zz[k + 1]
            if k + 1 >= K - 1:
                return S_LOST, z, t, math.atan2(tz, tr), arc, ns, nb, code, loss, nturn, npath, c_end, kink
            k += 1
            part = _part_entering(cc, j, k, E_TOP)
            entry = E_TOP
        elif which == E_RIGHT:
            r = rr[j + 1]
            if j + 1 >= J - 1:
                return S_LOST, z, t, math.atan2(tz, tr), arc, ns, nb, code, loss, nturn, npath, c_end, kink
            j += 1
            part = _part_entering(cc, j, k, E_LEFT)
            entry = E_LEFT
        elif which == E_LEFT:
            r = rr[j]
            if j == 0:
                return S_LOST, z, t, math.atan2(tz, tr), arc, ns, nb, code, loss, nturn, npath, c_end, kink
            j -= 1
            part = _part_entering(cc, j, k, E_RIGHT)
            entry = E_RIGHT
        else:  # diagonal
            if part in (P_UPPER, P_LOWER):
                part = P_LOWER if part == P_UPPER else P_UPPER
            else:
                part = P_LR if part == P_UL else P_UL
            entry = E_DIAG
        if ns + nb > maxb:
            return S_LOST, z, t, math.atan2(tz, tr), arc, ns, nb, code, loss, nturn, npath, c_end, kink
    return S_LOST, z, t, math.atan2(tz, tr), arc, ns, nb, code, loss, nturn, npath, c_end, kink


# --------------------------------------------------------------------------- eigenray search

NF = 14  # fields of one arrival row, see search()
F_TIME, F_THETA0, F_THETAR, F_NS, F_NB, F_CODE, F_ARC, F_LOSS, F_DZDTH, F_NTURN, F_ZMISS, F_CS, F_CR, F_KINK = range(NF)
_BISECT_LEVELS = 8  # towards a family's edge
_NONLIN_LEVELS = 6  # inside a family, where the miss is far from linear
_EDGE_LEVELS = 40  # towards an edge where the miss heads for zero


@_jit
def _heading(f_end, f_prev, code):
    """The miss of family ``code`` heads for zero at the edge: it shrank from f_prev to f_end
    (same sign) and a few more such steps would reach zero."""
    if code < 0 or not math.isfinite(f_prev) or not math.isfinite(f_end):
        return False
    if (f_end > 0.0) != (f_prev > 0.0):
        return False
    return abs(f_end) < abs(f_prev) and abs(f_end) < 8.0 * (abs(f_prev) - abs(f_end))


_STACK = 96
_MAXIT = 100
_ACCEPT_M = 1e-6  # a converged bracket is an eigenray only if it hits the receiver this closely


@_jit
def _speed_src(rr, zz, cc, zs, R):
    """c at the source (0, zs) on the cell that holds it."""
    J, K = rr.size, zz.size
    k = 0
    while k < K - 2 and zz[k + 1] <= zs:
        k += 1
    j = 0
    while j < J - 2 and rr[j + 1] <= 0.0:
        j += 1
    part = _part_at(rr, zz, cc, j, k, 0.0, zs)
    c0, gr, gz = _plane(rr, zz, cc, j, k, part)
    return c0 + gr * (0.0 - rr[j]) + gz * (zs - zz[k])


@_jit
def _miss(rr, zz, cc, bb, floor, zs, zr, R, th, maxb, bpar, dummy):
    st, ze, _t, _a, _l, _n1, _n2, code, _lo, _nt, _np, _c, _k = trace(
        rr, zz, cc, bb, floor, zs, th, R, maxb, bpar, False, dummy
    )
    if st != S_REACHED:
        return math.nan, -1
    return ze - zr, code


@_jit
def _refine(rr, zz, cc, bb, floor, zs, zr, R, maxb, bpar, a, fa, b, fb, code, ztol, out, row, dummy):
    """Illinois regula falsi on the depth miss at r = R inside one bounce family [a, b]; the
    converged ray's fields go to out[row]. Returns False if the family is not contiguous."""
    m = a
    fm = fa
    if fa == 0.0:
        m, fm = a, fa
    elif fb == 0.0:
        m, fm = b, fb
    else:
        for _ in range(_MAXIT):
            m = b - fb * (b - a) / (fb - fa)
            if not (min(a, b) < m < max(a, b)):
                m = 0.5 * (a + b)
            fm, cm = _miss(rr, zz, cc, bb, floor, zs, zr, R, m, maxb, bpar, dummy)
            if cm != code:
                m = 0.5 * (a + b)
                fm, cm = _miss(rr, zz, cc, bb, floor, zs, zr, R, m, maxb, bpar, dummy)
                if cm != code:
                    return False
            if abs(fm) <= ztol or abs(b - a) <= 4e-16 * (1.0 + abs(m)):
                break
            if (fm > 0.0) != (fb > 0.0):
                a, fa = b, fb
            else:
                fa *= 0.5
            b, fb = m, fm
    st, ze, t, thr, arc, ns, nb, cd, loss, nturn, _np, cR, kink = trace(
        rr, zz, cc, bb, floor, zs, m, R, maxb, bpar, False, dummy
    )
    if st != S_REACHED or cd != code or not abs(ze - zr) <= _ACCEPT_M:
        # a jump of the miss inside a family (a ray hitting a vertex of the floor polyline
        # reflects off one slope or the other), not a root
        return False
    # the receiver's depth miss, to first order: dt/dz_R = sin(theta_R) / c_R (Fermat)
    out[row, F_TIME] = t + (zr - ze) * math.sin(thr) / cR
    out[row, F_THETA0] = m
    out[row, F_THETAR] = thr
    out[row, F_NS] = ns
    out[row, F_NB] = nb
    out[row, F_CODE] = cd
    out[row, F_ARC] = arc
    out[row, F_LOSS] = loss
    out[row, F_NTURN] = nturn
    out[row, F_ZMISS] = ze - zr
    out[row, F_CR] = cR
    out[row, F_KINK] = kink
    out[row, F_CS] = _speed_src(rr, zz, cc, zs, R)
    # ray-tube width: d z_end / d theta0 by a small central difference inside the family
    h = 1e-7 * max(1.0, abs(m)) if abs(b - a) > 1e-6 else 0.25 * abs(b - a)
    fp, cp = _miss(rr, zz, cc, bb, floor, zs, zr, R, m + h, maxb, bpar, dummy)
    fq, cq = _miss(rr, zz, cc, bb, floor, zs, zr, R, m - h, maxb, bpar, dummy)
    if cp == code and cq == code:
        out[row, F_DZDTH] = (fp - fq) / (2.0 * h)
    elif cp == code:
        out[row, F_DZDTH] = (fp - fm) / h
    elif cq == code:
        out[row, F_DZDTH] = (fm - fq) / h
    else:
        out[row, F_DZDTH] = math.nan
    return True


@_jit
def search(rr, zz, cc, bb, floor, zs, zr, R, maxb, bpar, wmax, nfan, H, ztol, out):
    """Every eigenray from (0, zs) to (R, zr) with at most ``maxb`` boundary bounces. A fan of
    ``nfan`` launch angles uniform in w = tan(theta) R / H over [-wmax, wmax] (the families of
    a waveguide of depth H lie about 2 apart in w), then adaptive bisection of each fan
    interval: where its ends took different bounce sequences (to put samples next to each
    family's edge), and where the depth miss at the receiver's range is not nearly linear
    between them (a fold of the family may hide two roots); regula falsi inside each family
    where the miss changes sign. Returns the number of arrival rows written to ``out``."""
    dummy = np.empty((1, 3))
    th = np.empty(nfan)
    f = np.empty(nfan)
    cd = np.empty(nfan, np.int64)
    for i in range(nfan):
        w = -wmax + 2.0 * wmax * (i + 0.5) / nfan
        th[i] = math.atan(w * H / R)
        f[i], cd[i] = _miss(rr, zz, cc, bb, floor, zs, zr, R, th[i], maxb, bpar, dummy)
    n = 0
    cap = out.shape[0]
    nbmax = 8 * nfan + 256
    br = np.empty((nbmax, 4))  # brackets (a, fa, b, fb) and their family
    bc = np.empty(nbmax, np.int64)
    nbr = 0
    # interval stack: a, f(a), code(a), b, f(b), code(b), and the previous miss of a's family
    # beyond a and of b's family beyond b (NaN if unknown): is the miss heading for zero at an edge?
    stack = np.empty((_STACK, 8))
    lev = np.zeros(_STACK, np.int64)
    for i in range(nfan - 1):
        stack[0, 0], stack[0, 1], stack[0, 2] = th[i], f[i], cd[i]
        stack[0, 3], stack[0, 4], stack[0, 5] = th[i + 1], f[i + 1], cd[i + 1]
        stack[0, 6] = f[i - 1] if i > 0 and cd[i - 1] == cd[i] else math.nan
        stack[0, 7] = f[i + 2] if i + 2 < nfan and cd[i + 2] == cd[i + 1] else math.nan
        lev[0] = 0
        top = 1
        while top > 0:
            top -= 1
            a, fa, b, fb = stack[top, 0], stack[top, 1], stack[top, 3], stack[top, 4]
            ca, cb = int(stack[top, 2]), int(stack[top, 5])
            pa, pb = stack[top, 6], stack[top, 7]
            lv = lev[top]
            if ca == cb and ca < 0:
                continue  # both rays lost
            same = ca == cb
            stop = lv >= (_NONLIN_LEVELS if same else _BISECT_LEVELS) or top + 2 > _STACK
            if stop and not same and top + 2 <= _STACK and lv < _EDGE_LEVELS and abs(b - a) > 1e-13:
                # near a family's edge the miss may race to zero (a ray grazing a boundary):
                # keep bisecting while it heads there
                stop = not (_heading(fa, pa, ca) or _heading(fb, pb, cb))
            if stop:
                if same and ((fa > 0.0) != (fb > 0.0) or fa == 0.0) and nbr < nbmax:
                    br[nbr, 0], br[nbr, 1], br[nbr, 2], br[nbr, 3] = a, fa, b, fb
                    bc[nbr] = ca
                    nbr += 1
                continue
            m = 0.5 * (a + b)
            fm, cm = _miss(rr, zz, cc, bb, floor, zs, zr, R, m, maxb, bpar, dummy)
            split = True
            if same and cm == ca:
                # a fold may hide two roots where the miss bends by more than a quarter of its
                # distance from zero (ends of one sign); with ends of both signs a root is seen
                dev = abs(fm - 0.5 * (fa + fb))
                split = (fa > 0.0) == (fb > 0.0) and min(abs(fa), abs(fb), abs(fm)) < 4.0 * dev
            if split:
                stack[top, 0], stack[top, 1], stack[top, 2] = a, fa, ca
                stack[top, 3], stack[top, 4], stack[top, 5] = m, fm, cm
                stack[top, 6], stack[top, 7] = pa, (fb if cm == cb else math.nan)
                lev[top] = lv + 1
                stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2] = m, fm, cm
                stack[top + 1, 3], stack[top + 1, 4], stack[top + 1, 5] = b, fb, cb
                stack[top + 1, 6], stack[top + 1, 7] = (fa if cm == ca else math.nan), pb
                lev[top + 1] = lv + 1
                top += 2
                continue
            for x0, f0, x1, f1 in ((a, fa, m, fm), (m, fm, b, fb)):
                if ((f0 > 0.0) != (f1 > 0.0) or f0 == 0.0) and nbr < nbmax:
                    br[nbr, 0], br[nbr, 1], br[nbr, 2], br[nbr, 3] = x0, f0, x1, f1
                    bc[nbr] = ca
                    nbr += 1
    for q in range(nbr):
        if n >= cap:
            break
        if _refine(
            rr,
            zz,
            cc,
            bb,
            floor,
            zs,
            zr,
            R,
            maxb,
            bpar,
            br[q, 0],
            br[q, 1],
            br[q, 2],
            br[q, 3],
            bc[q],
            ztol,
            out,
            n,
            dummy,
        ):
            # the same eigenray from two brackets sharing a sample
            dup = False
            for p in range(n):
                if out[p, F_CODE] == out[n, F_CODE] and abs(out[p, F_THETA0] - out[n, F_THETA0]) <= 1e-12:
                    dup = True
                    break
            if not dup:
                n += 1
    return n


@_jit
def search_links(starts, ends, rr_all, zz, cc_all, bb_all, floor, zs, zr, R, maxb, bpar, wmax, nfan, H, ztol, cap):
    """:func:`search` for every link l: its section rows starts[l]:ends[l] of rr_all (J,),
    cc_all (J, K), bb_all (J,) (fewer than 2 rows: skipped). Returns (rows (L, cap, NF),
    counts (L,))."""
    L = zs.size
    out = np.full((L, cap, NF), np.nan)
    cnt = np.zeros(L, np.int64)
    for l in range(L):
        o0, o1 = starts[l], ends[l]
        if o1 - o0 < 2:
            continue
        cnt[l] = search(
            rr_all[o0:o1],
            zz,
            cc_all[o0:o1],
            bb_all[o0:o1],
            floor,
            zs[l],
            zr[l],
            R[l],
            maxb,
            bpar,
            wmax[l],
            nfan[l],
            H[l],
            ztol,
            out[l],
        )
    return out, cnt


@_jit
def trace_links(offs, rr_all, zz, cc_all, bb_all, floor, zs, R, theta0, maxb, bpar, npts):
    """The walk of one ray per link (launch angle theta0[l]): vertices (L, npts, 3) of (r, z, t)
    and their counts, for plots and for the reference checks."""
    L = zs.size
    paths = np.full((L, npts, 3), np.nan)
    cnt = np.zeros(L, np.int64)
    for l in range(L):
        o0, o1 = offs[l], offs[l + 1]
        res = trace(
            rr_all[o0:o1], zz, cc_all[o0:o1], bb_all[o0:o1], floor, zs[l], theta0[l], R[l], maxb, bpar, True, paths[l]
        )
        cnt[l] = res[10]
    return paths, cnt


@_jit
def track_links(starts, ends, rr_all, zz, cc_all, bb_all, floor, zs, zr, R, maxb, bpar, theta0, slope, code, ztol):
    """Follow known eigenrays to slightly moved end points: for each link l and each of its
    arrivals q (launch angle theta0[l, q], bounce sequence code[l, q] >= 0, depth-miss slope
    d z_R / d theta0 slope[l, q]), secant iterations from the old launch angle in the new
    section, keeping the bounce sequence. Returns the corrected delays (L, Q), NaN where the
    arrival could not be followed (its sequence changed, or no convergence in 12 steps)."""
    L, Q = theta0.shape
    out = np.full((L, Q), np.nan)
    dummy = np.empty((1, 3))
    for l in range(L):
        o0, o1 = starts[l], ends[l]
        if o1 - o0 < 2:
            continue
        rr, cc, bb = rr_all[o0:o1], cc_all[o0:o1], bb_all[o0:o1]
        for q in range(Q):
            cd = code[l, q]
            if cd < 0 or not math.isfinite(theta0[l, q]):
                continue
            a = theta0[l, q]
            fa, ca = _miss(rr, zz, cc, bb, floor, zs[l], zr[l], R[l], a, maxb, bpar, dummy)
            if ca != cd:
                continue
            s = slope[l, q]
            if not (math.isfinite(s) and s != 0.0):
                continue
            ok = abs(fa) <= ztol
            for _ in range(12):
                if ok:
                    break
                b = a - fa / s
                fb, cb = _miss(rr, zz, cc, bb, floor, zs[l], zr[l], R[l], b, maxb, bpar, dummy)
                if cb != cd:
                    break
                if fb != fa and b != a:
                    s = (fb - fa) / (b - a)
                a, fa = b, fb
                ok = abs(fa) <= ztol
            if not ok:
                continue
            st, ze, t, thr, _arc, _ns, _nb, c2, _lo, _nt, _np, cR, _k = trace(
                rr, zz, cc, bb, floor, zs[l], a, R[l], maxb, bpar, False, dummy
            )
            if st == S_REACHED and c2 == cd:
                out[l, q] = t + (zr[l] - ze) * math.sin(thr) / cR
    return out
