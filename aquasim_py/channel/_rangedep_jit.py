"""Compiled kernels of the range-dependent ray tracer (numba): the exact cell-by-cell ray walk
through a (range, depth) section and the per-link eigenray search. See :mod:`.rangedep` for
the model and the public API; this module is imported lazily on the first range-dependent solve.

The section of one link: column ranges ``rr`` (J,) from 0 (the source) to R (the receiver),
depth nodes ``zz`` (K,) from 0, speeds ``cc`` (J, K), sea-floor depths ``bb`` (J,) at the
columns and the floor's shape ``ff`` (J, 7) between them (:attr:`.rangedep.Sections.floor_shape`:
a straight segment, or two circular arcs). Each grid rectangle is one cell where its four speeds lie on
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

# edge codes of a cell (E_FLOOR2: the second arc of a curved floor's interval)
E_TOP, E_RIGHT, E_BOTTOM, E_LEFT, E_DIAG, E_FLOOR, E_TARGET, E_FLOOR2, E_NONE = 0, 1, 2, 3, 4, 5, 6, 7, -1
# columns of a floor shape row (rangedep.Sections.floor_shape): tangent angles at the column from
# the left and to the right; the biarc's junction (range, depth, tangent angle); its two arcs'
# curvatures; the unit normals (into the floor) where each arc starts; the interval's shallowest
# floor depth
FS_LEFT, FS_RIGHT, FS_JR, FS_JZ, FS_JA, FS_K1, FS_K2, FS_N1R, FS_N1Z, FS_N2R, FS_N2Z, FS_ZMIN = range(12)
NFS = 12
# cell parts: the whole (planar) rectangle; the two triangles of the diagonal (r_j, z_k) -
# (r_j+1, z_k+1) above / below it; the two of the other diagonal above-left / below-right
P_WHOLE, P_UPPER, P_LOWER, P_UL, P_LR = 0, 1, 2, 3, 4
# ray status
S_REACHED, S_LOST, S_OVER = 1, 0, 2
# with event predictions, a ray goes on for this many bounces past the limit (S_OVER at R)
OVER_BOUNCES = 2
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
def _cosc(x: float) -> float:
    """(cos x - sin(x) / x) / x, -x / 3 at 0 (the arc's end point's rate with its curvature)."""
    if abs(x) < 1e-2:
        x2 = x * x
        return x * (-1.0 / 3.0 + x2 * (1.0 / 30.0 - x2 / 840.0))
    return (math.cos(x) - math.sin(x) / x) / x


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
def _sigma_to_s(sg, kap, best):
    """The arc length s = 2 sigma atanc(kappa sigma) of a root sigma > 0 (inf otherwise, or where
    s >= ``best`` for sure: atanc(x) >= 1 - x^2 / 3, which spares the arctangent)."""
    if not sg > 0.0:
        return math.inf
    x = kap * sg
    if 2.0 * sg * (1.0 - x * x / 3.0) >= best:
        return math.inf
    return 2.0 * sg * _atanc(x)


@_jit
def _exit_circle(e, A, B, kap, kf, entry, best):
    """The two arc lengths (s1 <= s2; inf where none is positive, or none shorter than
    ``best``) at which the ray arc X(s) = X + (t sin u + m (1 - cos u)) / kappa, u = kappa s,
    meets the curve G = 0, G(Y) = n.(Y - P) + kf / 2 |Y - P|^2 (a circle of curvature kf through
    P with normal n there; kf = 0 the line), with e = G(X), A = grad G(X).t, B = grad G(X).m. In
    sigma = tan(u / 2) / kappa the meeting is a2 sigma^2 + 2 A sigma + e = 0, a2 = e kappa^2 + 2 B
    kappa + 2 kf (as :func:`_exit_s`, which is the line's case); s = 2 sigma atanc(kappa sigma).
    ``entry``: the ray sits on the curve (the root at 0 is not counted)."""
    a2 = e * kap * kap + 2.0 * B * kap + 2.0 * kf
    s1 = math.inf
    s2 = math.inf
    if entry:
        if a2 != 0.0:
            s1 = _sigma_to_s(-2.0 * A / a2, kap, best)
        return s1, s2
    disc = A * A - e * a2
    if disc < 0.0:
        return s1, s2
    sq = math.sqrt(disc)
    q = -(A + sq) if A >= 0.0 else -(A - sq)
    if q != 0.0:
        s1 = _sigma_to_s(e / q, kap, best)
    if a2 != 0.0:
        s = _sigma_to_s(q / a2, kap, best)
    elif kap != 0.0:
        s = math.pi / abs(kap)
    else:
        s = math.inf
    if s < s1:
        s1, s2 = s, s1
    else:
        s2 = s
    return s1, s2


@_jit
def _piece(rr, bb, ff, j, second):
    """A piece of the floor of column interval j: (pr, pz, nr, nz, kf, lo, hi), a point on it,
    the unit normal into the floor there, its curvature (0: straight), its ranges. A straight
    interval is one piece (``second`` False), a curved one two arcs."""
    k1, k2 = ff[j, FS_K1], ff[j, FS_K2]
    if k1 == 0.0 and k2 == 0.0:
        dr = rr[j + 1] - rr[j]
        db = bb[j + 1] - bb[j]
        dn = math.hypot(dr, db)
        return rr[j], bb[j], -db / dn, dr / dn, 0.0, rr[j], rr[j + 1]
    if second:
        return ff[j, FS_JR], ff[j, FS_JZ], ff[j, FS_N2R], ff[j, FS_N2Z], k2, ff[j, FS_JR], rr[j + 1]
    return rr[j], bb[j], ff[j, FS_N1R], ff[j, FS_N1Z], k1, rr[j], ff[j, FS_JR]


@_jit
def _floor_hit(r, z, tr, tz, kap, pr, pz, nr, nz, kf, lo, hi, entry, best, want_near, reach):
    """(arc length at which the ray at (r, z), direction (tr, tz), curvature kap, meets the
    floor arc through (pr, pz) with unit normal (nr, nz) there and curvature kf on its ranges
    [lo, hi] (the branch whose normal points down), inf: none shorter than ``best``; arc length
    to the ray's closest approach of the arc's circle where it turns away without meeting it,
    -1: none)."""
    dr, dz = r - pr, z - pz
    e = nr * dr + nz * dz + 0.5 * kf * (dr * dr + dz * dz)
    gr, gz = nr + kf * dr, nz + kf * dz
    A = gr * tr + gz * tz
    B = gr * -tz + gz * tr
    slack = 1e-9 * max(1.0, abs(hi))
    if not entry and e >= 0.0 and A > 0.0 and lo - slack <= r <= hi + slack:
        return 0.0, -1.0  # on the floor (rounding) and heading into it
    s_near = -1.0
    if want_near and not entry and A > 0.0:
        s_near = _near_miss(e, A, B, kap, kf)
    if not reach:
        return math.inf, s_near
    s1, s2 = _exit_circle(e, A, B, kap, kf, entry, best)
    for s in (s1, s2):
        if not s < best:
            break
        # the hit's range to first order in the turn (error <= s h^2): a cheap reject
        h = 0.5 * kap * s
        rl = r + s * (tr - tz * h)
        m = s * h * h + slack
        if rl < lo - m or rl > hi + m:
            continue
        sc = s * _sinc(h)
        cm, sm = math.cos(h), math.sin(h)
        rh = r + sc * (tr * cm - tz * sm)
        zh = z + sc * (tr * sm + tz * cm)
        if lo - slack <= rh <= hi + slack and nz + kf * (zh - pz) > 0.0:
            return s, s_near
    return math.inf, s_near


@_jit
def _near_miss(e, A, B, kap, kf):
    """The arc length to where the ray arc turns away from the curve G = 0 (see
    :func:`_exit_circle`) without meeting it; -1 where it does not (heading away, meeting it, or
    G without an interior maximum along the arc). To first order in kappa sigma (the rays' arcs
    are km wide): G ~ a2 sigma^2 + 2 A sigma + e, its maximum e - A^2 / a2 < 0 (the clearance's
    negative) at sigma = -A / a2."""
    a2 = e * kap * kap + 2.0 * B * kap + 2.0 * kf
    if not (a2 < 0.0 and A > 0.0) or e - A * A / a2 >= 0.0:
        return -1.0
    sg = -A / a2
    return 2.0 * sg * _atanc(kap * sg)


@_jit
def _predict_touch(ev, r, z, tr, tz, kap, qr, qz, qp, dkap, s, pr, pz, nr, nz, kf, lo, hi):
    """Where the ray's closest approach (arc length s) of the curve through (pr, pz) with normal
    (nr, nz) and curvature kf lies on its ranges [lo, hi]: note the launch-angle offset at which
    it would touch, -clearance / (d clearance / d theta0), the clearance's rate the normal
    component of the walk's tangent-linear displacement there."""
    h = 0.5 * kap * s
    sc = s * _sinc(h)
    cm, sm = math.cos(h), math.sin(h)
    hr, hz = tr * cm - tz * sm, tr * sm + tz * cm
    xr, xz = r + sc * hr, z + sc * hz
    if not (lo <= xr <= hi):
        return
    er, ez = xr - pr, xz - pz
    clear = -(nr * er + nz * ez + 0.5 * kf * (er * er + ez * ez))
    g1, g2 = _cosc(h), _sinc(h)
    dxr = qr - sc * hz * qp + 0.5 * s * s * (hr * g1 - hz * g2) * dkap
    dxz = qz + sc * hr * qp + 0.5 * s * s * (hz * g1 + hr * g2) * dkap
    rate = -((nr + kf * er) * dxr + (nz + kf * ez) * dxz)
    if rate != 0.0 and clear > 0.0:
        _note_event(ev, -clear / rate)


@_jit
def _note_event(ev, dtheta):
    """Keep the nearest predicted launch-angle offset of a bounce appearing or vanishing, by
    direction: ev[0] the nearest above theta0 (> 0), ev[1] below (< 0, as a distance)."""
    if dtheta > 0.0:
        ev[0] = min(ev[0], dtheta)
    elif dtheta < 0.0:
        ev[1] = min(ev[1], -dtheta)


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
def trace(rr, zz, cc, bb, ff, floor, z0, theta0, R, maxb, bottom_par, want_path, path, ev):
    """Trace one ray from (0, z0) at launch angle theta0 until it reaches r = R (rr[0] <= 0,
    rr[-1] >= R: both ends lie inside the section).

    Returns (status, z_end, time, theta_end, arc, n_surface, n_bottom, code, bottom_loss_db,
    n_turns, n_path, c_end, kink, dz_dtheta, dthr_dtheta): ``kink`` the distance in range from
    the nearest bottom reflection point to a point where the floor's slope or curvature jumps
    (inf without a bottom bounce or such a point; a delay's first or second derivative jumps
    where a reflection point crosses one); ``dz_dtheta`` d z_end / d theta0 (m/rad, the ray-tube width) and ``dthr_dtheta`` d
    theta_end / d theta0 at r = R, exact: the walk's
    tangent-linear map (each arc's end point and direction differentiated with respect to its
    start point, start direction and curvature, the exit arc length from the exit line, the
    reflection off a curved floor turning its normal with the reflection point). ``code`` encodes the bounce sequence (base 3: 1 surface, 2 bottom, first
    bounce least significant); ``bottom_par`` = (cb, rho, delta) of the sediment; ``floor``:
    a sea floor reflects (False: the bottom of the grid absorbs). With ``want_path`` the
    vertices (r, z, t) of the walk go to ``path`` (n, 3).

    Status S_REACHED: at r = R within ``maxb`` bounces; S_LOST: not; S_OVER (only with ``ev``
    wanted): at R with up to OVER_BOUNCES more (the search tells these families apart, so that
    one within ``maxb`` between two of them is not hidden in a run of lost rays).

    ``ev`` (2,) (size 0: not wanted, a cheaper walk), set to (inf, inf) first: the nearest launch-angle offsets (rad; above, below
    theta0) at which the ray's bounce sequence is predicted to change, to first order: where a
    bounce's grazing angle (sin theta_g = the direction's component along the boundary's normal)
    would vanish; where a closest approach of the surface or the floor that it turns away
    from (a clearance d) would touch (d / |d d / d theta0|, the clearance's rate the normal
    component of the walk's tangent-linear displacement there); where its depth at R would
    reach the floor's or the surface (a bounce crossing the receiver's range). The search refines its fan
    wherever one falls between two samples: a family too narrow for the fan lies there."""
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
    # a source a rounding error across a node line from the cell the ray enters starts on that
    # line (outside its cell, the first step would leave through the line at once, the wrong way)
    z = min(max(z0, zz[k]), zz[k + 1])
    part = _part_at(rr, zz, cc, j, k, rn, zn)
    entry = E_NONE
    c_end = math.nan
    kink = math.inf
    t = 0.0
    arc = 0.0
    # derivatives of (r, z, direction angle) by theta0
    qr, qz, qp = 0.0, 0.0, 1.0
    events = ev.size >= 2
    if events:
        ev[0] = math.inf
        ev[1] = math.inf
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
        # d kappa / d theta0 (kappa = -(t x grad c) / c at the start point and direction)
        dkap = (-kap * (gr * qr + gz * qz) + (tr * gr + tz * gz) * qp) / c1
        best = math.inf
        which = E_NONE
        wnr, wnz = 0.0, 0.0
        # candidate lines: (code, normal, point)
        for ed in range(6):
            if ed == E_FLOOR:
                continue  # below
            if ed == E_TOP:
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
            else:  # E_DIAG
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
            e = nr * (r - pr) + nz * (z - pz)
            A = nr * tr + nz * tz
            B = nr * mr + nz * mz
            s = _exit_s(e, A, B, kap, ed == entry)
            if s < best:
                best = s
                which = ed
                wnr, wnz = nr, nz
        # the receiver's range (reaching it wins a tie)
        if rr[j] < R <= rr[j + 1]:
            e = r - R
            s = _exit_s(e, tr, mr, kap, entry == E_TARGET)
            if s <= best:  # evaluated before the floor: the floor must beat it strictly
                best = s
                which = E_TARGET
                wnr, wnz = 1.0, 0.0
        # the floor: the straight segment of the interval, or its two arcs (and where the ray
        # turns away from it, or from the surface, inside this step without touching: closest
        # approaches, whose touch the search is told about)
        curved = not (ff[j, FS_K1] == 0.0 and ff[j, FS_K2] == 0.0)
        near0, near1, near2 = -1.0, -1.0, -1.0
        reach = z + best >= ff[j, FS_ZMIN]  # else out of reach in this step (|dz / ds| <= 1)
        if not (events or reach):
            pass
        elif not curved:
            pr, pz, nr, nz, kf, lo, hi = _piece(rr, bb, ff, j, False)
            e = nr * (r - pr) + nz * (z - pz)
            A = nr * tr + nz * tz
            B = nr * mr + nz * mz
            s = _exit_s(e, A, B, kap, entry == E_FLOOR)
            if s < best:
                best = s
                which = E_FLOOR
                wnr, wnz = nr, nz
            if events and A > 0.0 and entry != E_FLOOR:
                near1 = _near_miss(e, A, B, kap, 0.0)
        else:
            pr, pz, nr, nz, kf, lo, hi = _piece(rr, bb, ff, j, False)
            s, near1 = _floor_hit(r, z, tr, tz, kap, pr, pz, nr, nz, kf, lo, hi, entry == E_FLOOR, best, events, reach)
            if s < best:
                best = s
                which = E_FLOOR
            pr, pz, nr, nz, kf, lo, hi = _piece(rr, bb, ff, j, True)
            s, near2 = _floor_hit(r, z, tr, tz, kap, pr, pz, nr, nz, kf, lo, hi, entry == E_FLOOR2, best, events, reach)
            if s < best:
                best = s
                which = E_FLOOR2
        if which == E_NONE or not math.isfinite(best):
            break  # lost
        if events and k == 0 and tz < 0.0 and part != P_LOWER and part != P_LR and entry != E_TOP:
            near0 = _near_miss(-z, -tz, -tr, kap, 0.0)  # the surface: G = -z
        if 0.0 < near0 < best:
            _predict_touch(ev, r, z, tr, tz, kap, qr, qz, qp, dkap, near0, r, 0.0, 0.0, -1.0, 0.0, -math.inf, math.inf)
        if 0.0 < near1 < best:
            pr, pz, nr, nz, kf, lo, hi = _piece(rr, bb, ff, j, False)
            _predict_touch(ev, r, z, tr, tz, kap, qr, qz, qp, dkap, near1, pr, pz, nr, nz, kf, lo, hi)
        if 0.0 < near2 < best:
            pr, pz, nr, nz, kf, lo, hi = _piece(rr, bb, ff, j, True)
            _predict_touch(ev, r, z, tr, tz, kap, qr, qz, qp, dkap, near2, pr, pz, nr, nz, kf, lo, hi)
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
        tr0 = tr
        tr, tz = tr * c2 - tz * s2, tr * s2 + tz * c2
        r += dxr
        z += dxz
        # tangent-linear step: the end point at fixed s moves with the start point, the start
        # direction (the chord turned by 90 deg) and the curvature ((s^2 / 2) (T_h cosc(h) + M_h
        # sinc(h)), T_h the chord's direction); the exit arc length moves the end along the ray
        # until it is back on the exit line (normal w)
        hr, hz = dxr / sc if sc != 0.0 else tr0, dxz / sc if sc != 0.0 else tz_old
        f1, f2 = _cosc(h), _sinc(h)
        sxr = qr - dxz * qp + 0.5 * s * s * (hr * f1 - hz * f2) * dkap
        sxz = qz + dxr * qp + 0.5 * s * s * (hz * f1 + hr * f2) * dkap
        if curved and which in (E_FLOOR, E_FLOOR2):
            pr, pz, nr, nz, kf, lo, hi = _piece(rr, bb, ff, j, which == E_FLOOR2)
            wnr = nr + kf * (r - pr)
            wnz = nz + kf * (z - pz)
        dsq = -(wnr * sxr + wnz * sxz) / (wnr * tr + wnz * tz)
        qr, qz = sxr + tr * dsq, sxz + tz * dsq
        qp = qp + s * dkap + kap * dsq
        if (tz_old > 0.0) != (tz > 0.0) and tz != 0.0 and tz_old != 0.0:
            nturn += 1
        if want_path and npath < path.shape[0]:
            path[npath, 0], path[npath, 1], path[npath, 2] = r, z, t
            npath += 1
        # cross or reflect
        if which == E_TARGET:
            c_end = c0 + gr * (R - rr[j]) + gz * (z - zz[k])
            # a neighbour meeting the floor or the surface just before R: where z at R would
            # reach either, a bounce enters (or the last one leaves) the sequence
            if events and qz != 0.0:
                pr, pz, nr, nz, kf, lo, hi = _piece(rr, bb, ff, j, ff[j, FS_K1] != 0.0 and ff[j, FS_JR] < R)
                er = R - pr
                c0f = nr * er + 0.5 * kf * er * er
                zf = pz - 2.0 * c0f / (nz + math.sqrt(max(nz * nz - 2.0 * kf * c0f, 0.0)))
                _note_event(ev, (zf - z) / qz)
                _note_event(ev, -z / qz)
            st = S_REACHED if ns + nb <= maxb else S_OVER
            return st, z, t, math.atan2(tz, tr), arc, ns, nb, code, loss, nturn, npath, c_end, kink, qz, qp
        if which in (E_FLOOR, E_FLOOR2):
            if not floor:
                break  # lost
            # the floor's normal (into it) at the reflection point
            pr, pz, nr, nz, kf, lo, hi = _piece(rr, bb, ff, j, which == E_FLOOR2)
            if kf != 0.0:
                nr = nr + kf * (r - pr)
                nz = nz + kf * (z - pz)
                dn = math.hypot(nr, nz)
                nr, nz = nr / dn, nz / dn
            a_n = tr * nr + tz * nz
            # this bounce vanishes where its grazing component a_n would reach 0
            da_n = qp * (-tz * nr + tr * nz) + kf * (tr * qr + tz * qz)
            if events and da_n != 0.0:
                _note_event(ev, -a_n / da_n)
            # the normal turns with the reflection point: d alpha = -kf (tangent . dX)
            qp += 2.0 * kf * (nz * qr - nr * qz)
            cw = c0 + gr * (r - rr[j]) + gz * (z - zz[k])
            rc = rayleigh(math.asin(min(abs(a_n), 1.0)), cw, bottom_par[0], bottom_par[1], bottom_par[2])
            # the nearest point where the floor's slope or curvature jumps: a column with
            # different slopes either side (a polyline's vertex) or curvatures (arcs meeting),
            # the junction of the interval's two arcs
            for jv in (j, j + 1):
                if 0 < jv < J - 1 and (ff[jv, FS_LEFT] != ff[jv, FS_RIGHT] or ff[jv - 1, FS_K2] != ff[jv, FS_K1]):
                    kink = min(kink, abs(r - rr[jv]))
            if ff[j, FS_K1] != ff[j, FS_K2]:
                kink = min(kink, abs(r - ff[j, FS_JR]))
            loss += -20.0 * math.log10(max(abs(rc), 1e-300))
            tr, tz = tr - 2.0 * a_n * nr, tz - 2.0 * a_n * nz
            qp = -qp
            nb += 1
            code += 2 * p3
            p3 *= 3
            entry = which
        elif which == E_TOP:
            if k == 0:
                z = 0.0
                if events and tr != 0.0 and qp != 0.0:
                    _note_event(ev, -tz / (tr * qp))  # a_n = -tz, d a_n = -tr qp
                tz = -tz
                qp = -qp
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
                break  # lost
            k += 1
            part = _part_entering(cc, j, k, E_TOP)
            entry = E_TOP
        elif which == E_RIGHT:
            r = rr[j + 1]
            if j + 1 >= J - 1:
                break  # lost
            j += 1
            part = _part_entering(cc, j, k, E_LEFT)
            entry = E_LEFT
        elif which == E_LEFT:
            r = rr[j]
            if j == 0:
                break  # lost
            j -= 1
            part = _part_entering(cc, j, k, E_RIGHT)
            entry = E_RIGHT
        else:  # diagonal
            if part in (P_UPPER, P_LOWER):
                part = P_LOWER if part == P_UPPER else P_UPPER
            else:
                part = P_LR if part == P_UL else P_UL
            entry = E_DIAG
        if ns + nb > maxb + (OVER_BOUNCES if events else 0):
            break  # lost
    # lost: no way on, absorbed by the floor (``floor`` False) or the grid's bottom, out of the
    # section's ends, past the bounce limit, or out of steps
    return S_LOST, z, t, math.atan2(tz, tr), arc, ns, nb, code, loss, nturn, npath, c_end, kink, math.nan, math.nan
