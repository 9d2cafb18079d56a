"""Compiled eigenray search of the range-dependent solver (numba): the per-link fan, the
bisection towards family edges, regula falsi inside a family (:func:`search`, :func:`search_links`)
and the following of known eigenrays to moved end points (:func:`track_links`). The ray walk they
call is :func:`._rangedep_jit.trace`; see :mod:`.rangedep` for the model and the public API.
"""

from __future__ import annotations

import math

import numpy as np

from ._rangedep_jit import S_REACHED, _jit, _part_at, _plane, trace

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
    # a jump of the miss inside a family (a ray hitting a vertex of the floor polyline reflects
    # off one slope or the other) is not a root: _fill refuses it
    h = 1e-7 * max(1.0, abs(m)) if abs(b - a) > 1e-6 else 0.25 * abs(b - a)
    return _fill(rr, zz, cc, bb, floor, zs, zr, R, maxb, bpar, m, code, h, out, row, dummy)


@_jit
def _fill(rr, zz, cc, bb, floor, zs, zr, R, maxb, bpar, m, code, h, out, row, dummy):
    """Trace the converged ray of launch angle ``m`` (family ``code``) and write its fields to
    out[row]; False (nothing written that counts) unless it reaches the receiver within
    _ACCEPT_M in that family. ``h``: the step of the central difference d z_R / d theta0 (the
    ray-tube width)."""
    res = trace(rr, zz, cc, bb, floor, zs, m, R, maxb, bpar, False, dummy)
    if res[0] != S_REACHED or res[7] != code or not abs(res[1] - zr) <= _ACCEPT_M:
        return False
    _write_row(rr, zz, cc, zs, zr, R, m, res, out, row)
    fm = res[1] - zr
    # ray-tube width: d z_end / d theta0 by a small central difference inside the family
    fp, cp = _miss(rr, zz, cc, bb, floor, zs, zr, R, m + h, maxb, bpar, dummy)
    fq, cq = _miss(rr, zz, cc, bb, floor, zs, zr, R, m - h, maxb, bpar, dummy)
    if cp == code and cq == code:
        out[row, F_DZDTH] = (fp - fq) / (2.0 * h)
    elif cp == code:
        out[row, F_DZDTH] = (fp - fm) / h
    elif cq == code:
        out[row, F_DZDTH] = (fm - fq) / h
    return True


@_jit
def _write_row(rr, zz, cc, zs, zr, R, m, res, out, row):
    """out[row] from the walk ``res`` (:func:`trace`'s tuple) of the eigenray launched at ``m``
    (F_DZDTH left NaN)."""
    _st, ze, t, thr, arc, ns, nb, cd, loss, nturn, _np, cR, kink = res
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
    out[row, F_DZDTH] = math.nan


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
def search(rr, zz, cc, bb, floor, zs, zr, R, maxb, bpar, wmax, nfan, H, ztol, out):
    """Every eigenray from (0, zs) to (R, zr) with at most ``maxb`` boundary bounces. A fan of
    ``nfan`` launch angles uniform in w = tan(theta) R / H over [-wmax, wmax] (the families of
    a waveguide of depth H lie about 2 apart in w), then adaptive bisection of each fan
    interval: where its ends took different bounce sequences (to put samples next to each
    family's edge), and where the depth miss at the receiver's range is not nearly linear
    between them (a fold of the family may hide two roots); regula falsi inside each family
    where the miss changes sign. Returns the number of arrival rows written to ``out``."""
    dummy = np.empty((1, 3))
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
    th = np.empty(nfan + cusp.size + ne)
    for i in range(nfan):
        w = -wmax + 2.0 * wmax * (i + 0.5) / nfan
        th[i] = math.atan(w * H / R)
    th[nfan : nfan + cusp.size] = cusp
    th[nfan + cusp.size :] = extra[:ne]
    th = np.sort(th)
    nfan = th.size
    f = np.empty(nfan)
    cd = np.empty(nfan, np.int64)
    for i in range(nfan):
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
                # distance from zero (ends of one sign), or three where it bends by more than a
                # quarter of its change across the interval (ends of both signs: an S)
                dev = abs(fm - 0.5 * (fa + fb))
                if (fa > 0.0) == (fb > 0.0):
                    split = min(abs(fa), abs(fb), abs(fm)) < 4.0 * dev
                else:
                    split = dev > 0.25 * abs(fb - fa)
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
def follow_links(starts, ends, rr_all, zz, cc_all, bb_all, floor, zs, zr, R, maxb, bpar, theta0, slope, code, ztol):
    """Follow known eigenrays to moved end points: for each link l and each of its arrivals q
    (launch angle theta0[l, q], bounce sequence code[l, q] >= 0, depth-miss slope d z_R / d theta0
    slope[l, q]), secant iterations on the depth miss from the old launch angle in the new
    section, keeping the bounce sequence, to ``ztol``. Returns the arrival rows (L, Q, NF) (as
    :func:`search` writes them, the ray-tube width F_DZDTH the secant's last slope, or the
    given one where no step was needed) and whether each was followed (L, Q): not where its
    bounce sequence changed (a secant step that leaves it is halved up to six times first) or the
    secant did not converge in 12 steps (its row is then NaN). Each arrival costs one walk per
    secant evaluation (usually two or three)."""
    L, Q = theta0.shape
    out = np.full((L, Q, NF), np.nan)
    ok_all = np.zeros((L, Q), np.bool_)
    dummy = np.empty((1, 3))
    for l in range(L):
        o0, o1 = starts[l], ends[l]
        if o1 - o0 < 2:
            continue
        rr, cc, bb = rr_all[o0:o1], cc_all[o0:o1], bb_all[o0:o1]
        for q in range(Q):
            cd = code[l, q]
            s = slope[l, q]
            if cd < 0 or not math.isfinite(theta0[l, q]) or not (math.isfinite(s) and s != 0.0):
                continue
            a = theta0[l, q]
            res = trace(rr, zz, cc, bb, floor, zs[l], a, R[l], maxb, bpar, False, dummy)
            if res[0] != S_REACHED or res[7] != cd:
                continue
            fa = res[1] - zr[l]
            ok = abs(fa) <= ztol
            for _ in range(12):
                if ok:
                    break
                b = a - fa / s
                rb = trace(rr, zz, cc, bb, floor, zs[l], b, R[l], maxb, bpar, False, dummy)
                # a step that leaves the bounce sequence is shortened (the family may be narrower
                # than the step), up to 1/64 of it
                for _h in range(6):
                    if rb[0] == S_REACHED and rb[7] == cd:
                        break
                    b = a + 0.5 * (b - a)
                    rb = trace(rr, zz, cc, bb, floor, zs[l], b, R[l], maxb, bpar, False, dummy)
                if rb[0] != S_REACHED or rb[7] != cd:
                    break
                fb = rb[1] - zr[l]
                if fb != fa and b != a:
                    s = (fb - fa) / (b - a)
                a, fa, res = b, fb, rb
                ok = abs(fa) <= ztol
            if not ok:
                continue
            _write_row(rr, zz, cc, zs[l], zr[l], R[l], a, res, out[l], q)
            out[l, q, F_DZDTH] = s
            ok_all[l, q] = True
    return out, ok_all
