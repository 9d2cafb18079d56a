"""Per-link arrival cache over positions: a second-order Taylor expansion with an error bound
near the point where a link was searched, the exact following of its eigenrays further away.

In the spirit of WOSS's channel cache. The arrivals of a link (:func:`.arrivals.arrivals`) are
searched at reference positions x0 = (s0, d0); a later request for the same link at x = (s, d)
is served, cheapest first, by

0. the last solution itself, at the very positions it was solved for (moored nodes);
1. **Taylor** (``tol_s`` > 0), while |x - x0| <= 0.5 m, the bound below is <= ``tol_s`` and the
   link's section keeps its structure (below): each delay as

       t(x) = t0 + g . (x - x0) + 1/2 (x - x0)' H (x - x0),

   x the six end coordinates (source x, y, z, then receiver x, y, z);
2. **following** (``follow_m`` > 0), while each end stays within ``follow_m`` of where the link
   was last searched: each eigenray of the last solution followed to (s, d) from its launch
   angle by a few secant steps on the depth miss (:func:`.arrivals.follow`: exact delays,
   levels and angles; with ``follow_back``, a moved source's move backwards from the receiver
   where following it forwards loses an eigenray, :func:`.rangedep.follow_ends`), unless one
   cannot be followed (its bounce sequence changed: a path about to vanish) or may have been
   followed onto a sibling of its bounce sequence (a fold: it moved by half the gap to one, or
   farther than its ray-tube width allows for the move, :func:`.rangedep.turned_within`), or a
   fold in the making may have brought two new eigenrays, or one may have entered a family
   across its edge: the last search's watched intervals (:func:`.rangedep.watch`: stretches of
   a family where a lower bound on the depth miss at an extremum, its margin, was below 2 m
   per metre of ``follow_m``, at least 2 m; and family edges where the miss heading for zero
   beyond the edge was that near it) whose margin the miss may have crossed since the search
   (2 m per metre the farther end moved, at least 2 m) are checked again at (s, d) with the
   followed eigenrays, and a link where one fails is searched;
3. **searching** again, which resets the reference positions and the expansion.

A search is expanded (the stencil below, which costs about as much as following the link 13
times: ~7.6 ms against ~0.56 ms on the shelf-break benchmark) only where that can pay: at a
link's first request, and where its ends moved since its last request by at most 0.5 m / 13
(a link moving faster leaves the Taylor region before the expansion has paid for itself; it is
followed instead). ``stats.not_expanded`` counts the searches this skipped.

Expansion. g and H are those of the link's N x 2-D travel time, from the exact solutions at a
stencil of 18 points: each of the six coordinates moved by +-h (h = 0.5 m), both ends moved
sideways together by +-h, and each end sideways by +-h/2, every eigenray followed there (a
source's move backwards from the receiver where following it from the moved source loses it).
g: in the link's vertical plane the slowness vectors at the ends (Fermat: -(cos th_S u, sin th_S)
/ c_S at the source, (cos th_R u, sin th_R) / c_R at the receiver, u the plane's horizontal unit
vector), across it a central difference of the delays (moving an end sideways turns the plane,
which then samples another part of a front or a flank). H: central differences of the exact
in-plane gradients along each axis (each stencil point's own plane), symmetrized; the sideways
block from second differences of the delays.

Error bound, for a move r = |x - x0| <= h:

    |error| <= 1e-12 s + a1 r + a2 r^2 + a3 r^3,

a3 = M3 / 6 the third-order remainder, M3 a bound on the delay's third derivative: the larger of
eight times a straight ray's (2 sqrt(2) (2 / sqrt(3)) / (c_min L^2), L = D - 2 h the shortest the
link gets over the region) and twice the third derivatives the stencil itself measured (along
the in-plane axes from the gradients, across from the five sideways delays of each end);
a2 = 1/2 ||dH||, the Hessian's error: central differences (sqrt(6) h^2 / 6 M4, M4 eight times a
straight ray's 12 / (c_min L^3)), the in-plane block's asymmetry, the delays' own error in the
second differences; a1 = sqrt(2) h^2 / 6 M3, the sideways gradients' central-difference error.
The factor of eight is measured, not derived (refraction, and reflections off a sloping floor,
which turn the image sources as an end moves, curve the delays more than a straight ray does);
on the shelf-break sample the stencil's own third derivatives exceed it on most links and then
set the bound.

Smoothness. A Taylor bound needs smooth delays, and the model's are smooth only piecewise: the
section of a link changes its columns where an end, or the turning plane, brings a kink of the
environment (a grid line of a gridded floor or field) in or out of it or past another one, and
where one of its cells changes how it is cut; the delays' slopes may jump there (measured on the
shelf-break benchmark with this guard off: served errors up to 110x the bound, 6.9e-7 s, on
links running nearly along a grid axis, whose sections reach kinks tens of kilometres away). So
the Taylor tier serves a link only while its section's structure
(:attr:`.rangedep.Sections.structure`) is the reference's, and only if it was the same at every
stencil point, and the second differences across the plane over h and h/2 agree (else the slope
jumps in between). Not seen: a jump that changes none of these and lies between the stencil's
points (none found on the shelf-break benchmark, docs/channel.md).

Arrival-set changes. The stencil doubles as a guard: a link with an eigenray that cannot be
followed to one of its points, or followed onto a sibling of its bounce sequence, or with a
bottom reflection point near a point where the floor's slope or curvature jumps (a polyline's
vertex, where the delay's gradient jumps; a curved floor's arc junctions, where its Hessian does:
within 2 h, more where the stencil shows the point moving faster than the ends, as it does at
low grazing angles), is never served by Taylor; searched again within 2 h of where it was refused, it is not
expanded again (the stencil would most likely be refused again, and costs twice the search). A
link without arrivals is served as such within the region. The Taylor tier does not detect a
path that appears (a new eigenray) inside its region, nor the following tier one that appears
other than at a watched fold or edge (at an extremum or an edge whose miss was farther than 2 m
from zero: rays grazing a steep flank, whose miss moves tens of metres for a metre's move); how
often that changes the modem's stamp is measured by ``python
tools/follow_radius.py`` (docs/channel.md).

Levels and angles served by Taylor are the reference's (they vary on scales of metres, not of
the delay's 1e-7 s). Vectorized: links are integer ids, each given a slot in growing arrays;
no Python loop over links.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import arrivals as _arrivals
from . import rangedep
from ._rangedep_search_jit import NW, WATCH_ROWS
from .arrivals import Arrivals
from .environment import Environment

__all__ = ["TIERS", "ArrivalCache", "CacheStats"]

_IU = np.triu_indices(6)
_IU_WEIGHT = np.where(_IU[0] == _IU[1], 0.5, 1.0)  # 1/2 delta' H delta from the upper triangle

_STENCIL_M = 0.5  # the stencil's step, and the farthest each end may move for the Taylor tier
_SAFETY = 8.0  # third and fourth derivatives allowed over a straight ray's, see the module docstring
_D3_STRAIGHT = 2.0 * 2.0**0.5 * 2.0 / 3.0**0.5  # |d^3 (L / c)| <= this / (c L^2) over both ends' moves
_D4_STRAIGHT = 12.0  # |d^4 (L / c)| <= this / (c L^3)
_SOLVER_S = 1e-12  # the eigenray solver's own accuracy, added to the bound
# an expansion (18 stencil points) costs about as much as following the link this many times
# (measured on the shelf-break benchmark: ~7.6 ms against ~0.56 ms); it pays only for a link
# requested at least that often inside its region
_EXPANSION_FOLLOWS = 13.0
#: the per-arrival fields of an Arrivals the cache keeps (padded per slot)
_FLOAT_FIELDS = (
    "delay",
    "level_db",
    "launch_angle",
    "arrival_angle",
    "length",
    "bottom_loss_db",
    "source_speed",
    "receiver_speed",
    "dz_dlaunch",
    "floor_kink_distance",
)
_INT_FIELDS = ("surface_bounces", "bottom_bounces", "path_class", "bounce_code")


def _slot_arrays(A: int) -> tuple[tuple[str, tuple[int, ...], float, type], ...]:
    """(attribute, shape per slot, fill, dtype) of the per-slot arrays besides the tables; A the
    Taylor tables' width (0 without the Taylor tier)."""
    return (
        ("_s0", (3,), np.nan, float),  # Taylor reference ends
        ("_d0", (3,), np.nan, float),
        ("_sa", (3,), np.nan, float),  # where last searched
        ("_da", (3,), np.nan, float),
        ("_sl", (3,), np.nan, float),  # the last solution's ends
        ("_dl", (3,), np.nan, float),
        ("_coef", (3,), np.inf, float),  # the bound's coefficients of |delta|, ^2, ^3; inf: no Taylor
        ("_radius", (), 0.0, float),  # the largest |delta| the Taylor tier serves, m
        ("_struct", (), 0, np.uint64),  # the reference section's structure (rangedep.Sections)
        ("_refused", (6,), np.nan, float),  # the ends where the Taylor tier last refused the link
        ("_xq", (6,), np.nan, float),  # the ends of the link's last request
        ("_t0", (A,), np.nan, float),  # reference delays
        ("_g", (A, 6), 0.0, float),  # their gradients, s/m
        ("_H", (A, 21), 0.0, float),  # their Hessians (upper triangle, row by row), s/m^2
        ("_n", (), 0, np.int64),  # arrivals of the last solution
        # the last search's watched intervals (rangedep.watch): where a fold may bring two new
        # eigenrays; their count; whether they are the reverse link's (searched from this
        # link's receiver: the following tier then reached the link from its reverse)
        ("_watch", (WATCH_ROWS, NW), np.nan, float),
        ("_nwatch", (), 0, np.int64),
        ("_wrev", (), False, np.bool_),
    )


#: what served a link (:attr:`ArrivalCache.served_by`, an index into this)
TIERS = ("taylor", "same", "follow", "reverse", "search")
_TAYLOR, _SAME, _FOLLOW, _REVERSE, _SEARCH = range(len(TIERS))


@dataclass
class CacheStats:
    hits: int = 0  #: served by the Taylor expansion
    follows: int = 0  #: served by following the last solution's eigenrays
    misses: int = 0  #: searched
    uncacheable: int = 0  #: searches after which the Taylor tier refused a link (unstable or not smooth)
    not_expanded: int = 0  #: searches not expanded: the link moved too far per request for it to pay
    reversed: int = 0  #: of the follows, those from the reverse link's solution (``n_nodes``)

    @property
    def hit_rate(self) -> float:
        """Share of the requests served without a search (Taylor or following)."""
        n = self.hits + self.follows + self.misses
        return (self.hits + self.follows) / n if n else 0.0


@dataclass
class ArrivalCache:
    """Arrivals of links ``0 .. n_links-1`` (the caller's ids, e.g. src * n_nodes + dst).

    tol_s: the Taylor tier's error bound (s); 0 turns it off (every request exact), fixed at
    construction (the Taylor tables are allocated only when it is > 0). follow_m:
    the following tier's radius (m) around the last search; 0 turns it off (a search keeps the
    watched intervals a move within it may need, :func:`.rangedep.watch_reach`). follow_back: where
    following a moved source loses an eigenray, follow the link again in two legs
    (:func:`.rangedep.follow_ends`) instead of searching it: far more links followed, but a
    failing one-leg follow often marks a changing arrival set, and without it the modem's stamp
    differs from a new search's more often (docs/channel.md, ``tools/follow_radius.py``).
    max_arrivals: the per-link tables' initial width; they widen to the most arrivals a link has.
    After each :meth:`get`, ``served_by`` holds, per requested link, the index in :data:`TIERS` of
    what served it."""

    env: Environment
    n_links: int
    max_bounces: int = 2
    tol_s: float = 1e-7
    frequency_khz: float = 10.0
    spreading: str | float = "ray"
    max_arrivals: int = 24
    follow_m: float = 1.0
    follow_back: bool = False
    n_nodes: int = 0
    stats: CacheStats = field(default_factory=CacheStats)
    served_by: NDArray[np.int8] = field(init=False, repr=False)
    # per-slot arrays (_resize); the last solution's fields in _tab
    _s0: NDArray[np.float64] = field(init=False, repr=False)
    _d0: NDArray[np.float64] = field(init=False, repr=False)
    _sa: NDArray[np.float64] = field(init=False, repr=False)
    _da: NDArray[np.float64] = field(init=False, repr=False)
    _sl: NDArray[np.float64] = field(init=False, repr=False)
    _dl: NDArray[np.float64] = field(init=False, repr=False)
    _coef: NDArray[np.float64] = field(init=False, repr=False)
    _radius: NDArray[np.float64] = field(init=False, repr=False)
    _struct: NDArray[np.uint64] = field(init=False, repr=False)
    _refused: NDArray[np.float64] = field(init=False, repr=False)
    _xq: NDArray[np.float64] = field(init=False, repr=False)
    _t0: NDArray[np.float64] = field(init=False, repr=False)
    _g: NDArray[np.float64] = field(init=False, repr=False)
    _H: NDArray[np.float64] = field(init=False, repr=False)
    _n: NDArray[np.int64] = field(init=False, repr=False)
    _watch: NDArray[np.float64] = field(init=False, repr=False)
    _nwatch: NDArray[np.int64] = field(init=False, repr=False)
    _wrev: NDArray[np.bool_] = field(init=False, repr=False)
    _tab: dict[str, NDArray] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if int(self.n_links) < 1 or int(self.max_arrivals) < 1:
            raise ValueError("ArrivalCache: n_links and max_arrivals must be >= 1")
        if not self.tol_s >= 0.0:
            raise ValueError(f"ArrivalCache: tol_s must be >= 0, got {self.tol_s!r}")
        if not self.follow_m >= 0.0:
            raise ValueError(f"ArrivalCache: follow_m must be >= 0, got {self.follow_m!r}")
        if int(self.n_nodes) < 0 or (self.n_nodes and int(self.n_nodes) ** 2 > int(self.n_links)):
            raise ValueError(f"ArrivalCache: n_nodes must be >= 0 with n_nodes^2 <= n_links, got {self.n_nodes!r}")
        self._slot: dict[int, int] = {}
        self._cap, self._width = 0, 0
        self._resize(64, int(self.max_arrivals))
        self.served_by = np.zeros(0, np.int8)

    # ----------------------------------------------------------------- public
    def get(self, links: ArrayLike, src: ArrayLike, dst: ArrayLike) -> Arrivals:
        """Arrivals of ``links`` (n,) between ``src`` and ``dst`` (n, 3): from the cache where
        its tiers allow, else searched (and cached)."""
        ids = np.asarray(links, np.int64).ravel()
        s = np.asarray(src, float).reshape(-1, 3)
        d = np.asarray(dst, float).reshape(-1, 3)
        if not (ids.size == s.shape[0] == d.shape[0]):
            raise ValueError("ArrivalCache.get: links, src and dst differ in length")
        if ids.size and (ids.min() < 0 or ids.max() >= self.n_links):
            raise ValueError(f"ArrivalCache.get: link ids must be in [0, {self.n_links})")
        if np.unique(ids).size != ids.size:
            raise ValueError("ArrivalCache.get: a link id appears twice in one call")
        slots = self._slots(ids)
        hit = np.zeros(ids.size, bool)
        if self.tol_s > 0.0:
            delta = np.concatenate([s - self._s0[slots], d - self._d0[slots]], axis=1)
            with np.errstate(invalid="ignore"):
                hit = np.linalg.norm(delta, axis=1) <= self._radius[slots]
        if hit.any():  # only while the section keeps the reference's structure, to second order
            h = np.flatnonzero(hit)
            hit[h] = rangedep.sections(self.env, s[h], d[h]).structure == self._struct[slots[h]]
            h = h[hit[h]]
            dh = delta[h]
            quad = dh[:, _IU[0]] * dh[:, _IU[1]] * _IU_WEIGHT
            taylor = self._t0[slots[h]] + np.einsum("naj,nj->na", self._g[slots[h]], dh)
            taylor += np.einsum("naq,nq->na", self._H[slots[h]], quad)
        # the very positions of the last solution (a link between moored nodes): as it is
        same = np.all(s == self._sl[slots], axis=1) & np.all(d == self._dl[slots], axis=1) & ~hit
        self.stats.hits += int(hit.sum()) + int(same.sum())
        tier = np.where(hit, _TAYLOR, _SAME).astype(np.int8)
        rest = np.flatnonzero(~(hit | same))
        if rest.size:
            done, close = self._follow(slots[rest], s[rest], d[rest])
            tier[rest[done]] = _FOLLOW
            # from the reverse only links not near their own search: where following that failed,
            # the arrival set is changing (a path about to vanish, a fold), and is searched
            far = np.flatnonzero(~close)
            if far.size and self.n_nodes > 0:
                r = rest[far]
                done[far] = self._follow_reverse(ids[r], slots[r], s[r], d[r])
                tier[r[done[far]]] = _REVERSE
                self.stats.reversed += int(done[far].sum())
            self.stats.follows += int(done.sum())
            rest = rest[~done]
        if rest.size:
            self.stats.misses += int(rest.size)
            tier[rest] = _SEARCH
            self._fill(slots[rest], s[rest], d[rest])
        # the Taylor tier serves from the reference solution, the others from the last one (the
        # tables may have widened since the Taylor delays were computed)
        delay = self._tab["delay"][slots]
        if hit.any():
            delay[h, : taylor.shape[1]] = taylor
        if self.tol_s > 0.0:  # only the expansion's cost rule reads it
            self._xq[slots] = np.concatenate([s, d], axis=1)
        self.served_by = tier
        return self._serve(slots, delay)

    def bound(self, links: ArrayLike, src: ArrayLike, dst: ArrayLike) -> NDArray[np.float64]:
        """The error bound (s) the Taylor tier would give for serving these positions (inf:
        it would not serve them)."""
        ids = np.asarray(links, np.int64).ravel()
        slots = np.array([self._slot.get(int(i), 0) for i in ids.tolist()], np.int64)
        known = np.array([int(i) in self._slot for i in ids.tolist()], bool)
        ds = np.asarray(src, float).reshape(-1, 3) - self._s0[slots]
        dd = np.asarray(dst, float).reshape(-1, 3) - self._d0[slots]
        r = np.sqrt((ds * ds).sum(axis=1) + (dd * dd).sum(axis=1))
        with np.errstate(invalid="ignore"):
            b = _bound(self._coef[slots], r)
            inside = r <= self._radius[slots]
        return np.where(known & inside, b, np.inf)

    def last(self, links: ArrayLike) -> Arrivals:
        """Each link's cached solution, as last searched or followed (for a link the Taylor
        tier serves, its reference)."""
        return self._last(self._known_slots(links, "last"))

    def positions(self, links: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(src, dst) (n, 3): the positions each link's :meth:`last` solution was solved at."""
        slots = self._known_slots(links, "positions")
        return self._sl[slots].copy(), self._dl[slots].copy()

    def _known_slots(self, links: ArrayLike, caller: str) -> NDArray[np.int64]:
        """The slots of links requested before (ValueError naming ``caller`` otherwise)."""
        ids = np.asarray(links, np.int64).ravel().tolist()
        unknown = [i for i in ids if i not in self._slot]
        if unknown:
            raise ValueError(f"ArrivalCache.{caller}: link {unknown[0]} was never requested")
        return np.array([self._slot[i] for i in ids], np.int64)

    def radius(self, links: ArrayLike) -> NDArray[np.float64]:
        """The largest move sqrt(|s - s0|^2 + |d - d0|^2) (m) of each link the Taylor tier
        serves (0: none)."""
        ids = np.asarray(links, np.int64).ravel()
        return np.array([self._radius[self._slot[i]] if i in self._slot else 0.0 for i in ids.tolist()])

    # ----------------------------------------------------------------- storage
    def _resize(self, cap: int, width: int) -> None:
        """Room for ``cap`` slots of ``width`` arrivals each (the arrays keep their contents; the
        Taylor tables only with the Taylor tier on)."""
        old = self._cap

        def grown(a: NDArray | None, shape: tuple[int, ...], fill: float, dtype: type = float) -> NDArray:
            out: NDArray = np.full((cap, *shape), fill, dtype=dtype)
            if a is not None:
                out[(slice(0, old), *(slice(0, k) for k in a.shape[1:]))] = a[:old]
            return out

        for name, shape, fill, dtype in _slot_arrays(width if self.tol_s > 0.0 else 0):
            setattr(self, name, grown(getattr(self, name, None), shape, fill, dtype))
        tab = getattr(self, "_tab", {})
        self._tab = {f: grown(tab.get(f), (width,), np.nan) for f in _FLOAT_FIELDS}
        self._tab.update({f: grown(tab.get(f), (width,), -1, np.int64) for f in _INT_FIELDS})
        self._cap, self._width = cap, width

    def _slots(self, ids: NDArray[np.int64]) -> NDArray[np.int64]:
        """The slot of each link id, new ones assigned (a dict lookup per link)."""
        slot = self._slot
        out = [slot.setdefault(i, len(slot)) for i in ids.tolist()]
        if len(slot) > self._cap:
            self._resize(max(2 * self._cap, len(slot)), self._width)
        return np.asarray(out, np.int64)

    def _store(self, slots: NDArray[np.int64], arr: Arrivals) -> None:
        """Keep ``arr`` (one link per slot) as the slots' last solution (the tables widened to
        hold its most arrivals)."""
        n = slots.size
        cnt = np.diff(arr.offsets)
        if cnt.size and int(cnt.max()) > self._width:
            self._resize(self._cap, int(cnt.max()))
        A = self._width
        rows = np.repeat(np.arange(n), cnt)
        col = np.arange(arr.delay.size) - arr.offsets[:-1][rows]
        for f in _FLOAT_FIELDS:
            t = np.full((n, A), np.nan)
            t[rows, col] = getattr(arr, f)
            self._tab[f][slots] = t
        for f in _INT_FIELDS:
            t = np.full((n, A), -1, np.int64)
            t[rows, col] = getattr(arr, f)
            self._tab[f][slots] = t
        self._n[slots] = cnt

    def _last(self, slots: NDArray[np.int64]) -> Arrivals:
        """The slots' last solutions as an Arrivals (one link per slot)."""
        return self._serve(slots, self._tab["delay"][slots])

    # ----------------------------------------------------------------- tiers
    def _followable(self, slots: NDArray[np.int64]) -> NDArray[np.bool_]:
        """Whether the slots' last solutions can be followed: some arrival."""
        return self._n[slots] > 0

    def _clear(
        self, wslots: NDArray[np.int64], s: NDArray, d: NDArray, flip: bool, known: Arrivals, reach: NDArray
    ) -> NDArray[np.bool_]:
        """Whether the watched intervals of ``wslots`` (the last searches' folds in the making)
        still hold no eigenray but the ``known`` ones (one link per slot, followed there) for
        links with ends (s, d): the slots' own links (``flip`` False) or their reverses (True),
        each watch checked in the direction it was searched, those intervals whose margin is
        below ``reach`` (m; how far the miss may have moved since the search,
        :func:`.rangedep.watch_reach` of the farther end's move)."""
        clear = np.ones(wslots.size, bool)
        has = self._nwatch[wslots] > 0
        if not has.any():
            return clear
        ws = wslots[has]
        back = self._wrev[ws] != flip
        src, dst = np.where(back[:, None], d[has], s[has]), np.where(back[:, None], s[has], d[has])
        mine = _links_of(known, has)
        th, cd = _arrivals.launch_table(mine)
        if back.any():  # those links' eigenrays as seen from the other end, where it was searched
            rth, rcd = _arrivals.launch_table(_arrivals.reversed_arrivals(_links_of(mine, back)))
            th[back], cd[back] = np.nan, -1
            th[back, : rth.shape[1]], cd[back, : rcd.shape[1]] = rth, rcd
        clear[has] = rangedep.watch(
            self.env, src, dst, self.max_bounces, self._watch[ws], self._nwatch[ws], th, cd, reach[has]
        )
        return clear

    def _follow_from(
        self,
        slots: NDArray[np.int64],
        prev: Arrivals,
        s: NDArray,
        d: NDArray,
        moved: NDArray,
        src_from: NDArray | None = None,
        wslots: NDArray[np.int64] | None = None,
    ) -> NDArray[np.bool_]:
        """Follow ``prev`` (one link per slot) to (s, d) and keep it as the slots' last solution
        where every arrival was followed and no watched interval (of the slots, or of the
        reverse links' ``wslots``; ``moved``: the farther end's distance from where they were
        searched, m) may hold new eigenrays (True there)."""
        reach = rangedep.watch_reach(moved)  # how far the miss at a fixed angle may have moved
        got, ok = _arrivals.follow(
            self.env,
            prev,
            s,
            d,
            max_bounces=self.max_bounces,
            frequency_khz=self.frequency_khz,
            spreading=self.spreading,
            src_from=src_from,
            reach=reach,
        )
        if ok.any():
            idx = np.flatnonzero(ok)
            fol = _links_of(got, ok)
            wsub = slots[idx] if wslots is None else wslots[idx]
            clear = self._clear(wsub, s[idx], d[idx], wslots is not None, fol, reach[idx])
            ok[idx[~clear]] = False
            if ok.any():
                sub = slots[ok]
                self._store(sub, _links_of(fol, clear))
                self._sl[sub], self._dl[sub] = s[ok], d[ok]
                self._radius[sub] = 0.0  # the Taylor reference no longer matches the tables
        return ok

    def _follow(self, slots: NDArray[np.int64], s: NDArray, d: NDArray) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
        """Serve by following where the ends are within follow_m of the last search: (done (the
        last solution then holds the followed arrivals), close (the ends within follow_m))."""
        with np.errstate(invalid="ignore"):
            moved = _moved(s, d, self._sa[slots], self._da[slots])
            close = moved <= self.follow_m
        idx = np.flatnonzero(close & self._followable(slots))
        done = np.zeros(slots.size, bool)
        if idx.size:
            sub = slots[idx]
            src_from = self._sl[sub] if self.follow_back else None
            done[idx] = self._follow_from(sub, self._last(sub), s[idx], d[idx], moved[idx], src_from)
        return done, close

    def _follow_reverse(
        self, ids: NDArray[np.int64], slots: NDArray[np.int64], s: NDArray, d: NDArray
    ) -> NDArray[np.bool_]:
        """Serve by following the reverse link's last solution travelled backwards where both
        ends are within follow_m of where the reverse was last searched (its receiver there this
        link's source); True where done. The link's following centre becomes that search's ends."""
        n = int(self.n_nodes)
        rev = (ids % n) * n + ids // n
        rslot = np.array([self._slot.get(i, -1) for i in rev.tolist()], np.int64)
        done = np.zeros(ids.size, bool)
        known = np.flatnonzero(rslot >= 0)
        rs = rslot[known]
        with np.errstate(invalid="ignore"):
            moved = _moved(s[known], d[known], self._da[rs], self._sa[rs])
            near = (moved <= self.follow_m) & self._followable(rs)
        idx = known[near]
        if idx.size:
            prev = _arrivals.reversed_arrivals(self._last(rslot[idx]))
            done[idx] = self._follow_from(slots[idx], prev, s[idx], d[idx], moved[near], wslots=rslot[idx])
            sub, rsub = slots[idx[done[idx]]], rslot[idx[done[idx]]]
            self._sa[sub], self._da[sub] = self._da[rsub], self._sa[rsub]
            # the reverse's watch, now the link's, in the reverse's direction
            self._watch[sub], self._nwatch[sub], self._wrev[sub] = (
                self._watch[rsub],
                self._nwatch[rsub],
                ~self._wrev[rsub],
            )
        return done

    def _fill(self, slots: NDArray[np.int64], s: NDArray, d: NDArray) -> None:
        """Search the links of ``slots`` at (s, d): their new reference (and, with the Taylor
        tier on, its gradients and bound) and watched intervals."""
        arr, watch, nwatch = _arrivals.watched_arrivals(
            self.env,
            s,
            d,
            max_bounces=self.max_bounces,
            frequency_khz=self.frequency_khz,
            spreading=self.spreading,
            watch_m=float(rangedep.watch_reach(self.follow_m)),
        )
        self._store(slots, arr)
        self._watch[slots], self._nwatch[slots], self._wrev[slots] = watch, nwatch, False
        self._reference(slots, s, d, s, d)

    def _reference(self, slots: NDArray[np.int64], s: NDArray, d: NDArray, sa: NDArray, da: NDArray) -> None:
        """The slots' last solutions, solved at (s, d), become their reference; (sa, da): where
        their arrival set was last searched (the following tier's centre)."""
        self._sa[slots], self._da[slots] = sa, da
        self._sl[slots], self._dl[slots] = s, d
        self._s0[slots], self._d0[slots] = s, d
        self._coef[slots] = np.inf
        self._radius[slots] = 0.0
        if self.tol_s <= 0.0:
            return
        self._t0[slots] = self._tab["delay"][slots]
        self._g[slots] = 0.0
        self._H[slots] = 0.0
        sec = rangedep.sections(self.env, s, d)
        self._struct[slots] = sec.structure
        # a link refused within 2 h of here is not expanded again (its stencil would most likely
        # be refused again: a changing arrival set or structure nearby; searching it is the cost)
        x = np.concatenate([s, d], axis=1)
        with np.errstate(invalid="ignore"):
            todo = ~(np.linalg.norm(x - self._refused[slots], axis=1) <= 2.0 * _STENCIL_M)
            # nor a link that moved since its last request more than the region's radius over
            # the requests the expansion must serve to pay for itself (at its next requests the
            # link would be followed for less; a link requested for the first time is expanded)
            fast = np.linalg.norm(x - self._xq[slots], axis=1) > _STENCIL_M / _EXPANSION_FOLLOWS
        self.stats.uncacheable += int((~todo).sum())
        self.stats.not_expanded += int((todo & fast).sum())
        todo &= ~fast
        if not todo.any():
            return
        sub = slots[todo]
        u = np.stack([sec.ux[todo], sec.uy[todo], np.zeros(sub.size)], axis=1)
        coef, g, H = self._expansion(sub, s[todo], d[todo], u)
        self._coef[sub], self._g[sub], self._H[sub] = coef, g, H
        self._radius[sub] = _radius(coef, self.tol_s, _STENCIL_M)
        refused = ~(self._radius[sub] > 0.0)
        self._refused[sub] = np.where(refused[:, None], x[todo], np.nan)

    def _expansion(
        self, slots: NDArray[np.int64], s: NDArray, d: NDArray, u: NDArray
    ) -> tuple[NDArray, NDArray, NDArray]:
        """(bound coefficients (n, 3), gradients (n, A, 6), Hessians (n, A, 21)) of the Taylor
        tier at the searched (s, d), world coordinates (x, y, z of the source, then of the
        receiver); u (n, 3) the links' horizontal unit vectors (their sections'); coefficients
        inf where the link is not served (module docstring)."""
        from . import _rangedep_search_jit as jit

        n, A = slots.size, self._width
        tab = self._tab
        h = _STENCIL_M
        cnt = self._n[slots]
        valid = np.arange(A)[None, :] < cnt[:, None]
        t0 = tab["delay"][slots]
        ths, cb = tab["launch_angle"][slots], np.where(valid, tab["bounce_code"][slots], -1)
        # the link's frame: u along it (horizontal), v across it, z down; one unit vector per
        # axis of the six end coordinates (su, sv, sz, du, dv, dz), in world coordinates
        v = np.stack([-u[:, 1], u[:, 0], np.zeros(n)], axis=1)
        z = np.broadcast_to([0.0, 0.0, 1.0], (n, 3))
        zero = np.zeros((n, 3))
        axes = [np.concatenate(p, axis=1) for p in ((u, zero), (v, zero), (z, zero), (zero, u), (zero, v), (zero, z))]
        B = np.stack(axes, axis=2)  # (n, 6 world, 6 frame)
        # the stencil: +-h along each axis, and (sv, dv) moved together both ways
        steps = [sgn * ax for ax in axes for sgn in (1.0, -1.0)]
        steps += [axes[1] + axes[4], -(axes[1] + axes[4])]
        # and each end sideways by +-h/2: is the delay smooth across the plane? (The section of a
        # turned plane can change its columns, e.g. where it runs nearly along the lines of a
        # gridded field, and with them the delay's slope.)
        steps += [0.5 * axes[1], -0.5 * axes[1], 0.5 * axes[4], -0.5 * axes[4]]
        P = len(steps)
        X = np.concatenate([np.concatenate([s, d], axis=1) + h * st for st in steps])
        # a source's move that following from the moved source loses is followed backwards from
        # the receiver (rangedep.follow_ends; from a source moved up or down, the old launch angle
        # of a ray near a boundary or a turning point often falls into another bounce sequence)
        src_from = np.tile(s, (P, 1))
        th_in, code_in = np.tile(ths, (P, 1)), np.tile(cb, (P, 1))
        rows, ok, sec = rangedep.follow_ends(
            self.env,
            src_from,
            X[:, :3],
            X[:, 3:],
            self.max_bounces,
            th_in,
            code_in,
        )

        def at(field: int) -> NDArray:
            """A field of the followed rows (P, n, A); NaN where not followed (a bounce sequence
            changed, or the eigenray may have landed on a sibling: a fold)."""
            return np.where(ok, rows[:, :, field], np.nan).reshape(P, n, A)

        t = at(jit.F_TIME)
        th_s_p, th_r_p, c_s_p, c_r_p = at(jit.F_THETA0), at(jit.F_THETAR), at(jit.F_CS), at(jit.F_CR)
        # unstable: an arrival that cannot be followed to a stencil point (a path about to
        # vanish) or may have been followed onto a sibling
        stable = ~np.any(valid & np.isnan(t).any(axis=0), axis=1)
        # gradients at the searched ends: Fermat in the plane (the slowness vector at each end),
        # a central difference of the delays across it
        g_sv = (t[2] - t[3]) / (2.0 * h)
        g_dv = (t[8] - t[9]) / (2.0 * h)
        g = _fermat(u, ths, tab["arrival_angle"][slots], tab["source_speed"][slots], tab["receiver_speed"][slots])
        g += g_sv[:, :, None] * np.concatenate([v, zero], axis=1)[:, None, :]
        g += g_dv[:, :, None] * np.concatenate([zero, v], axis=1)[:, None, :]
        # the same at the twelve points along the axes, each in its own plane (its section's
        # direction; the sideways components there taken as at the centre: they enter the
        # in-plane columns below only through the plane's turn)
        Q = 12
        up = np.stack([sec.ux[: Q * n], sec.uy[: Q * n], np.zeros(Q * n)], axis=1)
        vp = np.stack([-up[:, 1], up[:, 0], up[:, 2]], axis=1)
        zq = np.zeros((Q * n, 3))

        def flat(a: NDArray) -> NDArray:
            return a[:Q].reshape(Q * n, A)

        gp = _fermat(up, flat(th_s_p), flat(th_r_p), flat(c_s_p), flat(c_r_p))
        gp += np.tile(g_sv, (Q, 1))[:, :, None] * np.concatenate([vp, zq], axis=1)[:, None, :]
        gp += np.tile(g_dv, (Q, 1))[:, :, None] * np.concatenate([zq, vp], axis=1)[:, None, :]
        gp = gp.reshape(Q, n, A, 6)
        # the Hessian in the link's frame: column k the central difference of the gradient along
        # axis k, read in the in-plane rows (su, sz, du, dz); the across rows by symmetry, except
        # (sv, sv), (dv, dv) and (sv, dv): second differences of the delays
        Hb = np.einsum("nwi,knaw->naik", B, (gp[0::2] - gp[1::2]) / (2.0 * h))
        inplane = np.array([0, 2, 3, 5])
        ip = np.ix_(inplane, inplane)
        asym = Hb[:, :, ip[0], ip[1]] - np.swapaxes(Hb[:, :, ip[0], ip[1]], 2, 3)
        sym = 0.5 * (Hb + np.swapaxes(Hb, 2, 3))
        H = np.zeros_like(Hb)
        H[:, :, ip[0], ip[1]] = sym[:, :, ip[0], ip[1]]
        for a in (1, 4):
            H[:, :, a, inplane] = Hb[:, :, inplane, a]
            H[:, :, inplane, a] = Hb[:, :, inplane, a]
        t0v = np.where(valid, t0, np.nan)
        H[:, :, 1, 1] = (t[2] - 2.0 * t0v + t[3]) / h**2
        H[:, :, 4, 4] = (t[8] - 2.0 * t0v + t[9]) / h**2
        H[:, :, 1, 4] = H[:, :, 4, 1] = (t[12] + t[13] - t[2] - t[3] - t[8] - t[9] + 2.0 * t0v) / (2.0 * h**2)
        H_world = np.einsum("nwi,naij,nvj->nawv", B, H, B)
        # third derivatives along the in-plane axes, seen by the same stencil points
        third = np.einsum(
            "nwi,knaw->naki", B[:, :, inplane], (gp[0::2][inplane] + gp[1::2][inplane] - 2.0 * g[None]) / h**2
        )
        k3 = np.sqrt(np.nanmax(np.where(valid, (third**2).sum(axis=(2, 3)), 0.0), axis=1, initial=0.0))
        k_asym = np.sqrt(np.nanmax(np.where(valid, (asym**2).sum(axis=(2, 3)), 0.0), axis=1, initial=0.0))
        # across the plane: the second differences over h and h/2 agree to (h / L)^2 for a smooth
        # delay (1e-3 of it is ample); where they do not, the slope jumps in between and no Taylor
        # bound holds. The same five points give the third derivative across.
        smooth = np.ones(n, bool)
        k3_side = np.zeros(n)
        for plus, minus, hp, hm in ((2, 3, 14, 15), (8, 9, 16, 17)):
            d2_h = (t[plus] - 2.0 * t0v + t[minus]) / h**2
            d2_q = (t[hp] - 2.0 * t0v + t[hm]) / (0.5 * h) ** 2
            with np.errstate(invalid="ignore"):
                bad = np.abs(d2_h - d2_q) > 1e-3 * np.abs(d2_h) + 1e-9
            smooth &= ~np.any(valid & bad, axis=1)
            d3 = (t[plus] - 2.0 * t[hp] + 2.0 * t[hm] - t[minus]) / (2.0 * (0.5 * h) ** 3)
            k3_side = np.maximum(k3_side, np.nanmax(np.where(valid, np.abs(d3), 0.0), axis=1, initial=0.0))
        # the bound's coefficients: straight-ray derivatives at the nearest the ends come over
        # the served region, times the safety factor, or twice what the stencil saw
        cmin = np.nanmin(
            np.where(valid, np.minimum(tab["source_speed"][slots], tab["receiver_speed"][slots]), np.inf),
            axis=1,
            initial=np.inf,
        )
        lmin = np.linalg.norm(d - s, axis=1) - 2.0 * h
        with np.errstate(divide="ignore", invalid="ignore"):
            m3 = np.maximum(_SAFETY * _D3_STRAIGHT / (cmin * lmin**2), 2.0 * np.maximum(k3, k3_side))
            m4 = _SAFETY * _D4_STRAIGHT / (cmin * lmin**3)
        # ||Hessian error||: central differences (sqrt(6) columns of h^2 / 6 m4 each), the in-plane
        # block's asymmetry, the delays' own error in the second differences
        dH = np.sqrt(6.0) * h**2 / 6.0 * m4 + k_asym + 8.0 * _SOLVER_S / h**2
        coef = np.stack([np.sqrt(2.0) * h**2 / 6.0 * m3, 0.5 * dH, m3 / 6.0], axis=1)
        # a bottom bounce near a jump of the floor's slope or curvature: the delay's gradient or
        # Hessian jumps where the reflection point crosses it, so no Taylor bound holds across
        # it. At a low grazing angle
        # the reflection point moves faster than the ends: its distance to the kink at the stencil
        # points gives the rate (a crossing between a pair of them shows as a fast one), and the
        # served region must stay clear of it by twice what that rate allows, 2 h at least
        k0 = tab["floor_kink_distance"][slots]
        with np.errstate(invalid="ignore"):
            moved = np.abs(at(jit.F_KINK) - k0[None]) / h  # (P, n, A) m per m of the ends' move
            per_axis = np.fmax(moved[0:12:2], moved[1:12:2])  # (6, n, A)
            rate = np.sqrt(np.nansum(per_axis**2, axis=0))  # |d point / d ends|, m/m
            rate = np.fmax(rate, np.nanmax(moved[12:14] / np.sqrt(2.0), axis=0, initial=0.0))
            rate = np.fmax(rate, np.nanmax(moved[14:] / 0.5, axis=0, initial=0.0))
            rate = np.where(np.isfinite(k0), rate, 0.0)
            near_kink = np.any(valid & (k0 <= 2.0 * h * (1.0 + rate)), axis=1)
        # a link without arrivals is served as such (like any served link, a path that appears
        # inside the served region is not detected)
        # the section's structure the same at every stencil point (else the differences
        # straddle a jump of the delays' slopes)
        smooth &= np.all(sec.structure.reshape(P, n) == self._struct[slots][None, :], axis=0)
        serve = stable & smooth & ~near_kink & (lmin > 0.0) & np.isfinite(coef).all(axis=1)
        self.stats.uncacheable += int((~(stable & smooth)).sum())
        coef[~serve] = np.inf
        return coef, np.nan_to_num(g), np.nan_to_num(H_world[:, :, _IU[0], _IU[1]])

    def _serve(self, slots: NDArray[np.int64], delay: NDArray) -> Arrivals:
        """Arrivals of ``slots`` from their tables, with delays ``delay`` (n, width) (in the
        tables' order; re-sorted here)."""
        n = slots.size
        cnt = self._n[slots]
        mask = np.arange(self._width)[None, :] < cnt[:, None]
        offsets = np.zeros(n + 1, np.int64)
        offsets[1:] = np.cumsum(cnt)
        # first-order moves keep the order except where two delays cross: re-sort per link
        tt = np.where(mask, delay, np.inf)
        order = np.argsort(tt, axis=1, kind="stable")
        picked = np.take_along_axis(mask, order, axis=1)

        def take(a: NDArray) -> NDArray:
            return np.take_along_axis(a, order, axis=1)[picked]

        tab = self._tab
        fields = {f: take(tab[f][slots]) for f in _FLOAT_FIELDS if f != "delay"}
        fields.update({f: take(tab[f][slots]) for f in _INT_FIELDS})
        fields["path_class"] = fields["path_class"].astype(np.int8)
        return Arrivals(
            shape=(n,),
            offsets=offsets,
            link=np.repeat(np.arange(n), cnt).astype(np.int64),
            delay=take(delay),
            **fields,
        )


def _moved(s: NDArray, d: NDArray, sa: NDArray, da: NDArray) -> NDArray:
    """The farther end's distance (m) from (sa, da) of links with ends (s, d) (NaN where those are)."""
    return np.sqrt(np.maximum(((s - sa) ** 2).sum(axis=1), ((d - da) ** 2).sum(axis=1)))


def _bound(coef: NDArray, r: NDArray) -> NDArray:
    """The Taylor tier's error bound (s) at a move r (m) from the reference, coef (n, 3) of r,
    r^2 and r^3 (module docstring)."""
    return _SOLVER_S + r * (coef[:, 0] + r * (coef[:, 1] + r * coef[:, 2]))


def _radius(coef: NDArray, tol: float, cap: float) -> NDArray:
    """The largest r <= cap with _bound(coef, r) <= tol (0 where none): bisection, the bound
    growing with r."""
    lo = np.zeros(coef.shape[0])
    hi = np.full(coef.shape[0], cap)
    with np.errstate(invalid="ignore"):
        whole = _bound(coef, hi) <= tol
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            ok = _bound(coef, mid) <= tol
            lo, hi = np.where(ok, mid, lo), np.where(ok, hi, mid)
        out = np.where(whole, cap, lo)
    return np.where(np.isfinite(coef).all(axis=1) & (tol >= _SOLVER_S), out, 0.0)


def _fermat(u: NDArray, th_s: NDArray, th_r: NDArray, c_s: NDArray, c_r: NDArray) -> NDArray:
    """(n, A, 6) the in-plane gradient of each delay (s/m) with respect to the ends: minus the
    slowness vector at the source, the slowness vector at the receiver (Fermat); u (n, 3) the
    plane's horizontal unit vector, angles (rad) and speeds (m/s) (n, A)."""
    ux, uy = u[:, None, 0], u[:, None, 1]
    return np.concatenate([-_arrivals.slowness(ux, uy, th_s, c_s), _arrivals.slowness(ux, uy, th_r, c_r)], axis=-1)


def _links_of(got: Arrivals, ok: NDArray[np.bool_]) -> Arrivals:
    """The links ``ok`` of ``got`` (one per row), as their own Arrivals, in order."""
    keep = ok[got.link]
    cnt = np.diff(got.offsets)[ok]
    return Arrivals(
        shape=(int(ok.sum()),),
        offsets=np.concatenate([[0], np.cumsum(cnt)]).astype(np.int64),
        link=np.repeat(np.arange(cnt.size), cnt).astype(np.int64),
        **{f: getattr(got, f)[keep] for f in Arrivals._FIELDS if f != "link"},
    )
