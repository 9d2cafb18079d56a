"""Eigenrays in range-dependent media: every arrival of a link up to a number of boundary bounces.

Model (N x 2-D). Each link is solved in the vertical plane through its two end points. Along
its line the environment is sampled at the geographic points where its horizontal
interpolation or its sea floor has a kink (:meth:`.fields.SoundSpeedField.section_ranges`,
:meth:`.bathymetry.Bathymetry.section_ranges`), from the last one at or before the source to
the first one at or after the receiver (the ends lie inside the end cells, so sliding an end
along the line does not change the medium): columns of the field's profile on its depth nodes,
and floor depths (and slopes, for a curved floor). In the (range, depth) plane the speed is linear
on each cell of that grid (a rectangle whose four speeds are coplanar, else its two triangles
cut along the diagonal whose end speeds differ least, a rule that makes the reversed link's
section the mirror image), continuous everywhere; the surface is z = 0. The floor is the
polyline through the column depths where the bathymetry is linear between them along every line
(flat, planar); for a curved floor (:meth:`.bathymetry.Bathymetry.slope_along`) it is the smooth
(C1) curve through the column depths with the bathymetry's slopes there, two circular arcs per
column interval (a biarc: the unique pair of arcs with equal tangent-point distances that leaves
one sample on its tangent and reaches the next on its tangent). A polyline would turn the normal
of a curved floor in jumps at its vertices, and reflect a fan of rays into beams with gaps (a
convex floor) or overlaps (a concave one) between them, which lose and invent eigenrays whatever
the resolution; arcs keep every reflection specular off a continuously turning floor, and are
still closed form against the rays' arcs (two circles). Range-independent media are the special case of identical
profile columns (every rectangle planar): the cells are the layers of :mod:`.layered`, which this
solver reproduces to 1e-12 s (tests/channel/test_rangedep.py).

Rays. Where the gradient of c is constant a ray is an exact arc of a circle, so the walk from
cell to cell is closed form (circle / line and circle / circle intersections, travel time and arc
length per arc: :mod:`._rangedep_jit`); rays reflect specularly off the surface and the sloping or
curved floor about its local normal (paying the floor's Rayleigh loss). No step size, no
integration error: what remains is rounding.

Eigenrays. Per link, a fan of launch angles (with samples next to the angles whose rays turn at
a depth node of the source's profile, where a family may fold), refined where the bounce sequence
("family") changes (edges located to 1e-5 rad), where the walk predicts a change (a family
narrower than the fan), and where the depth miss may fold (its exact slope from the walk's
tangent-linear map: :mod:`._rangedep_search_jit`); Newton's iteration on the depth miss at the
receiver's range inside each family, to 1e-8 m; the travel time is then corrected to first order
for the remaining miss (dt/dz = sin(theta_R) / c_R), far below 1e-9 s.

Limits (documented, not hidden): rays that travel backwards past the source's range, cross the
receiver's range twice, or bounce more than ``max_bounces`` times are dropped; an eigenray within
1e-5 rad of its family's edge, or two of a fold closer than 1e-4 rad that the samples do not show,
may be missed; out-of-plane refraction is ignored (N x 2-D); below 1 mm of horizontal separation a
link is solved as if the receiver were 1 mm away along +x (a time error below 1e-12 s).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .environment import Environment

__all__ = [
    "MIN_RANGE_M",
    "TURN_FACTOR",
    "Sections",
    "follow",
    "follow_ends",
    "kept_apart",
    "reversed_code",
    "reversed_rows",
    "sections",
    "solve",
    "trace_rays",
    "track",
    "turned_within",
    "watch",
    "watch_reach",
]

FloatArray = NDArray[np.float64]

MIN_RANGE_M = 1e-3
_OPEN_DEPTH_M = 1.0e4  # depth of the grid's end below the deepest point where no floor is modelled
_FAN_DW = 0.25  # fan spacing in w = tan(theta) R / H (families are ~2 apart)
_ZTOL_M = 1e-8  # depth miss at the receiver at which a root is converged
_MAX_ARRIVALS = 64


@dataclass(frozen=True)
class Sections:
    """The (range, depth) sections of n links, rows of each link at offs[l]:offs[l+1]."""

    offs: NDArray[np.int64]
    r: FloatArray  #: (rows,) column ranges, m (from <= 0 to >= R per link)
    c: FloatArray  #: (rows, K) speeds on ``z``
    floor_z: FloatArray  #: (rows,) floor depth at each column, m
    #: (rows, 12) the floor's shape (:func:`_floor_shape`): at each column its tangent angles from
    #: the left and to the right (rad, positive deepening; they differ at a kink), and of the
    #: interval to the next column the biarc's junction (range, depth, tangent angle), its two
    #: arcs' curvatures (1/m, positive where the floor bends towards the water: concave; zero:
    #: the straight segment between the two columns), the unit normals into the floor where
    #: each arc starts and the interval's shallowest floor depth
    floor_shape: FloatArray
    z: FloatArray  #: (K,) depth nodes, m
    floor: bool  #: a sea floor reflects (False: none modelled)
    zs: FloatArray  #: (n,) source depths
    zr: FloatArray  #: (n,) receiver depths
    R: FloatArray  #: (n,) horizontal ranges, m
    H: FloatArray  #: (n,) vertical scale (deepest floor or point), m
    ux: FloatArray  #: (n,) unit direction, x
    uy: FloatArray  #: (n,) unit direction, y
    valid: NDArray[np.bool_]  #: (n,) both ends in the water
    #: (n,) a hash of each section's structure: the kinks of the environment that bound and cut
    #: it, in order, and how each of its cells is cut (whole or along which diagonal). The
    #: delays are smooth functions of the ends while it stays the same; where it changes (a
    #: kink enters, leaves or passes another, a cell's cut flips) their slopes may jump.
    structure: NDArray[np.uint64]

    def link(self, i: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(r, c, floor_z) of link i."""
        a, b = self.offs[i], self.offs[i + 1]
        return self.r[a:b], self.c[a:b], self.floor_z[a:b]

    def floor_at(self, i: int, r: ArrayLike) -> FloatArray:
        """The floor depth (m) of link i's section at ranges ``r`` (m) inside it."""
        a, b = int(self.offs[i]), int(self.offs[i + 1])
        q = np.asarray(r, dtype=float)
        rs = self.r[a:b][None, :]
        flat = q.ravel()
        out = _floor_at(
            np.broadcast_to(rs, (flat.size, b - a)),
            self.floor_z[a:b],
            self.floor_shape[a:b],
            np.arange(flat.size + 1, dtype=np.int64) * 0,
            flat,
            shared=True,
        )
        return out.reshape(q.shape)


def _pairs(src: ArrayLike, dst: ArrayLike) -> tuple[tuple[int, ...], FloatArray, FloatArray]:
    s = np.asarray(src, dtype=float)
    d = np.asarray(dst, dtype=float)
    if s.shape[-1:] != (3,) or d.shape[-1:] != (3,):
        raise ValueError("src and dst must have a last axis of length 3 (x, y, z)")
    s, d = np.broadcast_arrays(s, d)
    return s.shape[:-1], s.reshape(-1, 3), d.reshape(-1, 3)


def sections(env: Environment, src: ArrayLike, dst: ArrayLike) -> Sections:
    """The vertical-plane sections of the links src -> dst (each (..., 3)), vectorized."""
    _, s, d = _pairs(src, dst)
    n = s.shape[0]
    dx, dy = d[:, 0] - s[:, 0], d[:, 1] - s[:, 1]
    R = np.hypot(dx, dy)
    short = ~(R >= MIN_RANGE_M)
    with np.errstate(invalid="ignore", divide="ignore"):
        ux = np.where(short, 1.0, dx / R)
        uy = np.where(short, 0.0, dy / R)
    R = np.where(short, MIN_RANGE_M, R)
    x0, y0 = s[:, 0], s[:, 1]
    # the kinks of the field and the floor along the link's line (geographic points), the
    # last one at or before the source and the first one at or after the receiver: the ends
    # lie inside the end cells, so moving an end along the line leaves the medium unchanged
    parts = [env.field.section_ranges(x0, y0, ux, uy, R)]
    if env.bathymetry is not None:
        parts.append(env.bathymetry.section_ranges(x0, y0, ux, uy, R))
    kinks = np.concatenate([np.empty((n, 0))] + parts, axis=1)
    Rc = R[:, None]
    left = np.max(np.where(kinks <= 0.0, kinks, -np.inf), axis=1, initial=-np.inf)
    right = np.min(np.where(kinks >= Rc, kinks, np.inf), axis=1, initial=np.inf)
    left = np.where(np.isfinite(left), left, 0.0)
    right = np.where(np.isfinite(right), right, R)
    inner = np.where((kinks > 0.0) & (kinks < Rc), kinks, np.nan)
    kink_ids = _kink_ids_hash(kinks, R)
    rs = np.sort(np.concatenate([left[:, None], inner, right[:, None]], axis=1), axis=1)  # NaN last
    # drop columns closer than a nanometre to the previous one
    close = np.zeros(rs.shape, bool)
    close[:, 1:] = np.diff(rs, axis=1) <= 1e-9 * np.maximum(1.0, Rc)
    rs = np.sort(np.where(close, np.nan, rs), axis=1)
    cnt = np.isfinite(rs).sum(axis=1)
    # the right end column must stay (it may have been dropped as "close" to an inner kink)
    rs[np.arange(n), cnt - 1] = np.maximum(rs[np.arange(n), cnt - 1], right)
    keep = np.isfinite(rs)
    px = x0[:, None] + rs * ux[:, None]
    py = y0[:, None] + rs * uy[:, None]
    px, py = px[keep], py[keep]
    cols = np.asarray(env.field.columns(px, py), dtype=float)
    depths = np.asarray(env.field.depths, dtype=float)
    zs, zr = s[:, 2], d[:, 2]
    deepest = float(np.nanmax(np.concatenate([zs, zr, [0.0]])))
    offs = np.zeros(n + 1, np.int64)
    offs[1:] = np.cumsum(cnt)
    rk = rs[keep]
    if env.bathymetry is not None:
        fz = np.asarray(env.bathymetry.depth(px, py), dtype=float)
        rows_u = np.repeat(ux, cnt), np.repeat(uy, cnt)
        slope = env.bathymetry.slope_along(px, py, *rows_u)
        shape, fmax = _floor_shape(rk, fz, None if slope is None else np.asarray(slope, float), offs)
        zmax = max(float(fmax.max(initial=0.0)), deepest) + 1.0
        floor = True
    else:
        zmax = max(deepest, float(depths[-1])) + _OPEN_DEPTH_M
        fz = np.full(px.shape, zmax - 1.0)
        shape, fmax = _floor_shape(rk, fz, None, offs)
        floor = False
    if depths[-1] < zmax:  # the last gradient continues down to the grid's end
        g = (cols[:, -1] - cols[:, -2]) / (depths[-1] - depths[-2])
        cols = np.concatenate([cols, (cols[:, -1] + g * (zmax - depths[-1]))[:, None]], axis=1)
        depths = np.concatenate([depths, [zmax]])
    # floor depth under each end: the floor between the columns that bracket it
    fz_s = _floor_at(rs, fz, shape, offs, np.zeros(n))
    fz_r = _floor_at(rs, fz, shape, offs, R)
    valid = (
        np.isfinite(s).all(axis=1)
        & np.isfinite(d).all(axis=1)
        & (zs >= 0.0)
        & (zr >= 0.0)
        & (zs <= fz_s)
        & (zr <= fz_r)
    )
    # the waveguide's depth between the ends (the end columns may lie far outside them)
    inside = np.full(rs.shape, -np.inf)
    inside[keep] = np.where((rs[keep] > 0.0) & (rs[keep] < np.broadcast_to(Rc, rs.shape)[keep]), fmax, -np.inf)
    between = np.maximum(np.maximum(fz_s, fz_r), inside.max(axis=1))
    H = np.maximum(between if floor else np.maximum(zs, zr), 1.0)
    if not floor:
        H = np.maximum(H, 100.0)
    if np.any(cols <= 0.0):
        raise ValueError("sound speed not positive inside the sections (check the field's depth extrapolation)")
    structure = kink_ids ^ _cuts_hash(cols, depths, fmax, offs) ^ (valid.astype(np.uint64) * _MIX[2])
    return Sections(offs, rk, cols, fz, shape, depths, floor, zs, zr, R, H, ux, uy, valid, structure)


_COPLANAR_MPS = 1e-6
_MIX = np.array([0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9], dtype=np.uint64)


def _splitmix(x: NDArray[np.uint64]) -> NDArray[np.uint64]:
    """A 64-bit mixer (splitmix64's finalizer), elementwise, wrapping."""
    x = x + _MIX[0]
    x = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    x = (x ^ (x >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return x ^ (x >> np.uint64(31))


def _kink_ids_hash(kinks: FloatArray, R: FloatArray) -> NDArray[np.uint64]:
    """(n,) a hash of which kinks (columns of ``kinks``) bound each section (the last at or
    before 0, the first at or after R) and which cut it, in their order along the line."""
    n, m = kinks.shape
    if m == 0:
        return np.zeros(n, np.uint64)
    Rc = R[:, None]
    with np.errstate(invalid="ignore"):
        before = np.where(kinks <= 0.0, kinks, -np.inf)
        after = np.where(kinks >= Rc, kinks, np.inf)
        inside = (kinks > 0.0) & (kinks < Rc)
    left = np.where(np.isfinite(before).any(axis=1), np.argmax(before, axis=1), -1)
    right = np.where(np.isfinite(after).any(axis=1), np.argmin(after, axis=1), -1)
    order = np.argsort(np.where(inside, kinks, np.inf), axis=1, kind="stable")
    ids = np.where(np.take_along_axis(inside, order, axis=1), order + 1, 0).astype(np.uint64)
    pos = np.arange(1, m + 1, dtype=np.uint64)
    with np.errstate(over="ignore"):
        h = _splitmix(ids * np.uint64(m + 1) + pos[None, :]) * (ids > 0)
        out = np.bitwise_xor.reduce(h, axis=1)
        out ^= _splitmix((left + 2).astype(np.uint64)) * _MIX[1]
        out ^= _splitmix((right + 2).astype(np.uint64) + np.uint64(1 << 32))
    return out


def _cuts_hash(cols: FloatArray, depths: FloatArray, fmax: FloatArray, offs: NDArray[np.int64]) -> NDArray[np.uint64]:
    """(n,) a hash of how every cell of each section above its floor (``fmax``: the floor's
    deepest point on the interval from each column to the next) is cut (the rule of
    _rangedep_jit: whole where its four speeds are coplanar, else along the diagonal whose ends
    differ least). A cell within 1e-6 m/s of coplanar counts as whole: whichever way it is cut,
    the medium differs from the plane by less than that (a delay by ~1e-10 s)."""
    n = offs.size - 1
    out = np.zeros(n, np.uint64)
    if cols.shape[0] < 2:
        return out
    c00, c10 = cols[:-1, :-1], cols[1:, :-1]
    c01, c11 = cols[:-1, 1:], cols[1:, 1:]
    flat = np.abs(c00 - c10 - c01 + c11) <= _COPLANAR_MPS
    code = np.where(flat, 0, np.where(np.abs(c10 - c01) < np.abs(c00 - c11), 1, 2))
    # a ray never enters a cell below the floor's deepest point over its interval
    code = np.where(depths[None, :-1] < fmax[:-1, None], code, 0)
    row = np.arange(cols.shape[0] - 1)
    link = np.searchsorted(offs, row, side="right") - 1
    same = row + 1 < offs[link + 1]  # both rows of the pair in one link
    j = (row - offs[link]).astype(np.uint64)
    k = np.arange(code.shape[1], dtype=np.uint64)
    with np.errstate(over="ignore"):
        h = _splitmix((j[:, None] << np.uint64(20)) + (k[None, :] << np.uint64(2)) + code.astype(np.uint64))
        per_row = np.bitwise_xor.reduce(h, axis=1) * same
        np.bitwise_xor.at(out, link[same], per_row[same])
    return out


def _floor_shape(
    r: FloatArray, fz: FloatArray, slope: FloatArray | None, offs: NDArray[np.int64]
) -> tuple[FloatArray, FloatArray]:
    """The floor of sections (column ranges r, depths fz, flat rows of links offs) as
    :attr:`Sections.floor_shape` rows, and the floor's deepest point on each column's interval
    to the next (rows,). ``slope``: the floor's slope d depth / d r at each column (a smooth
    floor of biarcs), None: the polyline."""
    m = r.size
    out = np.zeros((m, 12))
    last = np.zeros(m, bool)
    last[offs[1:][offs[1:] > offs[:-1]] - 1] = True
    nxt = np.minimum(np.arange(m) + 1, m - 1)
    dr, dz = r[nxt] - r, fz[nxt] - fz
    chord = np.where(last, 0.0, np.arctan2(dz, np.where(last, 1.0, dr)))
    fmax = np.where(last, fz, np.maximum(fz, fz[nxt]))
    if slope is None:
        right = chord
        first = np.zeros(m, bool)
        first[offs[:-1][offs[1:] > offs[:-1]]] = True
        prev = np.maximum(np.arange(m) - 1, 0)
        left = np.where(first, chord, chord[prev])
        right = np.where(last, left, right)
        out[:, 0], out[:, 1] = left, right
        out[:, 2], out[:, 3], out[:, 4] = r[nxt], fz[nxt], right
        out[:, 7], out[:, 8] = -np.sin(right), np.cos(right)
        out[:, 9], out[:, 10] = out[:, 7], out[:, 8]
        out[:, 11] = np.where(last, fz, np.minimum(fz, fz[nxt]))
        return out, fmax
    a = np.arctan(slope)
    out[:, 0] = out[:, 1] = a
    a1 = a[nxt]
    # the biarc between (r, fz) leaving at angle a and (r', fz') arriving at angle a1: tangent
    # points Q0 = P0 + d T0, Q1 = P1 - d T1 at equal distances d with |Q1 - Q0| = 2 d, the
    # junction midway between them; |T0 - T1|^2 d^2 + 2 (v.(T0 + T1)) d - |v|^2 = 0
    t0r, t0z, t1r, t1z = np.cos(a), np.sin(a), np.cos(a1), np.sin(a1)
    vt = dr * (t0r + t1r) + dz * (t0z + t1z)
    w2 = (2.0 * np.sin(0.5 * (a - a1))) ** 2
    v2 = dr * dr + dz * dz
    with np.errstate(invalid="ignore", divide="ignore"):
        d = v2 / (vt + np.sqrt(vt * vt + w2 * v2))
        jr = r + d * t0r + 0.5 * (dr - d * (t0r + t1r))
        jz = fz + d * t0z + 0.5 * (dz - d * (t0z + t1z))
        am = np.arctan2(dz - d * (t0z + t1z), dr - d * (t0r + t1r))
        # signed curvatures, positive where the arc bends towards the water (-n, n = (-sin, cos)
        # the normal into the floor): k = -2 n.(X_end - X_start) / |X_end - X_start|^2
        e1r, e1z = jr - r, jz - fz
        e2r, e2z = r[nxt] - jr, fz[nxt] - jz
        k1 = -2.0 * (-t0z * e1r + t0r * e1z) / (e1r * e1r + e1z * e1z)
        k2 = -2.0 * (-np.sin(am) * e2r + np.cos(am) * e2z) / (e2r * e2r + e2z * e2z)
    straight = last | ((np.abs(a - chord) <= 1e-13) & (np.abs(a1 - chord) <= 1e-13)) | ~np.isfinite(k1 + k2)
    out[:, 2] = np.where(straight, r[nxt], jr)
    out[:, 3] = np.where(straight, fz[nxt], jz)
    out[:, 4] = np.where(straight, a, am)
    out[:, 5] = np.where(straight, 0.0, k1)
    out[:, 6] = np.where(straight, 0.0, k2)
    # the deepest point of each arc: where its tangent turns level inside it (a bowl: the
    # angle falls through 0), at depth z0 + (1 - cos a0) / k from its start (k > 0)
    for a_s, a_e, z_s, k in ((a, am, fz, out[:, 5]), (am, a1, out[:, 3], out[:, 6])):
        dip = ~straight & (k > 0.0) & (a_s > 0.0) & (a_e < 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            zb = z_s + 2.0 * np.sin(0.5 * a_s) ** 2 / k
        fmax = np.where(dip, np.maximum(fmax, zb), fmax)
    fmax = np.maximum(fmax, np.where(straight, fmax, out[:, 3]))
    # and the shallowest: where a convex arc's tangent turns level inside it (a crest)
    fmin = np.where(last, fz, np.minimum(fz, fz[nxt]))
    fmin = np.minimum(fmin, np.where(straight, fmin, out[:, 3]))
    for a_s, a_e, z_s, k in ((a, am, fz, out[:, 5]), (am, a1, out[:, 3], out[:, 6])):
        crest = ~straight & (k < 0.0) & (a_s < 0.0) & (a_e > 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            zc = z_s + 2.0 * np.sin(0.5 * a_s) ** 2 / k
        fmin = np.where(crest, np.minimum(fmin, zc), fmin)
    out[:, 11] = fmin
    out[:, 7], out[:, 8] = -np.sin(out[:, 1]), np.cos(out[:, 1])
    out[:, 9], out[:, 10] = -np.sin(out[:, 4]), np.cos(out[:, 4])
    return out, fmax


def _arc_depth(pr: FloatArray, pz: FloatArray, a: FloatArray, k: FloatArray, q: FloatArray) -> FloatArray:
    """Depth at range q of the arc through (pr, pz) at tangent angle a with curvature k (the
    floor's sign convention; 0: the straight line): the root of n.(X - P) + k/2 |X - P|^2 = 0
    on the branch through P, n = (-sin a, cos a)."""
    nr, nz = -np.sin(a), np.cos(a)
    dr = q - pr
    c0 = nr * dr + 0.5 * k * dr * dr
    return pz - 2.0 * c0 / (nz + np.sqrt(np.maximum(nz * nz - 2.0 * k * c0, 0.0)))


def _floor_at(
    rs: FloatArray, fz: FloatArray, shape: FloatArray, offs: NDArray[np.int64], q: FloatArray, shared: bool = False
) -> FloatArray:
    """The floor of sections (columns rs (n, m) NaN-padded, depths fz and shape rows flat at
    offs) at distance q (n,) along each; ``shared``: every q on one section (rows from 0)."""
    n = q.size
    cnt = np.isfinite(rs).sum(axis=1)
    r = np.where(np.isfinite(rs), rs, np.inf)
    j = np.clip((r <= q[:, None]).sum(axis=1) - 1, 0, cnt - 2)
    row = (0 if shared else offs[:-1]) + j
    r0 = rs[np.arange(n), j]
    sh = shape[row]
    second = q > sh[:, 2]
    pr = np.where(second, sh[:, 2], r0)
    pz = np.where(second, sh[:, 3], fz[row])
    a = np.where(second, sh[:, 4], sh[:, 1])
    k = np.where(second, sh[:, 6], sh[:, 5])
    return _arc_depth(pr, pz, a, k, q)


def _kernel_args(env: Environment, sec: Sections) -> list[Any]:
    """(starts, ends, r, z, c, floor_z, floor_shape, floor, zs, zr, R) as the search / track
    kernels take them; links with an end outside the water get an empty section."""
    starts = sec.offs[:-1]
    ends = np.where(sec.valid, sec.offs[1:], starts)
    return [
        starts,
        ends,
        sec.r,
        sec.z,
        np.ascontiguousarray(sec.c),
        sec.floor_z,
        sec.floor_shape,
        sec.floor,
        np.where(sec.valid, sec.zs, 0.0),
        np.where(sec.valid, sec.zr, 0.0),
        sec.R,
    ]


def watch_reach(move_m: ArrayLike) -> FloatArray:
    """How far (m) the depth miss at a fixed launch angle is taken to move when the farther end of
    a link moves by ``move_m`` (m): ``WATCH_M_PER_M`` per metre, at least 1 m of move. A search
    for a follow radius R keeps the watched intervals whose margin is below ``watch_reach(R)``
    (:func:`solve`), and a link followed ``move_m`` from its search checks those below
    ``watch_reach(move_m)`` (:func:`watch`)."""
    from ._rangedep_search_jit import WATCH_M_PER_M

    return WATCH_M_PER_M * np.maximum(np.asarray(move_m, dtype=float), 1.0)


def solve(
    env: Environment, sec: Sections, max_bounces: int, watch_m: float | None = None
) -> tuple[FloatArray, NDArray[np.int64], FloatArray, NDArray[np.int64]]:
    """Raw eigenray rows (n, cap, NF) (see _rangedep_search_jit.F_*) and counts (n,) of the
    sections; their watched intervals (n, WATCH_ROWS, NW) and counts (n,) (where a small move
    may bring a fold's two eigenrays, or one across a family's edge: :func:`watch`): those whose
    margin is below ``watch_m`` (m; default ``watch_reach(1.0)``, what a follow radius of 1 m
    needs)."""
    from . import _rangedep_search_jit as jit

    mb = int(max_bounces)
    if mb < 0:
        raise ValueError(f"max_bounces must be >= 0, got {max_bounces!r}")
    wm = float(watch_reach(1.0) if watch_m is None else watch_m)
    n = sec.zs.size
    wmax = np.full(n, 2.0 * (mb + 1) + 1.0) * 1.5
    nfan = np.ceil(2.0 * wmax / _FAN_DW).astype(np.int64)
    starts, ends, r, z, c, fz, fs, floor, zs, zr, R = _kernel_args(env, sec)
    bpar = np.array(env.bottom.params, dtype=float)
    return jit.search_links(
        starts, ends, r, z, c, fz, fs, floor, zs, zr, R, mb, bpar, wmax, nfan, sec.H, _ZTOL_M, wm, _MAX_ARRIVALS
    )


def watch(
    env: Environment,
    src: ArrayLike,
    dst: ArrayLike,
    max_bounces: int,
    intervals: FloatArray,
    counts: NDArray[np.int64],
    theta0: FloatArray | None = None,
    code: NDArray[np.int64] | None = None,
    reach: ArrayLike | None = None,
) -> NDArray[np.bool_]:
    """Whether the watched intervals of each link (``intervals`` (n, WATCH_ROWS, NW), ``counts``
    (n,), as :func:`solve` gave them where the link was searched) still hold no eigenray with
    its ends at ``src`` -> ``dst`` (n, 3) but the link's known ones there (launch angles
    ``theta0`` (n, Q) rad and bounce sequences ``code`` (n, Q), NaN / -1 padded; none if not
    given): False where a fold may have brought two, or one may have entered across a watched
    edge (the link is to be searched again), or the link had more watched intervals than rows.
    ``reach`` (m, (n,) or scalar; default every interval): only the intervals whose margin is
    below it are checked (how far the miss may have moved since the search: :func:`watch_reach`
    of the farther end's move)."""
    from . import _rangedep_search_jit as jit

    sec = sections(env, src, dst)
    starts, ends, r, z, c, fz, fs, floor, zs, zr, R = _kernel_args(env, sec)
    return jit.watch_links(
        starts,
        ends,
        r,
        z,
        c,
        fz,
        fs,
        floor,
        zs,
        zr,
        R,
        int(max_bounces),
        np.array(env.bottom.params, dtype=float),
        np.ascontiguousarray(intervals, dtype=float),
        np.ascontiguousarray(counts, dtype=np.int64),
        np.broadcast_to(np.inf if reach is None else np.asarray(reach, dtype=float), sec.zs.shape).copy(),
        np.full((sec.zs.size, 0), np.nan) if theta0 is None else np.ascontiguousarray(theta0, dtype=float),
        np.full((sec.zs.size, 0), -1, np.int64) if code is None else np.ascontiguousarray(code, dtype=np.int64),
    )


def trace_rays(
    env: Environment, src: ArrayLike, dst: ArrayLike, theta0: ArrayLike, max_bounces: int = 10, npts: int = 4000
):
    """The exact walk of one ray per link at launch angle(s) ``theta0`` (rad) in the link's
    plane: (paths (n, npts, 3) of (range m, depth m, time s) vertices, counts (n,), sections)."""
    from . import _rangedep_search_jit as jit

    sec = sections(env, src, dst)
    th = np.broadcast_to(np.asarray(theta0, float), sec.zs.shape).copy()
    bpar = np.array(env.bottom.params, dtype=float)
    paths, cnt = jit.trace_links(
        sec.offs,
        sec.r,
        sec.z,
        np.ascontiguousarray(sec.c),
        sec.floor_z,
        sec.floor_shape,
        sec.floor,
        sec.zs,
        sec.R,
        th,
        int(max_bounces),
        bpar,
        int(npts),
    )
    return paths, cnt, sec


def follow(
    env: Environment,
    src: ArrayLike,
    dst: ArrayLike,
    max_bounces: int,
    theta0: FloatArray,
    code: NDArray[np.int64],
) -> tuple[FloatArray, NDArray[np.bool_], Sections]:
    """Known eigenrays (launch angles theta0 (n, Q), bounce sequences; code < 0 = none) followed
    to the links src -> dst: Newton's iteration from the old angle each, instead of a search.
    Returns (rows (n, Q, NF) as :func:`solve` gives them, NaN where not followed; followed (n,
    Q); the sections)."""
    from . import _rangedep_search_jit as jit

    sec = sections(env, src, dst)
    starts, ends, r, z, c, fz, fs, floor, zs, zr, R = _kernel_args(env, sec)
    rows, ok = jit.follow_links(
        starts,
        ends,
        r,
        z,
        c,
        fz,
        fs,
        floor,
        zs,
        zr,
        R,
        int(max_bounces),
        np.array(env.bottom.params, dtype=float),
        np.ascontiguousarray(theta0, dtype=float),
        np.ascontiguousarray(code, dtype=np.int64),
        _ZTOL_M,
    )
    return rows, ok, sec


def kept_apart(theta_old: FloatArray, theta_new: FloatArray, code: NDArray[np.int64]) -> NDArray[np.bool_]:
    """(n, Q) whether each followed eigenray stayed nearer its old launch angle than half the
    gap to its nearest sibling (another eigenray of its bounce sequence): then no two of one
    sequence can have met or swapped (a fold, where following one may land on the other).
    False where not followed (NaN) or code < 0."""
    code = np.asarray(code)
    used = code >= 0
    same = (code[:, :, None] == code[:, None, :]) & used[:, :, None] & used[:, None, :]
    same &= ~np.eye(code.shape[1], dtype=bool)[None]
    gap = np.min(np.where(same, np.abs(theta_old[:, :, None] - theta_old[:, None, :]), np.inf), axis=2)
    with np.errstate(invalid="ignore"):
        return used & (np.abs(theta_new - theta_old) < 0.5 * gap)


# a followed root may move by this many times the fold check's reach over its old slope (the
# slope changes along the move; an allowance, not derived)
TURN_FACTOR = 4.0


def turned_within(
    theta_old: FloatArray, theta_new: FloatArray, dz_dth_old: FloatArray, reach: ArrayLike
) -> NDArray[np.bool_]:
    """(n, Q) whether each followed eigenray's launch angle moved (rad) by at most
    ``TURN_FACTOR`` times ``reach`` (m, broadcast; :func:`watch_reach` of the farther end's move:
    how far the depth miss at a fixed launch angle may have moved) over its old ray-tube width
    |dz / d theta| (m/rad): to first order a root moves by the miss's change over its slope.
    Following lands on another root of its bounce sequence where one was born between (a fold)
    and the old one is steep: from a ray near a caustic (dz / d theta 8e6 m/rad) 1.2 deg onto
    the new pair's far root, which :func:`kept_apart` allows there (half the gap to the sibling,
    1.3 deg). False where not followed (NaN)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        out: NDArray[np.bool_] = np.abs(theta_new - theta_old) <= TURN_FACTOR * np.asarray(reach) / np.abs(dz_dth_old)
    return out


def reversed_code(code: NDArray[np.int64], bounces: NDArray[np.int64]) -> NDArray[np.int64]:
    """The bounce sequence of each eigenray travelled backwards: its ``bounces`` base-3 digits
    (first bounce least significant) in reverse order; codes < 0 (none) stay -1."""
    code = np.asarray(code, np.int64)
    bounces = np.asarray(bounces, np.int64)
    out = np.zeros_like(code)
    rest = np.maximum(code, 0)
    for k in range(int(bounces.max(initial=0))):
        digit = rest % 3
        rest = rest // 3
        out += np.where(k < bounces, digit * 3 ** np.maximum(bounces - 1 - k, 0), 0)
    return np.where(code < 0, -1, out)


def reciprocal_width(
    dz_dth: FloatArray, th_s: FloatArray, th_r: FloatArray, c_s: FloatArray, c_r: FloatArray
) -> FloatArray:
    """The ray-tube width (m/rad) at the source of rays travelled backwards from the receiver,
    from theirs at the receiver ``dz_dth`` = dz_R / dth_S, launch and arrival angles th_s, th_r
    (rad) and end speeds c_s, c_r (m/s): by the reciprocity of the ray propagator, dz_S / dth_R
    = dz_R / dth_S c_S cos th_R / (c_R cos th_S)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        out: FloatArray = dz_dth * c_s * np.cos(th_r) / (c_r * np.cos(th_s))
    return out


def reversed_rows(rows: FloatArray) -> FloatArray:
    """Eigenray rows (..., NF) of links seen from the other end: the same rays travelled
    backwards (launch and arrival angles swapped and negated, the end speeds swapped, the bounce
    sequence reversed, the ray-tube width at the other end by :func:`reciprocal_width`)."""
    from . import _rangedep_search_jit as jit

    out = rows.copy()
    th0, thr = rows[..., jit.F_THETA0], rows[..., jit.F_THETAR]
    cs, cr = rows[..., jit.F_CS], rows[..., jit.F_CR]
    out[..., jit.F_THETA0], out[..., jit.F_THETAR] = -thr, -th0
    out[..., jit.F_CS], out[..., jit.F_CR] = cr, cs
    out[..., jit.F_DZDTH] = reciprocal_width(rows[..., jit.F_DZDTH], th0, thr, cs, cr)
    code = rows[..., jit.F_CODE]
    known = np.isfinite(code)
    nb = np.where(known, rows[..., jit.F_NS] + rows[..., jit.F_NB], 0).astype(np.int64)
    out[..., jit.F_CODE] = np.where(known, reversed_code(np.where(known, code, -1).astype(np.int64), nb), np.nan)
    out[..., jit.F_ZMISS] = np.nan
    return out


def follow_ends(
    env: Environment,
    src_from: ArrayLike,
    src: ArrayLike,
    dst: ArrayLike,
    max_bounces: int,
    theta0: FloatArray,
    code: NDArray[np.int64],
) -> tuple[FloatArray, NDArray[np.bool_], Sections]:
    """:func:`follow`, and where that loses an eigenray of a link whose source moved from
    ``src_from``, the link again in two legs: the receiver's move from the source where it was
    (the old launch angles, a short Newton iteration on the depth miss), then the source's move followed
    backwards from the receiver (the reversed link, launched at the first leg's arrival angles;
    reciprocity: the same eigenrays). From a moved source the old launch angle of a ray near a
    boundary or a turning point often falls into another bounce sequence, where one leg gives
    up; the old arrival angle reaches a moved receiver by a short iteration. Every leg keeps an
    eigenray only where its launch angle (from the end that stays) moved by less than half the
    gap to its nearest sibling (:func:`kept_apart`). Returns what :func:`follow` does, for the
    links src -> dst."""
    from . import _rangedep_search_jit as jit

    s0 = np.asarray(src_from, dtype=float).reshape(-1, 3)
    s1 = np.asarray(src, dtype=float).reshape(-1, 3)
    d1 = np.asarray(dst, dtype=float).reshape(-1, 3)
    rows, ok, sec = follow(env, s1, d1, max_bounces, theta0, code)
    ok &= kept_apart(theta0, rows[..., jit.F_THETA0], code)
    used = np.asarray(code) >= 0
    # the two legs where following from the moved source lost an eigenray
    redo = np.flatnonzero(np.any(s1 != s0, axis=1) & np.any(used & ~ok, axis=1))
    if not redo.size:
        return rows, ok, sec
    ra, oka, _ = follow(env, s0[redo], d1[redo], max_bounces, theta0[redo], code[redo])
    oka &= kept_apart(theta0[redo], ra[..., jit.F_THETA0], code[redo])
    back = reversed_rows(ra)
    back_code = np.where(oka, np.nan_to_num(back[..., jit.F_CODE], nan=-1.0), -1.0).astype(np.int64)
    back_th = back[..., jit.F_THETA0]
    rb, okb, _ = follow(env, d1[redo], s1[redo], max_bounces, back_th, back_code)
    okb &= kept_apart(back_th, rb[..., jit.F_THETA0], back_code)
    rows[redo] = reversed_rows(rb)
    ok[redo] = oka & okb
    return rows, ok, sec


def track(
    env: Environment,
    src: ArrayLike,
    dst: ArrayLike,
    max_bounces: int,
    theta0: FloatArray,
    code: NDArray[np.int64],
) -> FloatArray:
    """Delays (n, Q) of known eigenrays followed to the links src -> dst (:func:`follow`); NaN
    where one could not be followed."""
    from . import _rangedep_search_jit as jit

    rows, _ok, _sec = follow(env, src, dst, max_bounces, theta0, code)
    return rows[:, :, jit.F_TIME]
