"""Independent oracle for range-dependent rays: numerical integration of the ray equations in a
(range, depth) section with c(r, z), reflecting off the surface and a sloping floor, plus shooting.

It knows nothing of circles: in arc length s it integrates

    dr/ds = cos th,  dz/ds = sin th,  dth/ds = (sin th c_r - cos th c_z) / c,  dt/ds = 1 / c

with ``scipy.integrate.solve_ivp`` (DOP853, rtol = atol = 1e-12, as tests/channel/ray_ode.py).
The medium is the same function as the solver's (linear on each cell of the section's grid: a
rectangle whose four speeds are coplanar, else its two triangles cut along the diagonal whose end
speeds differ least, (r_j, z_k) - (r_j+1, z_k+1) on a tie), evaluated here from its own
definition: the plane through the three corners of the triangle that holds the point. Its gradient jumps across cell edges, so the
integration stops at every edge (a terminal event) and restarts in the next cell; at the surface
and the floor the direction is reflected (th -> -th; the mirror image about the floor segment).

Error bounds per ray, as in ray_ode.py (``_ErrorSums``): local errors <= 2 (atol + rtol |y|) per
accepted step, summed over the steps of every segment, give ``time_bound`` (s); shooting
re-aims only across the ray, which leaves the time unchanged to first order (Fermat).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from ray_ode import ATOL, RTOL, _ErrorSums
from scipy.integrate import solve_ivp
from scipy.optimize import brentq


@dataclass(frozen=True)
class Medium:
    r: np.ndarray  #: (J,) column ranges
    z: np.ndarray  #: (K,) depth nodes
    c: np.ndarray  #: (J, K)
    floor: np.ndarray  #: (J,) floor depth at the columns

    def anti(self, j: int, k: int) -> bool:
        c = self.c
        return abs(c[j + 1, k] - c[j, k + 1]) < abs(c[j, k] - c[j + 1, k + 1])

    def cell(self, r: float, z: float) -> tuple[int, int, int]:
        """(j, k, part): part 0 the whole planar rectangle; 1 / 2 above / below the diagonal
        (r_j, z_k) - (r_j+1, z_k+1); 3 / 4 above-left / below-right of the other diagonal."""
        j = min(max(int(np.searchsorted(self.r, r, side="right")) - 1, 0), self.r.size - 2)
        k = min(max(int(np.searchsorted(self.z, z, side="right")) - 1, 0), self.z.size - 2)
        c = self.c
        if c[j, k] - c[j + 1, k] - c[j, k + 1] + c[j + 1, k + 1] == 0.0:
            return j, k, 0
        u = (r - self.r[j]) / (self.r[j + 1] - self.r[j])
        v = (z - self.z[k]) / (self.z[k + 1] - self.z[k])
        if self.anti(j, k):
            return j, k, 3 if u + v <= 1.0 else 4
        return j, k, 1 if v <= u else 2

    def plane(self, j: int, k: int, part: int) -> tuple[float, float, float]:
        """(c at (r_j, z_k), dc/dr, dc/dz) of a cell, from three of its corners."""
        c = self.c
        dr, dz = self.r[j + 1] - self.r[j], self.z[k + 1] - self.z[k]
        corners = {
            0: ((0, 0), (1, 0), (0, 1)),
            1: ((0, 0), (1, 0), (1, 1)),
            2: ((0, 0), (0, 1), (1, 1)),
            3: ((0, 0), (1, 0), (0, 1)),
            4: ((1, 0), (0, 1), (1, 1)),
        }[part]
        A = np.array([[1.0, u, v] for u, v in corners])
        b = np.array([c[j + u, k + v] for u, v in corners])
        c0, cu, cv = np.linalg.solve(A, b)
        return float(c0), float(cu / dr), float(cv / dz)


@dataclass(frozen=True)
class OdeRay:
    time: float
    z_end: float
    arrival_angle: float
    surface: int
    bottom: int
    code: int
    reached: bool
    time_bound: float


def trace(m: Medium, z0: float, th0: float, max_bounces: int = 10, R: float | None = None) -> OdeRay:
    """Integrate one ray from (0, z0) at launch angle th0 to r = R (default m.r[-1]; the
    section's columns span [m.r[0] <= 0, m.r[-1] >= R])."""
    R = float(m.r[-1]) if R is None else float(R)
    y = np.array([0.0, float(z0), float(th0), 0.0])
    s = 0.0
    ns = nb = code = 0
    p3 = 1
    err = _ErrorSums()
    cmin = float(np.min(m.c))
    for _ in range(100000):
        # the cell ahead: nudge along the ray
        h = 1e-9 * max(1.0, R)
        j, k, part = m.cell(y[0] + h * math.cos(y[2]), y[1] + h * math.sin(y[2]))
        c0, gr, gz = m.plane(j, k, part)
        rj, zk = m.r[j], m.z[k]

        def cfun(r: float, z: float, c0=c0, gr=gr, gz=gz, rj=rj, zk=zk) -> float:
            return c0 + gr * (r - rj) + gz * (z - zk)

        def rhs(_s, yy, cfun=cfun, gr=gr, gz=gz):
            cc = cfun(yy[0], yy[1])
            ct, st = math.cos(yy[2]), math.sin(yy[2])
            return [ct, st, (st * gr - ct * gz) / cc, 1.0 / cc]

        r1, z1, z2 = m.r[j + 1], m.z[k], m.z[k + 1]
        fa, fb = m.floor[j], m.floor[j + 1]
        dr = r1 - rj

        def ev_left(_s, yy, rj=rj):
            return yy[0] - rj

        def ev_right(_s, yy, r1=r1):
            return yy[0] - r1

        def ev_top(_s, yy, z1=z1):
            return yy[1] - z1

        def ev_bot(_s, yy, z2=z2):
            return yy[1] - z2

        def ev_diag(_s, yy, rj=rj, dr=dr, z1=z1, dz=z2 - z1, anti=part >= 3):
            u, v = (yy[0] - rj) / dr, (yy[1] - z1) / dz
            return u + v - 1.0 if anti else v - u

        def ev_floor(_s, yy, rj=rj, dr=dr, fa=fa, fb=fb):
            return yy[1] - (fa + (fb - fa) * (yy[0] - rj) / dr)

        def ev_target(_s, yy, R=R):
            return yy[0] - R

        # the target first: where it coincides with a column line, reaching it wins the tie
        events = [ev_target, ev_left, ev_right, ev_top, ev_bot, ev_floor] + ([ev_diag] if part else [])
        ev_target.direction = 1.0
        for e in events:
            e.terminal = True
        # leave the cell: crossing each line outwards (the floor downwards)
        ev_left.direction, ev_right.direction = -1.0, 1.0
        ev_top.direction, ev_bot.direction, ev_floor.direction = -1.0, 1.0, 1.0
        if part:
            ev_diag.direction = 1.0 if part in (1, 3) else -1.0
        # a ray that dips across an edge and back inside one step fires no crossing event: locate
        # its turning points (parallel to the horizontal edges, or to the diagonal) and, where one
        # lies outside the cell, integrate the segment again with shorter steps
        ang = math.atan2(-(z2 - z1) if part >= 3 else z2 - z1, dr)

        def turn_h(_s, yy):
            return math.sin(yy[2])

        def turn_d(_s, yy, ang=ang):
            return math.sin(yy[2] - ang)

        turns = [turn_h, turn_d] if part else [turn_h]
        n_stop = len(events)
        max_step = math.inf
        while True:
            sol = solve_ivp(
                rhs, (s, s + 1e7), y, method="DOP853", rtol=RTOL, atol=ATOL, events=events + turns, max_step=max_step
            )
            bad = False
            for _te, ye in zip(sol.t_events[n_stop:], sol.y_events[n_stop:]):
                for yy in ye:
                    u = (yy[0] - rj) / dr
                    v = (yy[1] - z1) / (z2 - z1)
                    tol = 1e-9
                    out = (
                        v < -tol
                        or v > 1 + tol
                        or (part == 1 and v > u + tol)
                        or (part == 2 and v < u - tol)
                        or (part == 3 and u + v > 1 + tol)
                        or (part == 4 and u + v < 1 - tol)
                    )
                    bad |= bool(out)
            if not bad:
                break
            max_step = min(max_step, float(sol.t[-1] - s)) / 8.0
            if max_step < 1e-6:
                raise RuntimeError("trace: cannot resolve an edge crossing at a turning point")
        sol.t_events = sol.t_events[:n_stop]
        sol.y_events = sol.y_events[:n_stop]
        fired = [(te[0], i) for i, te in enumerate(sol.t_events) if te.size]
        if not fired:
            return OdeRay(math.nan, math.nan, math.nan, ns, nb, code, False, math.inf)
        s_ev, i = min(fired)
        y = sol.y_events[i][0].copy()
        err.add(np.append(sol.t, s_ev), np.column_stack([sol.y, y]), lambda _z: cmin)
        s = s_ev
        name = events[i].__name__
        if name == "ev_target":
            return OdeRay(y[3], y[1], y[2], ns, nb, code, True, err.bounds(s)["time_bound"])
        if name == "ev_right" and j + 1 == m.r.size - 1:
            return OdeRay(math.nan, y[1], y[2], ns, nb, code, False, math.inf)
        if name == "ev_left" and j == 0:
            return OdeRay(math.nan, y[1], y[2], ns, nb, code, False, math.inf)
        if name == "ev_top" and k == 0:
            y[1] = 0.0
            y[2] = -y[2]
            ns += 1
            code += p3
            p3 *= 3
        elif name == "ev_floor":
            slope = math.atan2(fb - fa, dr)
            y[2] = 2.0 * slope - y[2]
            nb += 1
            code += 2 * p3
            p3 *= 3
        elif name == "ev_bot" and k + 1 == m.z.size - 1:
            return OdeRay(math.nan, y[1], y[2], ns, nb, code, False, math.inf)
        if ns + nb > max_bounces:
            return OdeRay(math.nan, y[1], y[2], ns, nb, code, False, math.inf)
    raise RuntimeError("trace: too many cells")


def shoot(
    m: Medium, z0: float, zr: float, th_guess: float, code: int, max_bounces: int = 10, R: float | None = None
) -> tuple[OdeRay, float]:
    """The eigenray of bounce sequence ``code`` nearest launch angle ``th_guess``: bracket the
    depth miss by stepping out from the guess (rays of other sequences are not used), then
    brentq to machine precision. Returns (ray, launch angle)."""

    def miss(th: float) -> float:
        ray = trace(m, z0, th, max_bounces, R)
        if not ray.reached or ray.code != code:
            return math.nan
        return ray.z_end - zr

    f0 = miss(th_guess)
    if f0 == 0.0:
        return trace(m, z0, th_guess, max_bounces, R), th_guess
    step = 1e-7
    for _ in range(40):
        for sgn in (1.0, -1.0):
            th = th_guess + sgn * step
            f1 = miss(th)
            if math.isfinite(f1) and math.isfinite(f0) and (f1 > 0.0) != (f0 > 0.0):
                lo, hi = sorted((th_guess, th))
                t = brentq(miss, lo, hi, xtol=1e-16, rtol=8.9e-16, maxiter=200)
                return trace(m, z0, t, max_bounces, R), t
        step *= 2.0
    raise RuntimeError("shoot: no bracket")
