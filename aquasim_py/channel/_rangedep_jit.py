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
