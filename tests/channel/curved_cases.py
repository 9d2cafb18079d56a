"""The curved-floor cases of tests/channel/test_curved_floors.py and tools/curved_floors.py: a
Gaussian seamount, a Gaussian ridge and a canyon on a slope given as a grid, their links, and
the comparison of aquasim_py's eigenrays with the independent tracer's (ray_ode_curved.py).

Each case is the environment aquasim_py sees (its bathymetry classes) and the true floor the
tracer integrates over (ray_ode_curved.Floor, the same formula: for the canyon, the surface the
grid samples). The sound speed: a summer profile (mixed layer, thermocline, a minimum at 300 m),
depth only, the same function for both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import ray_ode_curved as oc

from aquasim_py.channel import ssp
from aquasim_py.channel._rangedep_jit import S_REACHED, trace
from aquasim_py.channel.arrivals import Arrivals, arrivals
from aquasim_py.channel.bathymetry import FluidBottom, GriddedBathymetry, Ridge, Seamount
from aquasim_py.channel.environment import Environment
from aquasim_py.channel.fields import DepthProfile
from aquasim_py.channel.rangedep import sections

DEPTHS = np.array([0.0, 40.0, 100.0, 300.0, 1500.0])
SPEEDS = np.array([1522.0, 1518.0, 1496.0, 1490.0, 1492.0])
MAX_BOUNCES = 3
#: the acceptance's margin: eigenrays at least this far (launch angle) from their family's edge
EDGE_DEG = 1e-3


@dataclass(frozen=True)
class Case:
    name: str
    env: Environment
    truth: oc.Floor


def cases() -> list[Case]:
    """The seamount (1000 m of water, the crest at 600 m, 1 km wide, sampled every 50 m), the
    ridge (the same, 800 m wide, its crest at 60 deg) and the canyon (a 3 % slope from 600 m, a
    200 m deep trough 800 m wide down it, on a 25 m grid)."""
    prof = DepthProfile(ssp.Layered(DEPTHS, SPEEDS))
    sand = FluidBottom()
    canyon = oc.Floor(600.0, slope_y=0.03, features=((oc.RIDGE, 0.0, 0.0, math.pi / 2, -200.0, 800.0),))
    g = np.arange(-7000.0, 7000.1, 25.0)
    return [
        Case(
            "seamount",
            Environment(prof, Seamount(1000.0, 400.0, 1000.0), sand),
            oc.Floor(1000.0, features=((oc.MOUNT, 0.0, 0.0, 0.0, 400.0, 1000.0),)),
        ),
        Case(
            "ridge",
            Environment(prof, Ridge(1000.0, 400.0, 800.0, azimuth_deg=60.0), sand),
            oc.Floor(1000.0, features=((oc.RIDGE, 0.0, 0.0, math.radians(60.0), 400.0, 800.0),)),
        ),
        Case("canyon", Environment(prof, GriddedBathymetry(g, g, canyon.depth(g[:, None], g[None, :])), sand), canyon),
    ]


def links(case: Case, n: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """n links 2-10 km long across the feature (their midpoints within 1.5 km of it), each end
    at least 5 m inside the water column."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        R, a = rng.uniform(2000.0, 10000.0), rng.uniform(0.0, 2.0 * np.pi)
        c = rng.uniform(-1500.0, 1500.0, 2)
        s = np.array([c[0] - 0.5 * R * np.cos(a), c[1] - 0.5 * R * np.sin(a), 0.0])
        d = np.array([c[0] + 0.5 * R * np.cos(a), c[1] + 0.5 * R * np.sin(a), 0.0])
        s[2] = rng.uniform(5.0, float(case.truth.depth(s[0], s[1])) - 5.0)
        d[2] = rng.uniform(5.0, float(case.truth.depth(d[0], d[1])) - 5.0)
        out.append((s, d))
    return out


def floor_error(case: Case, src: np.ndarray, dst: np.ndarray) -> float:
    """The largest departure (m) of the link's section floor from the true one, sampled every
    metre (both are smooth: the sampling misses less than 1e-6 of it)."""
    sec = sections(case.env, src, dst)
    R = float(sec.R[0])
    r = np.linspace(0.0, R, int(R) + 1)
    u = (dst[:2] - src[:2]) / R
    true = case.truth.depth(src[0] + r * u[0], src[1] + r * u[1])
    return float(np.max(np.abs(sec.floor_at(0, r) - true)))


def delay_tolerance(delta_m: float, bottom_bounces: int) -> float:
    """How far a delay may move when the floor moves by at most ``delta_m``: by Fermat, to
    first order a reflection point displaced by d along the floor's normal lengthens the path by
    2 d sin(grazing angle) (the incident and the reflected legs d sin each), so at most
    2 delta / c_min per bottom bounce; plus the oracle's and our own error (1e-9 s, far more than
    either: both are ~1e-12 s)."""
    return 2.0 * delta_m / float(SPEEDS.min()) * bottom_bounces + 1e-9


def edge_distance(env: Environment, src: np.ndarray, dst: np.ndarray, launch: float, code: int) -> float:
    """How far (rad) our eigenray launched at ``launch`` is from the nearest edge of its family
    in our model: each side stepped out (1e-9 rad, doubling) until the bounces change, then
    bisected."""
    sec = sections(env, src, dst)
    rr, c, bb = sec.link(0)
    c = np.ascontiguousarray(c)
    bpar = np.array(env.bottom.params)
    dummy, none = np.empty((1, 3)), np.empty(0)

    def same(th: float) -> bool:
        r = trace(
            rr, sec.z, c, bb, sec.floor_shape, True, sec.zs[0], th, sec.R[0], MAX_BOUNCES, bpar, False, dummy, none
        )
        return r[0] == S_REACHED and r[7] == code

    best = math.inf
    for sgn in (1.0, -1.0):
        step = 1e-9
        while step < 0.1 and same(launch + sgn * step):
            step *= 2.0
        lo, hi = 0.5 * step if step > 1e-9 else 0.0, step
        while hi - lo > 1e-12:
            m = 0.5 * (lo + hi)
            lo, hi = (m, hi) if same(launch + sgn * m) else (lo, m)
        best = min(best, lo)
    return best


@dataclass
class Comparison:
    reference: list[oc.Eigenray]
    ours: Arrivals
    matched: list[tuple[oc.Eigenray, int]]  #: (reference, our row)
    missed: list[oc.Eigenray]
    #: our rows at least EDGE_DEG from their family's edge without a reference eigenray, nor one
    #: the tracer shoots near them
    extra: list[int]
    #: our rows the reference fan missed but the tracer confirms when shot from them (families
    #: narrower than the fan's spacing)
    confirmed: list[int]
    #: our rows not confirmed, within EDGE_DEG of their family's edge (the sampled floor's and
    #: the true one's eigenrays differ there)
    near_edge: list[int]
    delta_m: float
    worst_ratio: float  #: largest |delay difference| / tolerance over the matched

    @property
    def missed_far(self) -> list[oc.Eigenray]:
        """Missed eigenrays at least EDGE_DEG from their family's edge (the acceptance's)."""
        return [e for e in self.missed if e.edge >= math.radians(EDGE_DEG)]


def compare(case: Case, src: np.ndarray, dst: np.ndarray, dth: float = 1e-4) -> Comparison:
    """Our arrivals against the tracer's eigenrays (a fan of spacing ``dth`` rad): each reference
    eigenray matched to our nearest one in launch angle with its bounce sequence, within 1e-3
    rad (the floor's sampling moves them by far less); each of ours left over shot by the tracer
    from its launch angle (confirmed, or extra)."""
    ours = arrivals(case.env, src, dst, max_bounces=MAX_BOUNCES)
    ref = oc.eigenrays(oc.Link(DEPTHS, SPEEDS, case.truth, src, dst, MAX_BOUNCES), dth=dth)
    delta = floor_error(case, src, dst)
    used = np.zeros(ours.delay.size, bool)
    matched, missed, worst = [], [], 0.0
    for e in ref:
        cand = np.flatnonzero((ours.bounce_code == e.code) & ~used)
        if cand.size:
            i = int(cand[np.argmin(np.abs(ours.launch_angle[cand] - e.launch))])
            if abs(ours.launch_angle[i] - e.launch) < 1e-3:
                used[i] = True
                matched.append((e, i))
                tol = delay_tolerance(delta, int(ours.bottom_bounces[i]))
                worst = max(worst, abs(ours.delay[i] - e.delay) / tol)
                continue
        missed.append(e)
    link = oc.Link(DEPTHS, SPEEDS, case.truth, src, dst, MAX_BOUNCES)
    extra, confirmed, near = [], [], []
    for i in np.flatnonzero(~used):
        th, code = float(ours.launch_angle[i]), int(ours.bounce_code[i])
        e = oc.shoot(link, th, code)
        if e is not None and abs(e.delay - ours.delay[i]) <= delay_tolerance(delta, int(ours.bottom_bounces[i])):
            confirmed.append(int(i))
        elif edge_distance(case.env, src, dst, th, code) < math.radians(EDGE_DEG):
            near.append(int(i))
        else:
            extra.append(int(i))
    return Comparison(ref, ours, matched, missed, extra, confirmed, near, delta, worst)
