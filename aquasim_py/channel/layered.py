"""First-arrival eigenrays through a stack of isogradient layers (piecewise-linear c(z)).

Within a layer c = c_k + g_k (z - z_k) a ray is an arc of a circle (a straight line when
g_k = 0), so for a Snell invariant p = cos(theta) / c the horizontal range, travel time and
arc length across any part of a layer are closed form (Ramezani et al., eqs 4-7, 13, 19,
rewritten without the 1/g factor so that g -> 0 has no cancellation error).

For a pair of depths z_a <= z_b (the shallower point is called A) three ray families join
them without leaving the water and with at most one turning point:

* D, direct: depth changes monotonically from A to B, 0 <= p <= 1 / max c on [z_a, z_b];
* L, lower turn: down past B to the turning depth c(z_t) = 1/p, then back up to B;
* U, upper turn: up from A to the turning depth above it, then down past A to B.

The eigenray invariant solves X_family(p) = horizontal distance. The solver samples each
family on a grid of the grazing angle phi (p = p_max cos phi, which makes the grazing
singularities smooth), brackets every sign change and refines it with a safeguarded
Newton iteration (analytic d X / d p, bisection whenever a step leaves the bracket) to
~1e-13 relative range; the time is then corrected to first order for the residual
(t = p X + tau(p) is stationary in p at an eigenray). The samples and the iterations run
in a compiled kernel (numba, ``_layered_jit``: one loop over the layers a ray crosses per
pair and sample, the same doubles as the numpy ``family``); the rest works on all pairs
of a block at once.
Several eigenrays (caustics) give several roots: the earliest arrival is kept. Rays whose
turning point would lie above the surface or below the bottom are not direct paths
(eqs 21-22); the boundary-reflected arrivals come from the same solver applied to the
profile mirrored about the boundary, between the source and the image of the receiver.

Arrivals with two or more turning points (rays cycling in a sound channel) are not searched:
in a duct the ray with fewer cycles spends more time in fast water and arrives first, and at
network ranges (a few km) multi-turn rays exist only for pairs close to a channel axis.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .layer_stack import FAM_D, FAM_L, FAM_U, Geo, Stack, cos_sin, family, geometry, inv_p, log1p_ratio, stack
from .rays import Eigenray, PathKind
from .ssp import Layered

__all__ = [
    "REASON_BOTTOM",
    "REASON_OUTSIDE",
    "REASON_SHADOW",
    "REASON_SURFACE",
    "combine_arrivals",
    "eigenray",
    "reflected_eigenray",
    "straight_line_time",
    "travel_time",
    "travel_time_gradient",
    "why_no_path",
]

Reflections = Literal["none", "fallback", "all"]

REASON_SHADOW = "shadow zone: no direct eigenray"
REASON_SURFACE = "ray would leave the water at the surface"
REASON_BOTTOM = "ray would leave the water at the bottom"
REASON_OUTSIDE = "point outside the water column"

_GRID = 9  # phi samples per turning family (brackets the roots; caustics need >1 sample)
_SAME_DEPTH_M = 1e-9
# a block of pairs: (pairs, samples, layers) = 2^21 elements, about 5 800 pairs at 10 layers
# (the numpy work is on (pairs, samples) and (pairs, layers) arrays; 2 to 8x larger blocks
# were no faster)
_CHUNK_ELEMS = 1 << 21
_RTOL = 1e-13  # relative tolerance on horizontal range
_MAXIT = 80


# ----------------------------------------------------------------------------------------
# root finding


def _kernels():
    """The compiled family evaluations (numba: imported on the first solve, see _layered_jit)."""
    from . import _layered_jit

    return _layered_jit


def _range(st: Stack, geo: Geo, fam: int, phi: NDArray[np.float64], deriv: bool = False):
    """Compiled X(phi) (m, NaN where the family has no ray) at phi (pairs, samples), and with
    ``deriv`` also d X / d phi: the same doubles as ``family(..., deriv=deriv)[:2]``."""
    x, dx = _kernels().family_range(st.arrays, geo.arrays(), fam, phi, deriv)
    return (x, dx) if deriv else x


def _refine(st: Stack, geo: Geo, fam: int, target, lo, hi, hlo, hhi, guess=None):
    """Safeguarded Newton iteration on h(phi) = X(phi) - target inside brackets [lo, hi]
    with h(lo) h(hi) <= 0 (bisection whenever a step leaves the bracket or stalls), each
    bracket on its own (compiled: _layered_jit.refine), from ``guess`` or the regula falsi
    point; returns (phi, |h|) at the best point seen."""
    if guess is None:
        with np.errstate(divide="ignore", invalid="ignore"):
            guess = lo - hlo * (hi - lo) / (hhi - hlo)
    return _kernels().refine(st.arrays, geo.arrays(), fam, target, lo, hi, hlo, hhi, guess, _RTOL, _MAXIT)


def _pick_brackets(h: NDArray[np.float64]) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """(row, sample) of the sign changes of h (pairs, samples) worth refining: those where the
    range grows with phi, or every one in a row that has none of that kind.

    Along a family t = p X + tau(p) with d tau / d p = -X(p), so the eigenrays are the
    stationary points of t in p; the roots alternate between minima of t (range growing with
    phi) and maxima, and a maximum is always later than a neighbouring minimum: the earliest
    eigenray is among the minima whenever there is one."""
    h0, h1 = h[:, :-1], h[:, 1:]
    fin = np.isfinite(h0) & np.isfinite(h1)
    cross = fin & (h0 * h1 <= 0.0) & ~((h0 == 0.0) & (h1 == 0.0))
    up = cross & (h0 <= 0.0) & (h1 >= 0.0)
    use = np.where(up.any(axis=1, keepdims=True), up, cross)
    rows, cols = np.nonzero(use)
    return rows, cols


@dataclass
class _Arrivals:
    """Direct eigenrays in (A -> B) orientation, one per pair; ok False where none."""

    time: NDArray[np.float64]
    length: NDArray[np.float64]
    ang_a: NDArray[np.float64]
    ang_b: NDArray[np.float64]
    turn: NDArray[np.float64]
    ok: NDArray[np.bool_]

    @classmethod
    def empty(cls, n: int) -> _Arrivals:
        nan = np.full(n, np.nan)
        return cls(np.full(n, np.inf), nan.copy(), nan.copy(), nan.copy(), nan.copy(), np.zeros(n, bool))


def _angles(inv, c, w_sign):
    s, w = cos_sin(inv, c)
    return w_sign * np.arctan2(w, s)


def _finish(st, geo, fam, phi, target, idx, best: _Arrivals, resid) -> None:
    """Evaluate candidates at their converged invariants and keep the earliest per pair."""
    accept = resid <= 1e-9 * np.maximum(target, 1.0)
    if not np.any(accept):
        return
    phi, idx, target = phi[accept], idx[accept], target[accept]
    g = geo.take(idx)
    x, t, arc, turn = family(st, g, fam, phi, full=True)
    p = g.pmax * np.cos(phi)
    # t = p X + tau(p) is stationary at the eigenray: correct to first order in the residual
    t = t + p * (target - x)
    sa, sb = {FAM_D: (1.0, 1.0), FAM_L: (1.0, -1.0), FAM_U: (-1.0, 1.0)}[fam]
    # several candidates may share a pair: sort so the earliest is written last
    order = np.argsort(-t, kind="stable")
    idx, t, arc, turn, phi = idx[order], t[order], arc[order], turn[order], phi[order]
    ca, cb, pm = g.ca[order], g.cb[order], g.pmax[order]
    better = t < best.time[idx]
    idx, t, arc, turn, phi, ca, cb, pm = (v[better] for v in (idx, t, arc, turn, phi, ca, cb, pm))
    inv = inv_p(pm, phi)
    best.time[idx] = t
    best.length[idx] = arc
    best.turn[idx] = turn
    best.ang_a[idx] = _angles(inv, ca, sa)
    best.ang_b[idx] = _angles(inv, cb, sb)
    best.ok[idx] = True


_CUSP_JUMP = 1.05  # gradient ratio across a breakpoint that gets the extra samples
_CUSP_MAX = 12  # at most this many breakpoints per family and pair (evenly spread)


def _cusp_samples(st: Stack, geo: Geo, fam: int, ext) -> NDArray[np.float64] | None:
    """Extra samples where a turning family folds back (a triplication, several eigenrays).

    When the turning point crosses a breakpoint into a layer of steeper gradient (|g_new| >
    |g_old|), the range gains the term -beta sin(th_j), beta = 2 (1/|g_old| - 1/|g_new|) / p,
    with sin(th_j) ~ sqrt(2 tan(phi_j) u), u = phi - phi_j: a dip right after phi_j that a
    uniform grid can step over. Sampling phi_j and the dip's bottom, u* = beta^2 tan(phi_j) /
    (2 S'^2) (S' the range slope just before phi_j), brackets both of its eigenrays."""
    g = st.g
    if fam == FAM_L:  # breakpoint j between layers j-1 (above, old) and j (below, new)
        j = np.flatnonzero((g[:-1] > 0.0) & (g[1:] > _CUSP_JUMP * g[:-1])) + 1
        g_old, g_new = g[j - 1], g[j]
    else:
        j = np.flatnonzero((g[1:] < 0.0) & (g[:-1] < _CUSP_JUMP * g[1:])) + 1
        g_old, g_new = -g[j], -g[j - 1]
    if j.size == 0:
        return None
    zj, cj = st.z[j], st.c[j]
    side = (zj > geo.zb[:, None]) if fam == FAM_L else (zj < geo.za[:, None])
    ratio = 1.0 / (geo.pmax[:, None] * cj)  # cos(phi_j) = c_max / c_j
    with np.errstate(invalid="ignore"):
        phj = np.where(side & (ratio < 1.0), np.arccos(np.clip(ratio, -1.0, 1.0)), np.nan)
    phj = np.where(phj < ext[:, None], phj, np.nan)
    if not np.any(np.isfinite(phj)):
        return None
    # the breakpoint's gradients ride along with its phi_j through the per-pair selection
    key = np.broadcast_to(np.arange(j.size), phj.shape)
    order = np.argsort(np.where(np.isfinite(phj), phj, np.inf), axis=1)
    phj = np.take_along_axis(phj, order, axis=1)
    key = np.take_along_axis(key, order, axis=1)
    if j.size > _CUSP_MAX:
        # many thin layers: an even spread of the pair's relevant breakpoints
        m = np.isfinite(phj).sum(axis=1)
        pick = np.round(np.linspace(0.0, 1.0, _CUSP_MAX)[None, :] * np.maximum(m - 1, 0)[:, None]).astype(np.intp)
        phj = np.where(m[:, None] > 0, np.take_along_axis(phj, pick, axis=1), np.nan)
        key = np.take_along_axis(key, pick, axis=1)
    g_old, g_new, cj = g_old[key], g_new[key], cj[key]
    probe = np.where(np.isfinite(phj), phj * (1.0 - 1e-12), 0.0)  # just before: old layer turns
    _, slope = _range(st, geo, fam, probe, deriv=True)
    beta = 2.0 * (1.0 / g_old - 1.0 / g_new) * cj  # 1/p = c_j at phi_j
    with np.errstate(invalid="ignore", divide="ignore"):
        du = beta**2 * np.tan(phj) / (2.0 * slope**2)
    dip = np.where((slope > 0.0) & np.isfinite(du), np.minimum(phj + du, ext[:, None] * (1.0 - 1e-10)), np.nan)
    return np.concatenate([phj, dip], axis=1)


def _direct_block(st: Stack, za, zb, x) -> _Arrivals:
    """Earliest direct eigenray for one block of pairs with za <= zb, horizontal range x."""
    n = za.size
    best = _Arrivals.empty(n)
    geo = geometry(st, za, zb)
    allidx = np.arange(n)

    # coincident points, and equal depths inside a constant-speed layer: a horizontal line
    same = (za == zb) & (x == 0.0)
    best.time[same] = 0.0
    best.length[same] = 0.0
    best.ang_a[same] = best.ang_b[same] = 0.0
    best.ok[same] = True
    flat = (
        (za == zb)
        & (x > 0.0)
        & ((st.g[geo.ka] == 0.0) | ((za == st.z[geo.ka]) & (geo.ka > 0) & (st.g[np.maximum(geo.ka - 1, 0)] == 0.0)))
    )
    best.time[flat] = x[flat] / geo.ca[flat]
    best.length[flat] = x[flat]
    best.ang_a[flat] = best.ang_b[flat] = 0.0
    best.ok[flat] = True

    # direct family: X_D increases monotonically from 0 (vertical) to its grazing value
    vert = (zb > za) & (x == 0.0)
    if np.any(vert):
        i = allidx[vert]
        _finish(st, geo, FAM_D, np.full(i.size, 0.5 * np.pi), x[i], i, best, np.zeros(i.size))
    cand = (zb > za) & (x > 0.0)
    if np.any(cand):
        i = allidx[cand]
        g = geo.take(i)
        xg = _range(st, g, FAM_D, np.zeros((i.size, 1)))[:, 0]
        reach = xg >= x[i]
        i, xg = i[reach], xg[reach]
        if i.size:
            lo, hi = np.zeros(i.size), np.full(i.size, 0.5 * np.pi)
            # the chord's angle is the root for a uniform speed: a good Newton start
            guess = np.arctan2(zb[i] - za[i], x[i])
            phi, res = _refine(st, geo.take(i), FAM_D, x[i], lo, hi, xg - x[i], -x[i], guess)
            _finish(st, geo, FAM_D, phi, x[i], i, best, res)

    # turning families: sample phi, bracket every usable sign change, refine
    # the last sample stays a hair inside the family, where the turning point certainly exists
    u = np.linspace(0.0, 1.0 - 1e-10, _GRID)
    for fam, ext in ((FAM_L, geo.phi_l), (FAM_U, geo.phi_u)):
        i = allidx[(ext > 0.0) & (x > 0.0)]
        if i.size == 0:
            continue
        g = geo.take(i)
        grid = ext[i, None] * u[None, :]
        cusp = _cusp_samples(st, g, fam, ext[i])
        if cusp is not None:
            grid = np.sort(np.concatenate([grid, cusp], axis=1), axis=1)  # NaN (unused) last
        h = _range(st, g, fam, grid) - x[i, None]
        rows, s = _pick_brackets(h)
        if rows.size == 0:
            continue
        j = i[rows]
        phi, res = _refine(st, geo.take(j), fam, x[j], grid[rows, s], grid[rows, s + 1], h[rows, s], h[rows, s + 1])
        _finish(st, geo, fam, phi, x[j], j, best, res)
    best.time[~best.ok] = np.nan
    return best


def _direct(st: Stack, zs, zr, x) -> _Arrivals:
    """Earliest direct eigenray src -> dst for flat arrays (depths zs, zr, horizontal x);
    angles in the src -> dst orientation."""
    n = zs.size
    out = _Arrivals.empty(n)
    out.time[:] = np.nan
    swap = zs > zr
    za, zb = np.where(swap, zr, zs), np.where(swap, zs, zr)
    # depths within a nanometre are equal: below that, c(z_b) rounds to c(z_a) and the
    # direct family's range formula would see a depth step without a speed step
    zb = np.where(zb - za <= _SAME_DEPTH_M, za, zb)
    inside = (za >= 0.0) & (zb <= st.zmax) & np.isfinite(za) & np.isfinite(zb) & np.isfinite(x)
    idx = np.flatnonzero(inside)
    chunk = max(64, _CHUNK_ELEMS // ((_GRID + 2 * _CUSP_MAX) * (st.g.size + 1)))
    for s in range(0, idx.size, chunk):
        i = idx[s : s + chunk]
        r = _direct_block(st, za[i], zb[i], x[i])
        for f in ("time", "length", "turn", "ok"):
            getattr(out, f)[i] = getattr(r, f)
        sw = swap[i]
        # reversing the ray reverses both tangents
        out.ang_a[i] = np.where(sw, -r.ang_b, r.ang_a)
        out.ang_b[i] = np.where(sw, -r.ang_a, r.ang_b)
    return out


# ----------------------------------------------------------------------------------------
# public API


def _pairs(src: ArrayLike, dst: ArrayLike):
    s = np.asarray(src, dtype=float)
    d = np.asarray(dst, dtype=float)
    if s.shape[-1:] != (3,) or d.shape[-1:] != (3,):
        raise ValueError("src and dst must have a last axis of length 3 (x, y, z)")
    s, d = np.broadcast_arrays(s, d)
    shape = s.shape[:-1]
    s, d = s.reshape(-1, 3), d.reshape(-1, 3)
    x = np.hypot(d[:, 0] - s[:, 0], d[:, 1] - s[:, 1])
    return shape, s, d, x


def _deepest(s, d) -> float:
    z = np.concatenate([s[:, 2], d[:, 2]])
    z = z[np.isfinite(z)]
    return float(z.max()) if z.size else 0.0


def _to_eigenray(a: _Arrivals, kind: int, shape) -> Eigenray:
    path = np.where(a.ok, kind, PathKind.NONE).astype(np.int8)
    return Eigenray(
        time=np.where(a.ok, a.time, np.nan).reshape(shape),
        length=np.where(a.ok, a.length, np.nan).reshape(shape),
        launch_angle=np.where(a.ok, a.ang_a, np.nan).reshape(shape),
        arrival_angle=np.where(a.ok, a.ang_b, np.nan).reshape(shape),
        turning_depth=np.where(a.ok, a.turn, np.nan).reshape(shape),
        path=path.reshape(shape),
    )


def _reflected(st: Stack, zs, zr, x, boundary: Literal["surface", "bottom"]) -> _Arrivals:
    """First arrival with one reflection: the direct ray of the mirrored profile to the image."""
    n = zs.size
    if boundary == "bottom" and not st.bottom:
        return _Arrivals.empty(n)
    zm = st.zmax
    inside = (zs >= 0.0) & (zs <= zm) & (zr >= 0.0) & (zr <= zm)
    mst = st.mirrored(boundary)
    if boundary == "surface":
        zs_i, zr_i = zm - zs, zm + zr
    else:
        zs_i, zr_i = zs, 2.0 * zm - zr
    a = _direct(mst, np.where(inside, zs_i, np.nan), np.where(inside, zr_i, np.nan), x)
    a.ok &= inside
    if boundary == "surface":
        a.ang_a = -a.ang_a  # leaves the image source downwards = the real source upwards
        a.turn = np.abs(a.turn - zm)
    else:
        a.ang_b = -a.ang_b
        a.turn = np.where(a.turn > zm, 2.0 * zm - a.turn, a.turn)
    return a


def combine_arrivals(arrivals: list[tuple[int, Eigenray]], mode: Reflections) -> Eigenray:
    """Merge per-path eigenrays: the first is the direct one; ``mode`` picks how reflected
    paths (the others) are used: "none", "fallback" (only where no direct path) or "all"
    (the earliest of every path)."""
    if mode not in ("none", "fallback", "all"):
        raise ValueError(f"reflections must be 'none', 'fallback' or 'all', got {mode!r}")
    fields = ("time", "length", "launch_angle", "arrival_angle", "turning_depth")
    _, base = arrivals[0]
    out = {f: np.array(getattr(base, f), dtype=float, copy=True) for f in fields}
    path = np.array(base.path, dtype=np.int8, copy=True)
    if mode == "none":
        return Eigenray(path=path, **out)
    direct_ok = path != PathKind.NONE
    for kind, ray in arrivals[1:]:
        t = np.asarray(ray.time)
        cur = np.where(np.isnan(out["time"]), np.inf, out["time"])
        take = np.isfinite(t) & (t < cur)
        if mode == "fallback":
            take &= ~direct_ok
        for f in fields:
            out[f] = np.where(take, getattr(ray, f), out[f])
        path = np.where(take, np.int8(kind), path).astype(np.int8)
    return Eigenray(path=path, **out)


def eigenray(profile: Layered, src: ArrayLike, dst: ArrayLike, *, reflections: Reflections = "fallback") -> Eigenray:
    """First-arrival eigenray from ``src`` to ``dst`` (..., 3) through a layered profile.

    ``reflections``: "none" (direct path only), "fallback" (the first surface- or
    bottom-reflected arrival where there is no direct path), "all" (the earliest of the
    direct and reflected arrivals). ``path`` tells which path each arrival took; NaN and
    ``PathKind.NONE`` where there is none (see :func:`why_no_path`).
    """
    if reflections not in ("none", "fallback", "all"):
        raise ValueError(f"reflections must be 'none', 'fallback' or 'all', got {reflections!r}")
    shape, s, d, x = _pairs(src, dst)
    st = stack(profile, _deepest(s, d))
    direct = _direct(st, s[:, 2], d[:, 2], x)
    parts: list[tuple[int, Eigenray]] = [(PathKind.DIRECT, _to_eigenray(direct, PathKind.DIRECT, shape))]
    if reflections != "none":
        need = np.ones(x.size, bool) if reflections == "all" else ~direct.ok
        boundaries: tuple[tuple[PathKind, Literal["surface", "bottom"]], ...] = (
            (PathKind.SURFACE, "surface"),
            (PathKind.BOTTOM, "bottom"),
        )
        for kind, name in boundaries:
            r = _Arrivals.empty(x.size)
            r.time[:] = np.nan
            i = np.flatnonzero(need)
            if i.size and (name == "surface" or st.bottom):
                sub = _reflected(st, s[i, 2], d[i, 2], x[i], name)
                for f in ("time", "length", "ang_a", "ang_b", "turn", "ok"):
                    getattr(r, f)[i] = getattr(sub, f)
            parts.append((kind, _to_eigenray(r, kind, shape)))
    return combine_arrivals(parts, reflections)


def travel_time(
    profile: Layered, src: ArrayLike, dst: ArrayLike, *, reflections: Reflections = "fallback"
) -> NDArray[np.float64]:
    """First-arrival travel time (s); NaN where there is no path."""
    return eigenray(profile, src, dst, reflections=reflections).time


def slowness_gradient(profile, src: ArrayLike, dst: ArrayLike, ray: Eigenray) -> NDArray[np.float64]:
    """d t / d dst (s/m) of any eigenray: the slowness vector at the receiver,
    (cos theta_R u_h + sin theta_R e_z) / c(z_R), u_h the horizontal unit vector src -> dst.
    Exact for every eigenray (t is stationary in the path, so only the end point moves)."""
    s = np.asarray(src, dtype=float)
    d = np.asarray(dst, dtype=float)
    s, d = np.broadcast_arrays(s, d)
    dx, dy = d[..., 0] - s[..., 0], d[..., 1] - s[..., 1]
    hor = np.hypot(dx, dy)
    with np.errstate(invalid="ignore", divide="ignore"):
        ux = np.where(hor > 0.0, dx / hor, 0.0)
        uy = np.where(hor > 0.0, dy / hor, 0.0)
    c = np.asarray(profile.speed(d[..., 2]), dtype=float)
    th = np.asarray(ray.arrival_angle)
    ch, sh = np.cos(th) / c, np.sin(th) / c
    return np.stack([ch * ux, ch * uy, sh], axis=-1)


def travel_time_gradient(
    profile: Layered, src: ArrayLike, dst: ArrayLike, *, reflections: Reflections = "fallback"
) -> NDArray[np.float64]:
    """d travel_time / d dst (s/m), shape (..., 3); NaN where there is no path."""
    ray = eigenray(profile, src, dst, reflections=reflections)
    return slowness_gradient(profile, src, dst, ray)


def reflected_eigenray(
    profile: Layered, src: ArrayLike, dst: ArrayLike, boundary: Literal["surface", "bottom"]
) -> Eigenray:
    """First arrival with exactly one reflection off ``boundary`` (profile mirrored about it)."""
    shape, s, d, x = _pairs(src, dst)
    st = stack(profile, _deepest(s, d))
    kind = PathKind.SURFACE if boundary == "surface" else PathKind.BOTTOM
    return _to_eigenray(_reflected(st, s[:, 2], d[:, 2], x, boundary), kind, shape)


def why_no_path(
    profile: Layered, src: ArrayLike, dst: ArrayLike, *, assume_no_direct: bool = False
) -> NDArray[np.object_]:
    """Why there is no direct eigenray, per pair ("" where there is one): a point outside
    the water; the rays that would connect the points leave the water (only a reflected
    path exists: the reason names the boundary of the earliest one); or a shadow zone.
    ``assume_no_direct``: the caller already knows there is no direct path (skip the solve)."""
    shape, s, d, x = _pairs(src, dst)
    st = stack(profile, _deepest(s, d))
    out = np.full(x.size, "", dtype=object)
    zs, zr = s[:, 2], d[:, 2]
    outside = ~((np.minimum(zs, zr) >= 0.0) & (np.maximum(zs, zr) <= st.zmax))
    outside |= ~(np.isfinite(s).all(axis=1) & np.isfinite(d).all(axis=1))
    out[outside] = REASON_OUTSIDE
    has_direct = np.zeros(x.size, bool) if assume_no_direct else _direct(st, zs, zr, x).ok
    i = np.flatnonzero(~has_direct & ~outside)
    if i.size:
        # the direct ray in the profile continued past the boundaries: where does it turn?
        ext, off = st.extended()
        a = _direct(ext, zs[i] + off, zr[i] + off, x[i])
        out[i] = np.where(
            a.ok & (a.turn < off),
            REASON_SURFACE,
            np.where(a.ok & (a.turn > st.zmax + off), REASON_BOTTOM, REASON_SHADOW),
        )
    return out.reshape(shape)


def straight_line_time(profile: Layered, src: ArrayLike, dst: ArrayLike) -> NDArray[np.float64]:
    """Straight-ray time (s): distance times the mean slowness over the depth interval,
    t = |d - s| / |dz| * integral dz / c(z) (Ramezani et al., eq 23, layer by layer);
    1 / c(z) when both depths are equal."""
    shape, s, d, _x = _pairs(src, dst)
    st = stack(profile, _deepest(s, d))
    z1 = np.minimum(s[:, 2], d[:, 2])
    z2 = np.maximum(s[:, 2], d[:, 2])
    dist = np.linalg.norm(d - s, axis=1)
    top = np.maximum(st.z[:-1], z1[:, None])
    bot = np.minimum(st.z[1:], z2[:, None])
    hh = np.maximum(bot - top, 0.0)
    c1 = st.c[:-1] + st.g * (top - st.z[:-1])
    # integral of dz / c over the overlap: log(c2 / c1) / g written without 1/g
    integral = (hh / c1 * log1p_ratio(st.g * hh / c1)).sum(axis=1)
    dz = z2 - z1
    with np.errstate(divide="ignore", invalid="ignore"):
        # below a nanometre the integral underflows or rounds: the local slowness is exact
        mean_slow = np.where(dz > _SAME_DEPTH_M, integral / dz, 1.0 / st.speed(0.5 * (z1 + z2)))
    out = dist * mean_slow
    outside = (z1 < 0.0) | (z2 > st.zmax)
    return np.where(outside, np.nan, out).reshape(shape)
