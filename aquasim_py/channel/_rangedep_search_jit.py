"""Compiled eigenray search of the range-dependent solver (numba): the per-link fan and its
refinement, the safeguarded Newton iteration inside a family (:func:`search`, :func:`search_links`),
the following of known eigenrays to moved end points (:func:`follow_links`) and the check of the
folds and family edges where a search saw eigenrays in the making (:func:`watch_links`). The ray
walk they call is :func:`._rangedep_jit.trace`; see :mod:`.rangedep` for the model and the public
API.

The search of one link works on the depth miss f(theta) = z(theta, R) - z_R of the ray launched
at theta, its exact derivative q = d z / d theta (the walk's tangent-linear map) and its bounce
sequence ("family", code < 0: lost, or below -1 a family with more bounces than the limit,
each its own). Every eigenray is a root of f inside a family. A fan of launch angles, which
stops on each side at its first angle past those whose rays can reach R within the bounce
limit at all (:func:`_fan_cut`: a bound from the section's depth, floor tilt and sound speed;
the steeper rays it leaves out are the walks that cost most), is refined, interval by
interval, until each interval is one of:

* both ends lost or in one family beyond the bounce limit, and no bounce predicted to change
  inside it;
* a family edge (the ends in different families) narrower than ``_EDGE_RAD`` (5.7e-4 deg), or,
  where the miss of an end heads for zero at the edge (its first-order prediction changes sign
  across the interval), narrower than 1e-13 rad: an eigenray at least ``_EDGE_RAD`` from its
  family's edge then lies inside a family interval (and every family at least that wide has a
  sample). Where an end predicts the edge (below: to first order, usually within 10 %), the
  interval is split at two samples around the prediction instead of halved;
* one family: no bounce predicted to change inside it (the walk predicts, to first order, the
  offsets of the launch angle at which a bounce would appear or vanish: a family narrower than
  the fan, e.g. a ray grazing a seamount's flank, lies there), the cubic through f and q at
  both ends monotone inside it, and, where the miss could reach zero inside at its steeper end
  slope, both end slopes within 2x of the secant's (else a fold may hide two roots: split to
  ``_FOLD_RAD``, then the extremum of f located by the secant on q and its sign compared with
  the ends'); below ``_FOLD_RAD``, end slopes of one sign that still bend near zero are split
  on to ``_EDGE_RAD``: not a fold but a corner of f, where a ray's turning point crosses a depth
  node of the field and q jumps, past which f may dip through zero and back. A root is
  bracketed wherever f changes sign.

A predicted bounce change is pursued only in intervals wider than ``_EDGE_RAD``: a family inside
a narrower one is narrower than that, and every eigenray of it (and of the families beside it)
within ``_EDGE_RAD`` of an edge; nor where both ends reach R beyond the bounce limit with the
most bounces a walk goes on for (``OVER_BOUNCES`` past it: one bounce less is still beyond it). A
cubic with one stationary point inside (end slopes of opposite signs) does not split an interval
whose misses keep one sign and stay farther from zero than twice the steeper end slope times the
width (the miss near its one extremum convex or concave, so that the end slopes bound its slope
inside, doubled); the extremum is sought by :func:`_extremum` with the same bound, which stops it
once the bracket is narrow enough for the bound to exclude a root. Against the search without
these shortcuts (a predicted change pursued to 1e-9 rad in every interval, every turning interval
split to ``_FOLD_RAD``, every extremum located to 1e-13 rad), on 1 030 shelf-break links (2
bounces): 10 of 9 841 eigenrays are not found, all within 3.6e-6 rad of their family's edge and
none a link's first arrival, the others' delays within 1e-11 s, for half the walks; the corner
rule adds a pair 2.3e-5 rad apart that both lack (their rule below ``_FOLD_RAD`` is the same),
at no measurable cost (docs/channel.md).
"""

from __future__ import annotations

import math

import numpy as np

from ._rangedep_jit import FS_JA, FS_LEFT, FS_RIGHT, OVER_BOUNCES, S_OVER, S_REACHED, _jit, _part_at, _plane, trace

NF = 14  # fields of one arrival row, see search()
F_TIME, F_THETA0, F_THETAR, F_NS, F_NB, F_CODE, F_ARC, F_LOSS, F_DZDTH, F_NTURN, F_ZMISS, F_CS, F_CR, F_KINK = range(NF)
_EDGE_RAD = 1e-5  # a family's edge is located to this (the acceptance: eigenrays 1.75e-5 rad from it)
_FOLD_RAD = 1e-4  # an interval that may hold a fold is split to this before its extremum is sought
_HEAD_LEVELS = 44  # bisection levels towards an edge at which the miss heads for zero
_MAX_LEVELS = 60
_STACK = 160
_MAXIT = 60
_ACCEPT_M = 1e-6  # a converged bracket is an eigenray only if it hits the receiver this closely
# a watched fold or edge (search()'s docstring): an extremum of a family's miss, or its miss at
# the family's edge, whose lower bound (its margin, m) is below WATCH_M_PER_M times the farther
# end's move since the search (at least 1 m) is checked again by the following tier; 2 m is
# about 3x the median change of the miss at a fixed launch angle when both ends move 1 m (0.73 m
# on 1 500 shelf-break links of the 100-node network; the tail, rays grazing the slope, reaches
# 90 m and is not covered), and the change is taken as growing in proportion to the move beyond
# 1 m (first order). A search keeps the intervals whose margin is below its ``watch_m``:
# WATCH_M_PER_M times the follow radius (at least 1 m)
WATCH_M_PER_M = 2.0
WATCH_ROWS = 16  # watched intervals per link (more: the link cannot be watched, it is searched)
W_A, W_B, W_CODE, W_SIGN, W_MARGIN, W_EDGE = range(6)
NW = 6
_WATCH_STEPS = 16  # doubling steps that seek an extremum that left its watched interval
# a sample: angle, miss, code, d miss / d angle, predicted event offsets above and below, bounces
# (-1: lost)
S_TH, S_F, S_CODE, S_Q, S_EVP, S_EVM, S_NB = range(7)
NS = 7


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
def _sample(rr, zz, cc, bb, ff, floor, zs, zr, R, th, maxb, bpar, dummy, ev, out):
    """Walk the ray launched at ``th`` and write its sample (S_* fields) to ``out``."""
    res = trace(rr, zz, cc, bb, ff, floor, zs, th, R, maxb, bpar, False, dummy, ev)
    out[S_TH] = th
    if res[0] == S_REACHED:
        out[S_F] = res[1] - zr
        out[S_CODE] = res[7]
        out[S_Q] = res[13]
    elif res[0] == S_OVER:  # a family beyond the bounce limit: its own code, below -1
        out[S_F] = res[1] - zr
        out[S_CODE] = -2 - res[7]
        out[S_Q] = res[13]
    else:
        out[S_F] = math.nan
        out[S_CODE] = -1
        out[S_Q] = math.nan
    out[S_NB] = res[5] + res[6] if res[0] == S_REACHED or res[0] == S_OVER else -1
    out[S_EVP] = ev[0]
    out[S_EVM] = ev[1]


@_jit
def _miss(rr, zz, cc, bb, ff, floor, zs, zr, R, th, maxb, bpar, dummy, ev):
    """(depth miss at R, code, d miss / d theta) of the ray launched at ``th``; (NaN, -1, NaN) lost.
    ``ev``: as :func:`._rangedep_jit.trace`'s (size 0 here: no event predictions)."""
    res = trace(rr, zz, cc, bb, ff, floor, zs, th, R, maxb, bpar, False, dummy, ev)
    if res[0] != S_REACHED:
        return math.nan, -1, math.nan
    return res[1] - zr, res[7], res[13]


@_jit
def _refine(rr, zz, cc, bb, ff, floor, zs, zr, R, maxb, bpar, a, fa, b, fb, code, ztol, out, row, dummy, ev):
    """Newton's iteration on the depth miss inside one family's bracket [a, b] (f(a) f(b) <= 0),
    safeguarded: a step that leaves the bracket, or does not halve the miss, is a bisection; the
    bracket shrinks on every evaluation. The converged ray's fields go to out[row]; False if the
    family is not contiguous there or the ray does not reach the receiver within _ACCEPT_M."""
    if fa == 0.0:
        return _fill(rr, zz, cc, bb, ff, floor, zs, zr, R, maxb, bpar, a, code, out, row, dummy, ev)
    if fb == 0.0:
        return _fill(rr, zz, cc, bb, ff, floor, zs, zr, R, maxb, bpar, b, code, out, row, dummy, ev)
    lo, flo, hi = a, fa, b  # f(lo) has the sign of fa, f(hi) the other
    # start from the secant point
    x = b - fb * (b - a) / (fb - fa)
    if not (min(a, b) < x < max(a, b)):
        x = 0.5 * (a + b)
    fx, cx, qx = _miss(rr, zz, cc, bb, ff, floor, zs, zr, R, x, maxb, bpar, dummy, ev)
    fprev = math.inf
    for _ in range(_MAXIT):
        if cx != code:
            # not this family here: the bracket's middle, once; a family broken inside its bracket
            x = 0.5 * (lo + hi)
            fx, cx, qx = _miss(rr, zz, cc, bb, ff, floor, zs, zr, R, x, maxb, bpar, dummy, ev)
            if cx != code:
                return False
        if abs(fx) <= ztol:
            break
        if (fx > 0.0) == (flo > 0.0):
            lo, flo = x, fx
        else:
            hi = x
        if abs(hi - lo) <= 4e-16 * (1.0 + abs(x)):
            break
        xn = x - fx / qx if (qx != 0.0 and math.isfinite(qx)) else math.nan
        if not (min(lo, hi) < xn < max(lo, hi)) or abs(fx) > 0.5 * fprev:
            xn = 0.5 * (lo + hi)
        fprev = abs(fx)
        x = xn
        fx, cx, qx = _miss(rr, zz, cc, bb, ff, floor, zs, zr, R, x, maxb, bpar, dummy, ev)
    return _fill(rr, zz, cc, bb, ff, floor, zs, zr, R, maxb, bpar, x, code, out, row, dummy, ev)


@_jit
def _fill(rr, zz, cc, bb, ff, floor, zs, zr, R, maxb, bpar, m, code, out, row, dummy, ev):
    """Trace the converged ray of launch angle ``m`` (family ``code``) and write its fields to
    out[row] (the ray-tube width d z_R / d theta0 the walk's exact derivative); False (nothing
    written that counts) unless it reaches the receiver within _ACCEPT_M in that family (a jump
    of the miss inside a family is not a root)."""
    res = trace(rr, zz, cc, bb, ff, floor, zs, m, R, maxb, bpar, False, dummy, ev)
    if res[0] != S_REACHED or res[7] != code or not abs(res[1] - zr) <= _ACCEPT_M:
        return False
    _write_row(rr, zz, cc, zs, zr, R, m, res, out, row)
    return True


@_jit
def _write_row(rr, zz, cc, zs, zr, R, m, res, out, row):
    """out[row] from the walk ``res`` (:func:`trace`'s tuple) of the eigenray launched at ``m``."""
    _st, ze, t, thr, arc, ns, nb, cd, loss, nturn, _np, cR, kink, q, _qp = res
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
    out[row, F_DZDTH] = q


@_jit
def _hermite_turns(a, fa, qa, b, fb, qb):
    """Whether the cubic through (a, fa) and (b, fb) with slopes qa, qb has a stationary point
    strictly inside (a, b), or the slopes differ in sign (a fold of the miss may lie inside)."""
    if not (math.isfinite(qa) and math.isfinite(qb)):
        return True
    if (qa > 0.0) != (qb > 0.0) or qa == 0.0 or qb == 0.0:
        return True
    h = b - a
    d = (fb - fa) / h
    # p'(u) on u in [0, 1], times h: qa + (6 d - 4 qa - 2 qb) u + (3 qa + 3 qb - 6 d) u^2
    c0, c1, c2 = qa, 6.0 * d - 4.0 * qa - 2.0 * qb, 3.0 * qa + 3.0 * qb - 6.0 * d
    if c2 == 0.0:
        if c1 == 0.0:
            return False
        u = -c0 / c1
        return 0.0 < u < 1.0
    disc = c1 * c1 - 4.0 * c2 * c0
    if disc < 0.0:
        return False
    sq = math.sqrt(disc)
    u1, u2 = (-c1 - sq) / (2.0 * c2), (-c1 + sq) / (2.0 * c2)
    return 0.0 < u1 < 1.0 or 0.0 < u2 < 1.0


@_jit
def _out_of_reach(f_near, q_steep, w):
    """Whether a miss |f| >= ``f_near`` at both ends of an interval of width ``w`` cannot reach
    zero inside it: f_near > 2 q_steep w, the steeper end slope bounding the slope inside where
    the miss is convex or concave there (near its one extremum), doubled."""
    return f_near > 2.0 * q_steep * w


@_jit
def _extremum(rr, zz, cc, bb, ff, floor, zs, zr, R, maxb, bpar, lo, flo, qlo, hi, fhi, qhi, code, dummy, ev):
    """Whether the miss, of one sign at both ends of [lo, hi] (flo, fhi) with one extremum inside
    (q(lo), q(hi) of opposite signs), reaches the other sign there: regula falsi (Illinois) on q
    towards the extremum, to 1e-13 rad, or stopped once the miss cannot reach the other sign in
    the bracket (:func:`_out_of_reach` of its ends). (A miss of the other sign is followed to the extremum: the fold's two roots are
    bracketed on either side of it.) Returns (angle, miss, code there, margin): the margin a
    lower bound on |miss| over the last bracket (that test's, where it stopped the search; else
    the last miss's |f|), for a miss that kept its sign."""
    x, fx, cx = lo, math.nan, code
    positive = flo > 0.0
    fl, fh, ql, qh = abs(flo), abs(fhi), qlo, qhi  # at the ends (Illinois halves the slopes it steps with)
    xo, fo = math.nan, 0.0  # the farthest miss of the other sign so far
    side = 0
    for _ in range(_MAXIT):
        x = (lo * qhi - hi * qlo) / (qhi - qlo)
        if not (lo < x < hi):
            x = 0.5 * (lo + hi)
        fx, cx, qx = _miss(rr, zz, cc, bb, ff, floor, zs, zr, R, x, maxb, bpar, dummy, ev)
        if cx != code or not math.isfinite(qx):
            break
        if (fx > 0.0) != positive and abs(fx) > abs(fo):
            xo, fo = x, fx
        if (qx > 0.0) == (qlo > 0.0):
            lo, qlo, fl, ql = x, qx, abs(fx), qx
            if side == 1:
                qhi *= 0.5
            side = 1
        else:
            hi, qhi, fh, qh = x, qx, abs(fx), qx
            if side == -1:
                qlo *= 0.5
            side = -1
        if hi - lo <= 1e-13:
            break
        # no root in [lo, hi]: none of the other sign yet, and the misses cannot reach it there
        if math.isnan(xo) and _out_of_reach(min(fl, fh), max(abs(ql), abs(qh)), hi - lo):
            return x, fx, cx, min(fl, fh) - 2.0 * max(abs(ql), abs(qh)) * (hi - lo)
    if cx == code and (fx > 0.0) == positive and not math.isnan(xo):
        return xo, fo, code, 0.0
    return x, fx, cx, abs(fx)


@_jit
def _cusp_angles(rr, zz, cc, bb, zs):
    """Launch angles next to those of the rays that would turn exactly at a depth node in the
    source's profile (cos th = c(z_s) / c(z_node), up towards shallower nodes, down towards
    deeper ones): there the depth miss has a kink and a family may fold (two eigenrays a
    fraction of a fan spacing apart). Two samples, 1e-7 on either side of each. Only nodes
    above the deepest floor ``bb`` of the section (no ray turns below it); the surface node
    too (the ray that grazes it: the edge between the rays that turn below it and those that
    bounce)."""
    J, K = rr.size, zz.size
    j = 0
    while j < J - 2 and rr[j + 1] <= 0.0:
        j += 1
    w = (0.0 - rr[j]) / (rr[j + 1] - rr[j])
    cs = _speed_src(rr, zz, cc, zs, 0.0)  # R unused
    out = np.empty(2 * K)
    n = 0
    deepest = bb.max()
    for k in range(0, K - 1):
        if zz[k] >= deepest:
            break  # a ray cannot turn below the floor: it reflects off it first
        ck = cc[j, k] + w * (cc[j + 1, k] - cc[j, k])
        if ck > cs and zz[k] != zs:
            a = math.acos(cs / ck)
            if zz[k] < zs:
                a = -a
            out[n] = a * (1.0 - 1e-7)
            out[n + 1] = a * (1.0 + 1e-7)
            n += 2
    return out[:n]


@_jit
def _fan_w(i, wmax, nfan):
    """w = tan(theta) R / H of the fan's sample i: the middles of nfan equal cells of [-wmax, wmax]."""
    return -wmax + 2.0 * wmax * (i + 0.5) / nfan


@_jit
def _flattest(phi, ratio, gdrift, v):
    """A lower bound (rad, <= 0: none) on the flattest angle of a leg that starts at angle
    ``phi`` (its cosine at most ``ratio`` cos phi there, by c's range) and spans ``v`` in depth,
    for :func:`_reach`: along a ray of the model (circular arcs in linear c), d(cos phi / c) /
    ds = -(dc/dr) / c^2, so after a run s, cos phi <= ratio cos phi0 + gdrift s (``gdrift`` =
    c_max |dc/dr|_max / c_min^2); while phi >= psi the leg has run at most v / sin(psi), so phi
    never falls to a psi with cos psi > ratio cos phi0 + gdrift v / sin(psi) (the largest such
    psi, sought by iteration and checked)."""
    if phi <= 0.0:
        return 0.0
    a = ratio * math.cos(phi)
    if a >= 1.0:
        return 0.0
    psi = math.acos(a)
    d = gdrift * v
    if d > 0.0:
        for _ in range(60):
            x = a + d / math.sin(psi)
            if x >= 1.0:
                return 0.0
            nxt = math.acos(x)
            done = psi - nxt <= 1e-13
            psi = nxt
            if done:
                break
        psi *= 1.0 - 1e-6  # just below the largest root, where the inequality is strict
        if not math.cos(psi) - a - d / math.sin(psi) > 0.0:
            return 0.0
    return psi


@_jit
def _reach(th, nlegs, v_first, v_last, hmax, c_src, cmin, cmax, grad, tilt):
    """An upper bound (m, inf: none) on how far in range a ray launched at |theta| = ``th`` gets
    with nlegs - 1 bounces, for :func:`_fan_cut`. A leg (the stretch between the source, a
    bounce and the receiver) whose ray never turns level is monotone in depth: it spans at most
    ``v_first`` (the first: from the source to the surface or the floor it heads for), ``hmax``
    (the deepest water) or ``v_last`` (the last: from a boundary to the receiver) in depth, so
    at most that over tan(psi) in range, psi its flattest angle (:func:`_flattest`). A surface
    bounce keeps |phi|; a bottom bounce off a floor tilted at most ``tilt`` turns it by at
    most 2 tilt."""
    gdrift = cmax * grad / (cmin * cmin)
    total = 0.0
    phi = th
    for k in range(nlegs):
        v = hmax
        if k == 0:
            v = v_first
        elif k == nlegs - 1:
            v = v_last
        # cos phi / c at the leg's start: the source's c on the first leg, at least c_min later
        psi = _flattest(phi, cmax / (c_src if k == 0 else cmin), gdrift, v)
        if psi <= 0.0:
            return math.inf
        total += v / math.tan(psi)
        phi = psi - 2.0 * tilt
    return total


@_jit
def _fan_cut(rr, zz, cc, bb, ff, floor, zs, zr, R, H, maxb, wmax):
    """(w_down, w_up): the w = tan(theta) R / H beyond which no ray launched downwards (theta >
    0), or upwards, reaches the receiver's range with at most ``maxb`` bounces (inf: no such
    bound below ``wmax``): the smallest |theta| whose :func:`_reach` falls short of R
    (bisection; _reach falls as |theta| grows), from the section's own extremes: its deepest
    water (each interval's deeper end plus half its width times the steepest tilt), steepest
    floor tilt (the tangent angles of its arcs or segments, which turn monotonically along
    each), sound speed range (c is linear in each triangle: extremes at the nodes) and largest
    horizontal gradient (each triangle's is its horizontal edge's)."""
    J, K = cc.shape
    if not floor or J < 2 or R <= 0.0:
        return math.inf, math.inf
    tilt = 0.0
    for j in range(J):
        tilt = max(tilt, abs(ff[j, FS_LEFT]), abs(ff[j, FS_RIGHT]), abs(ff[j, FS_JA]))
    if tilt >= 0.25 * math.pi:
        return math.inf, math.inf
    hmax = max(zs, zr)
    for j in range(J - 1):
        hmax = max(hmax, max(bb[j], bb[j + 1]) + 0.5 * (rr[j + 1] - rr[j]) * math.tan(tilt))
    cmin, cmax, grad = math.inf, 0.0, 0.0
    for j in range(J):
        for k in range(K):
            cmin = min(cmin, cc[j, k])
            cmax = max(cmax, cc[j, k])
            if j + 1 < J and rr[j + 1] > rr[j]:
                grad = max(grad, abs(cc[j + 1, k] - cc[j, k]) / (rr[j + 1] - rr[j]))
    if not cmin > 0.0:
        return math.inf, math.inf
    c_src = max(_speed_src(rr, zz, cc, zs, R), cmin)
    nlegs = maxb + 1
    v_last = max(zr, hmax - zr)
    out = np.full(2, math.inf)
    for side in range(2):
        # the first leg heads for the floor (downwards) or the surface; without bounces it
        # ends at the receiver
        v_first = hmax - zs if side == 0 else zs
        if nlegs == 1:
            v_first = abs(zr - zs)
        hi = math.atan(wmax * H / R)
        if not _reach(hi, nlegs, v_first, v_last, hmax, c_src, cmin, cmax, grad, tilt) < R:
            continue
        lo = 0.0
        for _ in range(48):
            m = 0.5 * (lo + hi)
            if _reach(m, nlegs, v_first, v_last, hmax, c_src, cmin, cmax, grad, tilt) < R:
                hi = m
            else:
                lo = m
        out[side] = math.tan(hi) * R / H
    return out[0], out[1]


@_jit
def search(rr, zz, cc, bb, ff, floor, zs, zr, R, maxb, bpar, wmax, nfan, H, ztol, watch_m, out, watch):
    """Every eigenray from (0, zs) to (R, zr) with at most ``maxb`` boundary bounces: a fan of
    ``nfan`` launch angles uniform in w = tan(theta) R / H over [-wmax, wmax] (the families of a
    waveguide of depth H lie about 2 apart in w), each side stopped at its first angle past
    those that can reach R within ``maxb`` bounces (:func:`_fan_cut`), with samples next to the
    angles of rays that turn at a depth node of the source's profile, refined as the module
    docstring says, and Newton's iteration in every bracket. Returns (the number of arrival rows
    written to ``out``, the number of watched intervals, written to ``watch`` as far as it has
    rows).

    Watched: an interval of one family whose miss has one extremum inside (end slopes of
    opposite signs) and keeps the ends' sign there, but may come within ``watch_m`` (m) of zero
    (its margin: the bound of :func:`_out_of_reach` on the interval, or on the last bracket of
    :func:`_extremum` where it sought the extremum, else the extremum's miss): a small move
    of an end may carry that extremum through zero, where two eigenrays are born (a fold), which
    following the link's known eigenrays cannot see. And a located family edge (the last
    interval of two families, at most ``_EDGE_RAD`` wide) where the miss of one of them heads
    for zero beyond the edge (away from the family: else it reaches zero inside, at a known
    eigenray, which following sees leave) but stays within ``watch_m`` of it there (its margin:
    |f| less the end's slope times the width): a small move may carry that zero across the
    edge, where an eigenray enters the family, which following cannot see either. Its rows (a,
    b, family, sign of the ends' miss, margin, edge: 0 for a fold, 1 where the family is at a,
    -1 at b) are what :func:`watch_links` checks again at moved ends."""
    dummy = np.empty((1, 3))
    ev = np.empty(2)
    noev = np.empty(0)  # walks that need no event predictions
    cusp = np.sort(_cusp_angles(rr, zz, cc, bb, zs))
    # the rays that turn between two depth nodes form a band of launch angles; where one is
    # narrower than the fan's spacing there, a fold inside it (two eigenrays) would fall between
    # samples: two more samples inside it (a summer mixed layer turns its rays in a 0.1 deg band)
    dw = 2.0 * wmax / nfan
    extra = np.empty(2 * cusp.size)
    ne = 0
    for i in range(0, cusp.size - 2, 2):
        lo, hi = cusp[i + 1], cusp[i + 2]  # the inner samples of two neighbouring cusps
        if (lo > 0.0) != (hi > 0.0) or hi - lo <= 1e-12:
            continue
        spacing = dw * H / R * math.cos(0.5 * (lo + hi)) ** 2
        if hi - lo < spacing:
            extra[ne] = lo + (hi - lo) / 3.0
            extra[ne + 1] = lo + 2.0 * (hi - lo) / 3.0
            ne += 2
    # the fan stops at its first sample past the launch angles that can reach R within maxb
    # bounces (_fan_cut: steeper rays, the dearest walks, hold no eigenray)
    w_down, w_up = _fan_cut(rr, zz, cc, bb, ff, floor, zs, zr, R, H, maxb, wmax)
    i0, i1 = 0, nfan - 1
    cut_lo = cut_hi = False
    for i in range(nfan):
        w = _fan_w(i, wmax, nfan)
        if w < -w_up:
            i0, cut_lo = i, True
        elif w > w_down:
            i1, cut_hi = i, True
            break
    nf = i1 - i0 + 1
    th = np.empty(nf + cusp.size + ne)
    for m in range(nf):
        th[m] = math.atan(_fan_w(i0 + m, wmax, nfan) * H / R)
    # the cusp and fold-band samples, none past a cut side's last fan sample
    th_lo = th[0] if cut_lo else -math.inf
    th_hi = th[nf - 1] if cut_hi else math.inf
    m = nf
    for x in np.concatenate((cusp, extra[:ne])):
        if th_lo < x < th_hi:
            th[m] = x
            m += 1
    th = np.sort(th[:m])
    nth = th.size
    smp = np.empty((nth, NS))
    for i in range(nth):
        _sample(rr, zz, cc, bb, ff, floor, zs, zr, R, th[i], maxb, bpar, dummy, ev, smp[i])
    n = 0
    cap = out.shape[0]
    nbmax = 8 * nth + 256
    br = np.empty((nbmax, 4))  # brackets (a, fa, b, fb) and their family
    bc = np.empty(nbmax, np.int64)
    nbr = 0
    stack = np.empty((_STACK, 2 * NS))
    lev = np.zeros(_STACK, np.int64)
    mid = np.empty(NS)
    mid2 = np.empty(NS)
    nw = 0
    for i in range(nth - 1):
        stack[0, :NS] = smp[i]
        stack[0, NS:] = smp[i + 1]
        lev[0] = 0
        top = 1
        while top > 0:
            top -= 1
            A = stack[top, :NS].copy()
            B = stack[top, NS:].copy()
            lv = lev[top]
            a, b = A[S_TH], B[S_TH]
            ca, cb = int(A[S_CODE]), int(B[S_CODE])
            w = b - a
            # a bounce predicted to appear or vanish inside (a family narrower than the interval)
            event = (A[S_EVP] < w or B[S_EVM] < w) and w > _EDGE_RAD
            split = False
            if ca != cb:
                if w > _EDGE_RAD:
                    split = True
                elif lv < _HEAD_LEVELS and w > 1e-13:
                    # keep going while an end's miss, continued to the other end, changes sign
                    for E, other in ((A, b), (B, a)):
                        if E[S_CODE] >= 0 and math.isfinite(E[S_Q]):
                            fe = E[S_F] + E[S_Q] * (other - E[S_TH])
                            if (fe > 0.0) != (E[S_F] > 0.0):
                                split = True
                # no split for a predicted bounce change alone: the edge itself is one, and a
                # family inside an interval narrower than _EDGE_RAD has every eigenray within
                # _EDGE_RAD of its edge
            elif ca < 0:
                # a family within the limit may hide where a bounce changes, unless the ends' rays
                # reach R with the most bounces a walk goes on for (one bounce less is still beyond
                # the limit; lost rays are split)
                split = event and not (ca < -1 and A[S_NB] >= maxb + OVER_BOUNCES)
            else:
                fa, fb = A[S_F], B[S_F]
                qa, qb = A[S_Q], B[S_Q]
                turns = w > 1e-13 and _hermite_turns(a, fa, qa, b, fb, qb)
                # bent: the end slopes differ from the secant by more than 2x, near enough to zero
                # that the miss might reach it (at the steeper slope) inside
                d = abs(fb - fa) / w
                bent = not (0.5 * d <= abs(qa) <= 2.0 * d and 0.5 * d <= abs(qb) <= 2.0 * d)
                near = min(abs(fa), abs(fb)) < max(abs(qa), abs(qb)) * w
                # one extremum inside (end slopes of opposite signs) matters where the miss might
                # reach zero there: the ends of opposite signs, or the nearer one within twice the
                # steeper end slope times the width (the bound of _extremum); two (end slopes of
                # one sign, the cubic turning) always do
                one = (qa > 0.0) != (qb > 0.0)
                far = (fa > 0.0) == (fb > 0.0) and _out_of_reach(min(abs(fa), abs(fb)), max(abs(qa), abs(qb)), w)
                if turns and one and far:
                    margin = min(abs(fa), abs(fb)) - 2.0 * max(abs(qa), abs(qb)) * w
                    if margin < watch_m:
                        nw = _watch_row(watch, nw, a, b, ca, fa, margin, 0.0)
                turns = turns and not (one and far)
                split = event or ((turns or (bent and near)) and w > _FOLD_RAD)
                # end slopes of one sign that differ from the secant by more than 2x (or a cubic
                # through them that turns twice) within _FOLD_RAD: not a fold (a fold's extremum
                # lies between slopes of opposite signs, below) but a corner of the miss (a ray
                # turning at a depth node of the field, where d z / d theta jumps), beyond which
                # it may dip through zero and back
                split = split or (not one and (turns or bent) and near and w > _EDGE_RAD)
                if not split:
                    if (fa > 0.0) != (fb > 0.0) or fa == 0.0:
                        if nbr < nbmax:
                            br[nbr, 0], br[nbr, 1], br[nbr, 2], br[nbr, 3] = a, fa, b, fb
                            bc[nbr] = ca
                            nbr += 1
                    elif turns and (A[S_Q] > 0.0) != (B[S_Q] > 0.0):
                        # one extremum inside: two roots if its miss has the other sign
                        x, fx, cx, margin = _extremum(
                            rr, zz, cc, bb, ff, floor, zs, zr, R, maxb, bpar, a, fa, A[S_Q], b, fb, B[S_Q], ca, dummy,
                            noev,
                        )  # fmt: skip
                        if cx == ca and (fx > 0.0) == (fa > 0.0) and margin < watch_m:
                            nw = _watch_row(watch, nw, a, b, ca, fa, margin, 0.0)
                        if cx == ca and (fx > 0.0) != (fa > 0.0) and nbr + 2 <= nbmax:
                            br[nbr, 0], br[nbr, 1], br[nbr, 2], br[nbr, 3] = a, fa, x, fx
                            br[nbr + 1, 0], br[nbr + 1, 1], br[nbr + 1, 2], br[nbr + 1, 3] = x, fx, b, fb
                            bc[nbr] = ca
                            bc[nbr + 1] = ca
                            nbr += 2
                    continue
            if ca != cb and not split:
                # a located edge: a family's miss that may reach zero there with a small move
                # brings an eigenray in across it, which following the known ones cannot see
                for E, e_code, right in ((A, ca, False), (B, cb, True)):
                    if e_code >= 0:
                        margin = _edge_margin(E[S_F], E[S_Q], w)
                        # the miss heads for zero away from the family (else it reaches it inside,
                        # at a known eigenray: that one leaving is seen by following)
                        outward = not math.isfinite(E[S_Q]) or ((E[S_F] > 0.0) == (E[S_Q] > 0.0)) == right
                        if outward and margin < watch_m:
                            nw = _watch_row(watch, nw, a, b, e_code, E[S_F], max(margin, 0.0), -1.0 if right else 1.0)
            if not split or lv >= _MAX_LEVELS or top + 3 > _STACK:
                continue
            # a family's edge that an end predicts: two samples around the prediction (a tenth of
            # its distance from that end either side, at least a quarter of _EDGE_RAD), three
            # intervals; the predictions are first order, usually within 10 % (measured on the
            # shelf-break sample), so the middle one mostly holds the edge and is narrow
            if ca != cb and w > _EDGE_RAD:
                pe, dist = math.nan, 0.0
                if A[S_EVP] < w:
                    pe, dist = a + A[S_EVP], A[S_EVP]
                if B[S_EVM] < w and (math.isnan(pe) or B[S_EVM] < dist):
                    pe, dist = b - B[S_EVM], B[S_EVM]
                dl = max(0.1 * dist, 0.25 * _EDGE_RAD)
                if a < pe - dl and pe + dl < b:
                    _sample(rr, zz, cc, bb, ff, floor, zs, zr, R, pe - dl, maxb, bpar, dummy, ev, mid)
                    _sample(rr, zz, cc, bb, ff, floor, zs, zr, R, pe + dl, maxb, bpar, dummy, ev, mid2)
                    stack[top, :NS] = A
                    stack[top, NS:] = mid
                    stack[top + 1, :NS] = mid
                    stack[top + 1, NS:] = mid2
                    stack[top + 2, :NS] = mid2
                    stack[top + 2, NS:] = B
                    lev[top] = lev[top + 1] = lev[top + 2] = lv + 1
                    top += 3
                    continue
            m = 0.5 * (a + b)
            _sample(rr, zz, cc, bb, ff, floor, zs, zr, R, m, maxb, bpar, dummy, ev, mid)
            stack[top, :NS] = A
            stack[top, NS:] = mid
            lev[top] = lv + 1
            stack[top + 1, :NS] = mid
            stack[top + 1, NS:] = B
            lev[top + 1] = lv + 1
            top += 2
    for q in range(nbr):
        if n >= cap:
            break
        if _refine(
            rr, zz, cc, bb, ff, floor, zs, zr, R, maxb, bpar, br[q, 0], br[q, 1], br[q, 2], br[q, 3], bc[q], ztol,
            out, n, dummy, noev,
        ):  # fmt: skip
            # the same eigenray from two brackets sharing a sample
            dup = False
            for p in range(n):
                if out[p, F_CODE] == out[n, F_CODE] and abs(out[p, F_THETA0] - out[n, F_THETA0]) <= 1e-12:
                    dup = True
                    break
            if not dup:
                n += 1
    return n, nw


@_jit
def _edge_margin(f, q, w):
    """A lower bound (m) on |miss| across a family's last interval of width ``w`` (rad) before
    its edge, from its end's miss ``f`` and slope ``q``: |f| - |q| w (0 where q is not finite);
    the search's watch of the edge and its check at moved ends both use it."""
    return abs(f) - abs(q) * w if math.isfinite(q) else 0.0


@_jit
def _watch_row(watch, nw, a, b, code, f, margin, edge):
    """Write the watched interval [a, b] of family ``code`` (its ends' miss of the sign of ``f``,
    at least ``margin`` (m) off zero inside; ``edge`` 0 a fold's interval, +-1 an edge's with the
    family at a or b) to ``watch`` if it has room; returns the count of watched intervals, this
    one included."""
    if nw < watch.shape[0]:
        watch[nw, W_A], watch[nw, W_B], watch[nw, W_CODE] = a, b, code
        watch[nw, W_SIGN] = 1.0 if f > 0.0 else -1.0
        watch[nw, W_MARGIN] = margin
        watch[nw, W_EDGE] = edge
    return nw + 1


@_jit
def search_links(
    starts, ends, rr_all, zz, cc_all, bb_all, ff_all, floor, zs, zr, R, maxb, bpar, wmax, nfan, H, ztol, watch_m, cap
):
    """:func:`search` for every link l: its section rows starts[l]:ends[l] of rr_all (J,),
    cc_all (J, K), bb_all (J,) (fewer than 2 rows: skipped), keeping the watched intervals
    whose margin is below ``watch_m`` (m). Returns (rows (L, cap, NF),
    counts (L,), watched intervals (L, WATCH_ROWS, NW) (NaN past the count), their counts (L,)
    (above WATCH_ROWS: more than it holds))."""
    L = zs.size
    out = np.full((L, cap, NF), np.nan)
    cnt = np.zeros(L, np.int64)
    watch = np.full((L, WATCH_ROWS, NW), np.nan)
    nwatch = np.zeros(L, np.int64)
    for l in range(L):
        o0, o1 = starts[l], ends[l]
        if o1 - o0 < 2:
            continue
        cnt[l], nwatch[l] = search(
            rr_all[o0:o1],
            zz,
            cc_all[o0:o1],
            bb_all[o0:o1],
            ff_all[o0:o1],
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
            watch_m,
            out[l],
            watch[l],
        )
    return out, cnt, watch, nwatch


@_jit
def trace_links(offs, rr_all, zz, cc_all, bb_all, ff_all, floor, zs, R, theta0, maxb, bpar, npts):
    """The walk of one ray per link (launch angle theta0[l]): vertices (L, npts, 3) of (r, z, t)
    and their counts, for plots and for the reference checks."""
    L = zs.size
    paths = np.full((L, npts, 3), np.nan)
    cnt = np.zeros(L, np.int64)
    ev = np.empty(0)
    for l in range(L):
        o0, o1 = offs[l], offs[l + 1]
        res = trace(
            rr_all[o0:o1], zz, cc_all[o0:o1], bb_all[o0:o1], ff_all[o0:o1], floor, zs[l], theta0[l], R[l], maxb,
            bpar, True, paths[l], ev,
        )  # fmt: skip
        cnt[l] = res[10]
    return paths, cnt


_FOLLOW_S = 1e-10  # a followed delay's error from its walk's remaining depth miss, at most
_FOLLOW_M = 1e-3  # and that miss, at most (the ray-tube width, for the level, is taken there)


@_jit
def _close_enough(res, zr, ztol):
    """Whether the walk ``res`` ends near enough the receiver for its delay, corrected to first
    order in the depth miss f (t + f' sin theta_R / c_R, Fermat), to be within _FOLLOW_S of the
    eigenray's: the correction's error is f^2 / 2 times the rate of sin(theta_R) / c_R with the
    depth along the family, (cos theta_R d theta_R/d theta0) / (c_R dz_R/d theta0) + (dc/dz) /
    c_R^2, |dc/dz| <= 1 1/s in any ocean; doubled."""
    f = abs(res[1] - zr)
    if f <= ztol:
        return True
    if f > _FOLLOW_M or not (math.isfinite(res[13]) and res[13] != 0.0):
        return False
    c = res[11]
    rate = abs(math.cos(res[3]) * res[14] / res[13]) / c + 1.0 / (c * c)
    return f * f * rate <= _FOLLOW_S


@_jit
def follow_links(starts, ends, rr_all, zz, cc_all, bb_all, ff_all, floor, zs, zr, R, maxb, bpar, theta0, code, ztol):
    """Follow known eigenrays to moved end points: for each link l and each of its arrivals q
    (launch angle theta0[l, q], bounce sequence code[l, q] >= 0), Newton's iteration on the depth
    miss from the old launch angle in the new section with the walk's exact derivative, keeping
    the bounce sequence, to ``ztol`` or until the delay corrected to first order for the remaining
    miss is within _FOLLOW_S of the eigenray's (:func:`_close_enough`). Where the old angle's ray is no longer in the family (a moved
    source's ray near a boundary), the family is sought just past the edge that walk predicts on
    either side (at 1.001, 1.1 and 1.5 times the predicted offset). Returns the arrival rows (L,
    Q, NF) (as :func:`search` writes them) and whether each was followed (L, Q): not where its
    bounce sequence changed (a step that leaves it is halved up to six times first) or Newton did
    not converge in 12 steps, or would have to go as far as half the gap to a sibling (another
    of the link's eigenrays in its sequence: it might land on it; steps are shortened to stay
    inside) (its row is then NaN). Each arrival costs one walk per step: one for a move of millimetres, two or three
    for a metre."""
    L, Q = theta0.shape
    out = np.full((L, Q, NF), np.nan)
    ok_all = np.zeros((L, Q), np.bool_)
    dummy = np.empty((1, 3))
    ev = np.empty(0)
    evw = np.empty(2)  # the first walk's predictions
    for l in range(L):
        o0, o1 = starts[l], ends[l]
        if o1 - o0 < 2:
            continue
        rr, cc, bb, ff = rr_all[o0:o1], cc_all[o0:o1], bb_all[o0:o1], ff_all[o0:o1]
        for q in range(Q):
            cd = code[l, q]
            if cd < 0 or not math.isfinite(theta0[l, q]):
                continue
            a = theta0[l, q]
            # half the gap to its nearest sibling (an eigenray of its sequence): a step beyond it
            # may land on the sibling (a fold), so it is shortened, and the follow given up
            # where it cannot be avoided
            half = math.inf
            for q2 in range(Q):
                if q2 != q and code[l, q2] == cd and math.isfinite(theta0[l, q2]):
                    half = min(half, 0.5 * abs(theta0[l, q2] - a))
            res = trace(rr, zz, cc, bb, ff, floor, zs[l], a, R[l], maxb, bpar, False, dummy, evw)
            if res[0] != S_REACHED or res[7] != cd:
                # the family moved off the old angle (a moved source's ray near a boundary): just
                # past the edge this walk predicts, on either side, the family may be found again
                found = False
                p, m = evw[0], evw[1]
                for off in (p, -m):
                    if not (math.isfinite(off) and abs(off) < 0.05):
                        continue
                    for grow in (1.001, 1.1, 1.5):
                        b = a + off * grow
                        rb = trace(rr, zz, cc, bb, ff, floor, zs[l], b, R[l], maxb, bpar, False, dummy, ev)
                        if rb[0] == S_REACHED and rb[7] == cd:
                            found = True
                            break
                    if found:
                        break
                if not found:
                    continue
                a, res = b, rb
            fa = res[1] - zr[l]
            ok = _close_enough(res, zr[l], ztol)
            for _ in range(12):
                if ok:
                    break
                s = res[13]
                if not (math.isfinite(s) and s != 0.0):
                    break
                b = a - fa / s
                for _h in range(12):
                    if abs(b - theta0[l, q]) < half:
                        break
                    b = a + 0.5 * (b - a)
                if not abs(b - theta0[l, q]) < half:
                    break
                rb = trace(rr, zz, cc, bb, ff, floor, zs[l], b, R[l], maxb, bpar, False, dummy, ev)
                # a step that leaves the bounce sequence is shortened (the family may be narrower
                # than the step), up to 1/64 of it
                for _h in range(6):
                    if rb[0] == S_REACHED and rb[7] == cd:
                        break
                    b = a + 0.5 * (b - a)
                    rb = trace(rr, zz, cc, bb, ff, floor, zs[l], b, R[l], maxb, bpar, False, dummy, ev)
                if rb[0] != S_REACHED or rb[7] != cd:
                    break
                a, fa, res = b, rb[1] - zr[l], rb
                ok = _close_enough(res, zr[l], ztol)
            if not ok:
                continue
            _write_row(rr, zz, cc, zs[l], zr[l], R[l], a, res, out[l], q)
            ok_all[l, q] = True
    return out, ok_all


@_jit
def watch_links(
    starts, ends, rr_all, zz, cc_all, bb_all, ff_all, floor, zs, zr, R, maxb, bpar, watch, nwatch, reach, theta0, code0
):
    """Whether each link's watched intervals (:func:`search`: ``watch`` (L, WATCH_ROWS, NW),
    counts ``nwatch``) whose margin is below the link's ``reach`` (m; how far the miss at a fixed
    launch angle may have moved since the search) still hold no eigenray at the link's (moved)
    ends: both ends of each in
    its family with the miss of the watched sign; the extremum between end slopes of opposite
    signs (where it left the interval, it is sought downhill in up to ``_WATCH_STEPS`` doubling
    steps, each in the family with that sign); and the miss kept off zero there
    (:func:`_out_of_reach` of the bracket's ends, else :func:`_extremum` locates the extremum).
    False where a check fails (a fold may have put two eigenrays there: the link is to be
    searched) or the link had more watched intervals than rows. A miss of the other sign that
    the link's known eigenrays explain (launch angles ``theta0`` (L, Q), families ``code0``,
    NaN / -1 past each link's own) passes: one end of an interval across one of them, or the
    downhill search stopped by one (the miss is monotone from the interval to it, so the
    extremum watched there is gone). Two walks per interval, more where the extremum moved or
    is sought. A watched edge passes while it stays in its interval (its family at that end,
    another at the other) with the family's miss kept off zero across the interval as the
    search left it (two walks); an edge that moved out is not sought (that costs about what the
    search's own edge location does): the link is searched."""
    L = zs.size
    clear = np.ones(L, np.bool_)
    dummy = np.empty((1, 3))
    noev = np.empty(0)
    for l in range(L):
        if nwatch[l] == 0:
            continue
        o0, o1 = starts[l], ends[l]
        if nwatch[l] > watch.shape[1] or o1 - o0 < 2:
            clear[l] = False
            continue
        rr, cc, bb, ff = rr_all[o0:o1], cc_all[o0:o1], bb_all[o0:o1], ff_all[o0:o1]
        for k in range(nwatch[l]):
            if watch[l, k, W_MARGIN] >= reach[l]:
                continue  # the miss cannot have moved that far: no fold yet
            a, b = watch[l, k, W_A], watch[l, k, W_B]
            code, positive = int(watch[l, k, W_CODE]), watch[l, k, W_SIGN] > 0.0
            fa, ca, qa = _miss(rr, zz, cc, bb, ff, floor, zs[l], zr[l], R[l], a, maxb, bpar, dummy, noev)
            fb, cb, qb = _miss(rr, zz, cc, bb, ff, floor, zs[l], zr[l], R[l], b, maxb, bpar, dummy, noev)
            if watch[l, k, W_EDGE] != 0.0:
                # an edge: clear while it stays in its interval (the family at its end, another
                # at the other) with the miss there kept off zero across the interval, as the
                # search left it; an edge that moved is not sought but the link searched
                if watch[l, k, W_EDGE] > 0.0:
                    fe, ce, qe, co = fa, ca, qa, cb
                else:
                    fe, ce, qe, co = fb, cb, qb, ca
                if not (ce == code and co != code and (fe > 0.0) == positive and _edge_margin(fe, qe, b - a) > 0.0):
                    clear[l] = False
                    break
                continue
            if ca != code or cb != code:
                clear[l] = False
                break
            flips = int((fa > 0.0) != positive) + int((fb > 0.0) != positive)
            if flips == 1 and _known_between(theta0[l], code0[l], code, a, b) == 1:
                continue  # a known eigenray moved into the interval
            ok = flips == 0
            if ok and (qa > 0.0) == (qb > 0.0):
                # the extremum left the interval as the ends moved: sought downhill (the miss
                # nearer zero that way) in doubling steps until the slope turns, every walk in
                # the family with the watched sign
                down = (qa > 0.0) == positive  # the miss nears zero towards smaller angles
                e, fe, qe = (a, fa, qa) if down else (b, fb, qb)
                step, found, gone = b - a, False, False
                for _ in range(_WATCH_STEPS):
                    x = e - step if down else e + step
                    fx, cx, qx = _miss(rr, zz, cc, bb, ff, floor, zs[l], zr[l], R[l], x, maxb, bpar, dummy, noev)
                    if cx == code and (fx > 0.0) != positive and _known_between(theta0[l], code0[l], code, x, e) > 0:
                        found = gone = True  # downhill to a known eigenray: no extremum before it
                        break
                    if cx != code or (fx > 0.0) != positive or not math.isfinite(qx):
                        break
                    if (qx > 0.0) != (qe > 0.0):
                        found = True
                        break
                    e, fe, qe = x, fx, qx
                    step *= 2.0
                ok = found
                if gone:
                    continue
                if found:  # the new bracket of the extremum
                    if down:
                        a, fa, qa, b, fb, qb = x, fx, qx, e, fe, qe
                    else:
                        a, fa, qa, b, fb, qb = e, fe, qe, x, fx, qx
            if ok and not _out_of_reach(min(abs(fa), abs(fb)), max(abs(qa), abs(qb)), b - a):
                _x, fx, cx, _margin = _extremum(
                    rr, zz, cc, bb, ff, floor, zs[l], zr[l], R[l], maxb, bpar, a, fa, qa, b, fb, qb, code, dummy, noev
                )  # fmt: skip
                ok = cx == code and (fx > 0.0) == positive
            if not ok:
                clear[l] = False
                break
    return clear


@_jit
def _known_between(theta, code, family, x, y):
    """How many of the angles ``theta`` of family ``family`` (in ``code``) lie between x and y."""
    lo, hi = min(x, y), max(x, y)
    k = 0
    for i in range(theta.shape[0]):
        if code[i] == family and lo <= theta[i] <= hi:
            k += 1
    return k
