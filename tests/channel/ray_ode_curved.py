"""Independent oracle for eigenrays over curved floors: the ray equations integrated numerically
in a depth-only medium over an analytic sea floor, reflected about the floor's local normal, and
a dense launch fan that finds every eigenray of a link.

It knows nothing of circles, arcs or sections: in arc length s it integrates

    dr/ds = cos th,  dz/ds = sin th,  dth/ds = -cos th c'(z) / c(z),  dt/ds = 1 / c(z)

with the classical fourth-order Runge-Kutta method at a fixed step of 5 m (compiled with numba,
so that a fan of 1e4-1e5 rays per link is affordable), c(z) piecewise linear between the
profile's depth nodes (the last gradient continuing below). Where the right-hand side is not
smooth (c' jumps at a depth node) or the ray meets a boundary (the surface, the floor, the
receiver's range) the step is cut at the event: its arc length is found by regula falsi
(Illinois) on the event function along partial RK4 steps from the step's start (to 1e-12 m of
depth or range), the state there integrated exactly that far, and the step resumes.
The floor is the true surface along the link's vertical plane, depth(x0 + r ux, y0 + r uy) from
its own formula (a sum of Gaussian features over a plane, :class:`Floor`), not its samples; a
ray meeting it is reflected about its normal there: th -> 2 atan(depth'(r)) - th. The surface
reflects th -> -th.

Accuracy: within a layer the ray is a circle of radius c / |g| (km or more), and RK4's local
error at the step h = 5 m is of order h^5 / (120 rho^4), far below 1e-12 m per step; the events
are located to 1e-12 m (1e-15 s). It checks itself against the exact layered solver over a flat
floor in tests/channel/test_curved_floors.py. What it cannot see: a ray that dips below the
floor and back within one step (a graze shallower than h^2 k / 8, k the floor's curvature
relative to the ray's: ~1e-3 m over a 1 km wide seamount); such rays lie within ~1e-6 rad of
their family's edge, which the acceptance leaves out (1e-3 degrees).

:func:`eigenrays` shoots a dense fan (spacing ``dth``), finds the edges between bounce sequences
by bisection (to 1e-13 rad), and every eigenray of each sequence: each sign change of the depth
miss at the receiver's range between the fan's samples and the edges, and, where the miss has a
local minimum of |miss| between samples whose sign it does not change (a fold), a golden-section
search of that minimum; each root is refined by bisection to 1e-14 rad and traced.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from numba import njit

_jit = njit(cache=True)

#: feature kinds of a Floor: an isotropic Gaussian (a seamount) and a Gaussian along a line (a
#: ridge, or with a negative height a trough: a canyon)
MOUNT, RIDGE = 0, 1
_STEP_M = 5.0
_EVENT_TOL = 1e-12
LOST, REACHED = 0, 1


@dataclass(frozen=True)
class Floor:
    """depth(x, y) = base + slope_x x + slope_y y - sum of features, each height h exp(-d^2 / (2
    w^2)) with d the distance from its centre (MOUNT) or from its crest line through the centre
    at ``azimuth`` rad from x (RIDGE)."""

    base: float
    slope_x: float = 0.0
    slope_y: float = 0.0
    #: rows (kind, x, y, azimuth rad, height m, width m)
    features: tuple[tuple[float, float, float, float, float, float], ...] = ()

    def array(self) -> np.ndarray:
        return np.array(self.features, float).reshape(-1, 6)

    def depth(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        out = np.empty(x.shape)
        fa = self.array()
        for i in np.ndindex(x.shape):
            out[i] = _depth_xy(self.base, self.slope_x, self.slope_y, fa, x[i], y[i])[0]
        return out


@_jit
def _depth_xy(base, sx, sy, fa, x, y):
    """(depth, d depth/dx, d depth/dy) of the floor at (x, y)."""
    d = base + sx * x + sy * y
    gx, gy = sx, sy
    for i in range(fa.shape[0]):
        kind, cx, cy, az, h, w = fa[i, 0], fa[i, 1], fa[i, 2], fa[i, 3], fa[i, 4], fa[i, 5]
        if kind == MOUNT:
            dx, dy = x - cx, y - cy
            e = h * math.exp(-0.5 * (dx * dx + dy * dy) / (w * w))
            d -= e
            gx += e * dx / (w * w)
            gy += e * dy / (w * w)
        else:
            nx, ny = -math.sin(az), math.cos(az)
            q = (x - cx) * nx + (y - cy) * ny
            e = h * math.exp(-0.5 * q * q / (w * w))
            d -= e
            gx += e * q / (w * w) * nx
            gy += e * q / (w * w) * ny
    return d, gx, gy


@_jit
def _floor(line, fl, r):
    """(depth, d depth / d r) along the link's line (x0, y0, ux, uy) at range r."""
    x0, y0, ux, uy = line[0], line[1], line[2], line[3]
    d, gx, gy = _depth_xy(fl[0], fl[1], fl[2], fl[3:].reshape(-1, 6), x0 + r * ux, y0 + r * uy)
    return d, gx * ux + gy * uy


@_jit
def _speed(zn, cn, z):
    """(c, dc/dz) of the piecewise-linear profile at z, and the layer index."""
    k = 0
    K = zn.size
    while k < K - 2 and zn[k + 1] <= z:
        k += 1
    g = (cn[k + 1] - cn[k]) / (zn[k + 1] - zn[k])
    return cn[k] + g * (z - zn[k]), g, k


@_jit
def _rhs(zn, cn, k, y):
    """Ray equations with the gradient of layer k (held through a step: the steps are cut at
    the layer's edges)."""
    g = (cn[k + 1] - cn[k]) / (zn[k + 1] - zn[k])
    c = cn[k] + g * (y[1] - zn[k])
    ct, st = math.cos(y[2]), math.sin(y[2])
    return ct, st, -ct * g / c, 1.0 / c


@_jit
def _rk4(zn, cn, k, y, h):
    k1 = _rhs(zn, cn, k, y)
    y2 = (y[0] + 0.5 * h * k1[0], y[1] + 0.5 * h * k1[1], y[2] + 0.5 * h * k1[2], y[3] + 0.5 * h * k1[3])
    k2 = _rhs(zn, cn, k, y2)
    y3 = (y[0] + 0.5 * h * k2[0], y[1] + 0.5 * h * k2[1], y[2] + 0.5 * h * k2[2], y[3] + 0.5 * h * k2[3])
    k3 = _rhs(zn, cn, k, y3)
    y4 = (y[0] + h * k3[0], y[1] + h * k3[1], y[2] + h * k3[2], y[3] + h * k3[3])
    k4 = _rhs(zn, cn, k, y4)
    return (
        y[0] + h / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]),
        y[1] + h / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]),
        y[2] + h / 6.0 * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2]),
        y[3] + h / 6.0 * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3]),
    )


@_jit
def _events(zn, k, line, fl, R, y):
    """Signed event functions at state y, each crossing zero upwards where the event happens:
    above the layer's top, below its bottom, into the floor, past the receiver's range."""
    fz, _ = _floor(line, fl, y[0])
    return zn[k] - y[1], y[1] - zn[k + 1], y[1] - fz, y[0] - R


@_jit
def trace(zn, cn, line, fl, z0, th0, R, maxb):
    """One ray from (0, z0) at launch angle th0 (positive down) to r = R. Returns (status, z at
    R, time, arrival angle, surface bounces, bottom bounces, code: the bounce sequence base 3,
    1 surface, 2 bottom, first bounce least significant)."""
    y = (0.0, z0, th0, 0.0)
    _c, _g, k = _speed(zn, cn, z0)
    if math.sin(th0) < 0.0 and z0 == zn[k] and k > 0:
        k -= 1  # on a node heading up: the layer above
    ns = nb = code = 0
    p3 = 1
    K = zn.size
    for _ in range(10000000):
        yn = _rk4(zn, cn, k, y, _STEP_M)
        ev = _events(zn, k, line, fl, R, yn)
        hit = -1
        for i in range(4):
            if ev[i] > 0.0:
                hit = i
                break
        if hit < 0:
            y = yn
            if y[0] < -1.0:  # travelling back past the source
                return LOST, y[1], y[3], y[2], ns, nb, code
            continue
        # the first event along the step: regula falsi (Illinois) on each event that fired at
        # the step's end, along partial steps from its start; the earliest one counts
        best_h = _STEP_M
        first = hit
        y0 = y
        for i in range(4):
            if not ev[i] > 0.0:
                continue
            a, fa = 0.0, _events(zn, k, line, fl, R, y0)[i]
            b, fb = _STEP_M, ev[i]
            if b >= best_h and i != hit:
                b, fb = best_h, _events(zn, k, line, fl, R, _rk4(zn, cn, k, y0, best_h))[i]
                if not fb > 0.0:
                    continue
            side = 0
            for _it in range(200):
                m = (a * fb - b * fa) / (fb - fa)
                if not (a < m < b):
                    m = 0.5 * (a + b)
                fm = _events(zn, k, line, fl, R, _rk4(zn, cn, k, y0, m))[i]
                if fm > 0.0:
                    b, fb = m, fm
                    if side == 1:
                        fa *= 0.5
                    side = 1
                else:
                    a, fa = m, fm
                    if side == -1:
                        fb *= 0.5
                    side = -1
                if fb <= _EVENT_TOL or b - a <= 1e-13:
                    break
            if b < best_h or i == hit:
                best_h = b
                first = i
        y = _rk4(zn, cn, k, y0, best_h)
        r, z, th, t = y
        if first == 3:
            # the receiver's range, passed by at most 1e-12 m: step back onto it exactly
            over = (r - R) / math.cos(th)
            return REACHED, z - over * math.sin(th), t - over / _speed(zn, cn, z)[0], th, ns, nb, code
        if first == 0:
            if k == 0:
                th = -th
                z = 0.0
                ns += 1
                code += p3
                p3 *= 3
            else:
                k -= 1
        elif first == 1:
            if k + 2 >= K:
                return LOST, z, t, th, ns, nb, code
            k += 1
        else:
            fz, slope = _floor(line, fl, r)
            th = 2.0 * math.atan(slope) - th
            z = min(z, fz)
            nb += 1
            code += 2 * p3
            p3 *= 3
        if ns + nb > maxb:
            return LOST, z, t, th, ns, nb, code
        y = (r, z, th, t)
    return LOST, y[1], y[3], y[2], ns, nb, code


@_jit
def _fan(zn, cn, line, fl, z0, zr, R, maxb, th):
    n = th.size
    f = np.empty(n)
    cd = np.empty(n, np.int64)
    for i in range(n):
        st, ze, _t, _a, _ns, _nb, c = trace(zn, cn, line, fl, z0, th[i], R, maxb)
        if st == REACHED:
            f[i] = ze - zr
            cd[i] = c
        else:
            f[i] = math.nan
            cd[i] = -1
    return f, cd


@dataclass(frozen=True)
class Link:
    """A link's medium for the oracle: the profile (depth nodes, speeds, the last gradient
    continuing below), the floor, and the link's line."""

    depths: np.ndarray
    speeds: np.ndarray
    floor: Floor
    src: np.ndarray
    dst: np.ndarray
    max_bounces: int = 3

    def args(self) -> tuple:
        s, d = np.asarray(self.src, float), np.asarray(self.dst, float)
        R = float(np.hypot(d[0] - s[0], d[1] - s[1]))
        ux, uy = (d[0] - s[0]) / R, (d[1] - s[1]) / R
        zn = np.concatenate([np.asarray(self.depths, float), [1e5]])
        c = np.asarray(self.speeds, float)
        g = (c[-1] - c[-2]) / (zn[-2] - zn[-3])
        cn = np.concatenate([c, [c[-1] + g * (1e5 - zn[-2])]])
        line = np.array([s[0], s[1], ux, uy])
        fl = np.concatenate([[self.floor.base, self.floor.slope_x, self.floor.slope_y], self.floor.array().ravel()])
        return zn, cn, line, fl, float(s[2]), float(d[2]), R, int(self.max_bounces)


@dataclass(frozen=True)
class Eigenray:
    launch: float  #: rad
    delay: float  #: s
    code: int
    edge: float  #: rad from the launch angle to the nearest edge of its bounce sequence
    z_miss: float  #: m


def eigenrays(link: Link, dth: float = 1e-4, span: float = 1.2) -> list[Eigenray]:
    """Every eigenray of ``link`` with launch angles in (-span, span) rad: see the module
    docstring. ``dth``: the fan's spacing (rad)."""
    zn, cn, line, fl, z0, zr, R, maxb = link.args()
    th = np.arange(-span, span + 0.5 * dth, dth)
    f, cd = _fan(zn, cn, line, fl, z0, zr, R, maxb, th)

    def miss(a: float) -> tuple[float, int]:
        st, ze, _t, _a, _ns, _nb, c = trace(zn, cn, line, fl, z0, a, R, maxb)
        return (ze - zr, int(c)) if st == REACHED else (math.nan, -1)

    # the samples of each bounce sequence, with its edges located by bisection on the code
    pts: list[tuple[float, float, int]] = []  # (angle, miss, code), sorted by angle
    edges: list[float] = []
    for i in range(th.size):
        if i > 0 and cd[i] != cd[i - 1]:
            a, b = th[i - 1], th[i]
            fa_, fb_ = (f[i - 1], int(cd[i - 1])), (f[i], int(cd[i]))
            while b - a > 1e-13:
                m = 0.5 * (a + b)
                fm = miss(m)
                if fm[1] == fa_[1]:
                    a, fa_ = m, fm
                else:
                    b, fb_ = m, fm
            if fa_[1] >= 0:
                pts.append((a, fa_[0], fa_[1]))
            edges.append(0.5 * (a + b))
            if fb_[1] >= 0:
                pts.append((b, fb_[0], fb_[1]))
        if cd[i] >= 0:
            pts.append((float(th[i]), float(f[i]), int(cd[i])))
    pts.sort()
    edges_a = np.array(sorted(edges)) if edges else np.array([-span - 1.0, span + 1.0])

    def refine(a: float, fa: float, b: float, code: int) -> float:
        for _ in range(200):
            if b - a <= 1e-14:
                break
            m = 0.5 * (a + b)
            fm, cm = miss(m)
            if cm != code:
                return math.nan
            if (fm > 0.0) == (fa > 0.0):
                a, fa = m, fm
            else:
                b = m
        return 0.5 * (a + b)

    roots: list[float] = []
    codes: list[int] = []
    for (a, fa, ca), (b, fb, cb) in itertools.pairwise(pts):
        if ca != cb:
            continue
        if fa == 0.0 or (fa > 0.0) != (fb > 0.0):
            x = a if fa == 0.0 else refine(a, fa, b, ca)
            if math.isfinite(x):
                roots.append(x)
                codes.append(ca)
    # folds: a local minimum of |miss| between three samples of one sign in one sequence
    for (a, fa, ca), (_b, fb, cb), (c, fc, cc) in zip(pts[:-2], pts[1:-1], pts[2:]):
        if not (ca == cb == cc) or (fa > 0.0) != (fb > 0.0) or (fb > 0.0) != (fc > 0.0):
            continue
        if not (abs(fb) <= abs(fa) and abs(fb) <= abs(fc)):
            continue
        lo, hi = a, c
        g = 0.5 * (math.sqrt(5.0) - 1.0)
        x1, x2 = hi - g * (hi - lo), lo + g * (hi - lo)
        f1, f2 = miss(x1), miss(x2)
        for _ in range(80):
            if f1[1] != ca or f2[1] != ca or hi - lo < 1e-14:
                break
            if abs(f1[0]) < abs(f2[0]):
                hi, x2, f2 = x2, x1, f1
                x1 = hi - g * (hi - lo)
                f1 = miss(x1)
            else:
                lo, x1, f1 = x1, x2, f2
                x2 = lo + g * (hi - lo)
                f2 = miss(x2)
            if f1[1] == ca and (f1[0] > 0.0) != (fb > 0.0):
                x0 = refine(a, fa, x1, ca)
                x3 = refine(x1, f1[0], c, ca)
                for x in (x0, x3):
                    if math.isfinite(x):
                        roots.append(x)
                        codes.append(ca)
                break
    out = []
    for x, code in zip(roots, codes):
        st, ze, t, tha, _ns, _nb, c = trace(zn, cn, line, fl, z0, x, R, maxb)
        if st != REACHED or c != code:
            continue
        c_r = _speed(zn, cn, zr)[0]
        delay = t + (zr - ze) * math.sin(tha) / c_r
        edge = float(np.min(np.abs(edges_a - x)))
        out.append(Eigenray(x, delay, code, edge, ze - zr))
    out.sort(key=lambda e: e.delay)
    return out


def shoot(link: Link, guess: float, code: int, window: float = 1e-4) -> Eigenray | None:
    """The eigenray of bounce sequence ``code`` nearest launch angle ``guess``: a ray of that
    sequence sought within ``window`` rad of the guess (a narrow family may lie a little off it
    on this floor), the depth miss bracketed by stepping out from there (1e-9 rad, doubling, rays
    of other sequences not used), then bisection to 1e-14 rad; None where none is found."""
    zn, cn, line, fl, z0, zr, R, maxb = link.args()

    def miss(a: float) -> float:
        st, ze, _t, _a, _ns, _nb, c = trace(zn, cn, line, fl, z0, a, R, maxb)
        return ze - zr if st == REACHED and c == code else math.nan

    start, f0 = guess, miss(guess)
    k = 1
    while not math.isfinite(f0) and k * 1e-7 <= window:
        for x in (guess + k * 1e-7, guess - k * 1e-7):
            f0 = miss(x)
            if math.isfinite(f0):
                start = x
                break
        k = k + 1 if k < 10 else int(k * 1.2)
    step = 1e-9
    while step < window and math.isfinite(f0):
        for sgn in (1.0, -1.0):
            x = start + sgn * step
            f1 = miss(x)
            if math.isfinite(f1) and (f1 > 0.0) != (f0 > 0.0):
                lo, hi, flo = (start, x, f0) if start < x else (x, start, f1)
                while hi - lo > 1e-14:
                    m = 0.5 * (lo + hi)
                    fm = miss(m)
                    if not math.isfinite(fm):
                        return None
                    if (fm > 0.0) == (flo > 0.0):
                        lo, flo = m, fm
                    else:
                        hi = m
                a = 0.5 * (lo + hi)
                _st, ze, t, tha, _ns, _nb, _c = trace(zn, cn, line, fl, z0, a, R, maxb)
                delay = t + (zr - ze) * math.sin(tha) / _speed(zn, cn, zr)[0]
                return Eigenray(a, delay, code, math.nan, ze - zr)
        step *= 2.0
    return None
