"""Per-link arrival cache over positions: a Taylor expansion with an error bound near the point
where a link was searched, the exact following of its eigenrays further away.

In the spirit of WOSS's channel cache. The arrivals of a link (:func:`.arrivals.arrivals`) are
searched at reference positions (s0, d0); a later request for the same link at (s, d) is
served, cheapest first, by

0. the last solution itself, at the very positions it was solved for (moored nodes);
1. **Taylor** (``tol_s`` > 0), while the ends stay close to (s0, d0): a first-order expansion of
   each delay,

       t(s, d) = t0 + g_s . (s - s0) + g_d . (d - d0),

   with an error bound <= ``tol_s`` (below);
2. **following** (``follow_m`` > 0), while each end stays within ``follow_m`` of where the link
   was last searched: each eigenray of the last solution followed to (s, d) from its launch
   angle by a few secant steps on the depth miss (:func:`.arrivals.follow`: exact delays, levels
   and angles, a tenth of a search's rays), unless one cannot be followed (its bounce sequence
   changed: a path about to vanish) or may have been followed onto a sibling of its bounce
   sequence (a fold);
3. **searching** again, which resets the reference positions.

Taylor gradients. g_s, g_d are the exact gradients of the link's N x 2-D travel time: in the
link's vertical plane the slowness vectors at the ends (Fermat: -(cos th_S u, sin th_S) / c_S at
the source, (cos th_R u, sin th_R) / c_R at the receiver, u the horizontal unit vector of the
link); across the plane (moving an end sideways turns the plane, which then samples another part
of a front or a flank) a central difference of the delays with that end moved by +-h = 0.5 m,
each eigenray followed there.

Taylor error bound. The remainder is at most 1/2 |H| |delta|^2, |delta|^2 = |s - s0|^2 +
|d - d0|^2, |H| the largest curvature of t over the move. For a straight ray |H| = 2 / (c L)
(L the end-to-end distance); the cache takes kappa = max(16 / (c_min D), 2 k_side) per link,
eight times the straight-ray value (refraction, and reflections off a sloping floor, which turn
the image sources as an end moves, curve the delays more: with four times, served errors up to
1.004x the bound were measured on the shelf-break benchmark, tools/bench_arrivals.py), and twice
the sideways curvatures seen by the central differences; plus 1e-12 s for the solver's own
accuracy. The factor is measured, not derived: the tests check the bound on random moves. A link
is served while 1/2 kappa |delta|^2 + 1e-12 s <= tol_s (default 1e-7 s).

Arrival-set changes. The sideways steps double as a guard: a link with an eigenray that cannot
be followed to +-h, or followed onto a sibling of its bounce sequence, or with a bottom
reflection point within twice the served radius of a kink of the floor polyline (where the
delay's gradient jumps), is never served by Taylor. Neither tier detects a path that appears (a
new eigenray) inside its radius. Measured on the shelf-break network (``python
tools/follow_radius.py --seeds 4 --nodes 20``: 1 520 links, both ends moved by r): at r = 1 m (the
default ``follow_m``) 39 % of the links are followed (the others searched again) and the first
arrival above a 10 dB detection threshold equals the new search's on every followed one (0 of
599); at 0.1 m 1 of 1 025 and at 3 m 3 of 360 differ, each time the search finding an earlier
detectable arrival. The two arrival sets differ more often (30 of 599 at 1 m), mostly where the
search itself misses a fold's pair of eigenrays that following keeps (docs/channel.md).

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
from .arrivals import Arrivals
from .environment import Environment

__all__ = ["ArrivalCache", "CacheStats"]

_SIDE_STEP_M = 0.5
_SAFETY = 8.0  # curvature allowed over a straight ray's 2 / (c L), see the module docstring
_SOLVER_S = 1e-12  # the eigenray solver's own accuracy, added to the bound
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
    """(attribute, shape per slot, fill, dtype) of the per-slot arrays besides the tables."""
    return (
        ("_s0", (3,), np.nan, float),  # Taylor reference ends
        ("_d0", (3,), np.nan, float),
        ("_sa", (3,), np.nan, float),  # where last searched
        ("_da", (3,), np.nan, float),
        ("_sl", (3,), np.nan, float),  # the last solution's ends
        ("_dl", (3,), np.nan, float),
        ("_kappa", (), np.inf, float),  # s/m^2; inf: no Taylor
        ("_t0", (A,), np.nan, float),  # reference delays
        ("_g", (A, 6), 0.0, float),  # their gradients
        ("_n", (), 0, np.int64),  # arrivals of the last solution
        # False where the last solution had more arrivals than a slot holds (never followed)
        ("_fits", (), False, bool),
    )


@dataclass
class CacheStats:
    hits: int = 0  #: served by the Taylor expansion
    follows: int = 0  #: served by following the last solution's eigenrays
    misses: int = 0  #: searched
    uncacheable: int = 0  #: searches of links whose arrival set is not stable sideways

    @property
    def hit_rate(self) -> float:
        """Share of the requests served without a search (Taylor or following)."""
        n = self.hits + self.follows + self.misses
        return (self.hits + self.follows) / n if n else 0.0


@dataclass
class ArrivalCache:
    """Arrivals of links ``0 .. n_links-1`` (the caller's ids, e.g. src * n_nodes + dst).

    tol_s: the Taylor tier's error bound (s); 0 turns it off (every request exact). follow_m:
    the following tier's radius (m) around the last search; 0 turns it off."""

    env: Environment
    n_links: int
    max_bounces: int = 2
    tol_s: float = 1e-7
    frequency_khz: float = 10.0
    spreading: str | float = "ray"
    max_arrivals: int = 24
    follow_m: float = 1.0
    stats: CacheStats = field(default_factory=CacheStats)
    # per-slot arrays (_grow); the last solution's fields in _tab
    _s0: NDArray[np.float64] = field(init=False, repr=False)
    _d0: NDArray[np.float64] = field(init=False, repr=False)
    _sa: NDArray[np.float64] = field(init=False, repr=False)
    _da: NDArray[np.float64] = field(init=False, repr=False)
    _sl: NDArray[np.float64] = field(init=False, repr=False)
    _dl: NDArray[np.float64] = field(init=False, repr=False)
    _kappa: NDArray[np.float64] = field(init=False, repr=False)
    _t0: NDArray[np.float64] = field(init=False, repr=False)
    _g: NDArray[np.float64] = field(init=False, repr=False)
    _n: NDArray[np.int64] = field(init=False, repr=False)
    _fits: NDArray[np.bool_] = field(init=False, repr=False)
    _tab: dict[str, NDArray] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if int(self.n_links) < 1 or int(self.max_arrivals) < 1:
            raise ValueError("ArrivalCache: n_links and max_arrivals must be >= 1")
        if not self.tol_s >= 0.0:
            raise ValueError(f"ArrivalCache: tol_s must be >= 0, got {self.tol_s!r}")
        if not self.follow_m >= 0.0:
            raise ValueError(f"ArrivalCache: follow_m must be >= 0, got {self.follow_m!r}")
        self._slot: dict[int, int] = {}
        self._cap = 0
        self._grow(64)

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
        ds = s - self._s0[slots]
        dd = d - self._d0[slots]
        move2 = (ds * ds).sum(axis=1) + (dd * dd).sum(axis=1)
        with np.errstate(invalid="ignore"):
            hit = 0.5 * self._kappa[slots] * move2 + _SOLVER_S <= self.tol_s
        hit &= np.isfinite(move2)
        # the very positions of the last solution (a link between moored nodes): as it is
        same = np.all(s == self._sl[slots], axis=1) & np.all(d == self._dl[slots], axis=1) & ~hit
        self.stats.hits += int(hit.sum()) + int(same.sum())
        rest = np.flatnonzero(~(hit | same))
        delay = self._t0[slots] + np.einsum("naj,nj->na", self._g[slots], np.concatenate([ds, dd], axis=1))
        # the Taylor tier serves from the reference solution, the others from the last one
        fresh = np.zeros(ids.size, bool)
        if rest.size:
            done = self._follow(slots[rest], s[rest], d[rest])
            self.stats.follows += int(done.sum())
            rest = rest[~done]
        if rest.size:
            self.stats.misses += int(rest.size)
            self._fill(slots[rest], s[rest], d[rest])
        fresh[~(hit | same)] = True
        fresh |= same
        delay[fresh] = self._tab["delay"][slots[fresh]]
        return self._serve(slots, delay, fresh)

    def bound(self, links: ArrayLike, src: ArrayLike, dst: ArrayLike) -> NDArray[np.float64]:
        """The error bound (s) the Taylor tier would give for serving these positions (inf:
        it would not serve them)."""
        ids = np.asarray(links, np.int64).ravel()
        slots = np.array([self._slot.get(int(i), 0) for i in ids.tolist()], np.int64)
        known = np.array([int(i) in self._slot for i in ids.tolist()], bool)
        ds = np.asarray(src, float).reshape(-1, 3) - self._s0[slots]
        dd = np.asarray(dst, float).reshape(-1, 3) - self._d0[slots]
        with np.errstate(invalid="ignore"):
            b = 0.5 * self._kappa[slots] * ((ds * ds).sum(axis=1) + (dd * dd).sum(axis=1)) + _SOLVER_S
        return np.where(known, b, np.inf)

    def radius(self, links: ArrayLike) -> NDArray[np.float64]:
        """The largest move sqrt(|s - s0|^2 + |d - d0|^2) (m) of each link the Taylor tier
        serves (0: none)."""
        ids = np.asarray(links, np.int64).ravel()
        kappa = np.array([self._kappa[self._slot[i]] if i in self._slot else np.inf for i in ids.tolist()])
        with np.errstate(divide="ignore"):
            r = np.sqrt(2.0 * max(self.tol_s - _SOLVER_S, 0.0) / kappa)
        return np.where(np.isfinite(r), r, 0.0)

    # ----------------------------------------------------------------- storage
    def _grow(self, cap: int) -> None:
        """Room for ``cap`` slots (the arrays keep their rows)."""
        old, A = self._cap, int(self.max_arrivals)

        def grown(a: NDArray | None, shape: tuple[int, ...], fill: float, dtype: type = float) -> NDArray:
            out: NDArray = np.full((cap, *shape), fill, dtype=dtype)
            if a is not None:
                out[:old] = a[:old]
            return out

        for name, shape, fill, dtype in _slot_arrays(A):
            setattr(self, name, grown(getattr(self, name, None), shape, fill, dtype))
        tab = getattr(self, "_tab", {})
        self._tab = {f: grown(tab.get(f), (A,), np.nan) for f in _FLOAT_FIELDS}
        self._tab.update({f: grown(tab.get(f), (A,), -1, np.int64) for f in _INT_FIELDS})
        self._cap = cap

    def _slots(self, ids: NDArray[np.int64]) -> NDArray[np.int64]:
        """The slot of each link id, new ones assigned (a dict lookup per link)."""
        slot = self._slot
        out = [slot.setdefault(i, len(slot)) for i in ids.tolist()]
        if len(slot) > self._cap:
            self._grow(max(2 * self._cap, len(slot)))
        return np.asarray(out, np.int64)

    def _store(self, slots: NDArray[np.int64], arr: Arrivals) -> NDArray[np.bool_]:
        """Keep ``arr`` (one link per slot) as the slots' last solution; False where it holds
        more arrivals than a slot does (the first ``max_arrivals`` are kept, and such a link is
        searched at every request)."""
        n, A = slots.size, int(self.max_arrivals)
        cnt = np.diff(arr.offsets)
        rows = np.repeat(np.arange(n), cnt)
        col = np.arange(arr.delay.size) - arr.offsets[:-1][rows]
        keep = col < A
        for f in _FLOAT_FIELDS:
            t = np.full((n, A), np.nan)
            t[rows[keep], col[keep]] = getattr(arr, f)[keep]
            self._tab[f][slots] = t
        for f in _INT_FIELDS:
            t = np.full((n, A), -1, np.int64)
            t[rows[keep], col[keep]] = getattr(arr, f)[keep]
            self._tab[f][slots] = t
        fits = cnt <= A
        self._n[slots] = np.minimum(cnt, A)
        self._fits[slots] = fits
        return fits

    def _last(self, slots: NDArray[np.int64]) -> Arrivals:
        """The slots' last solutions as an Arrivals (one link per slot)."""
        return self._serve(slots, self._tab["delay"][slots], np.ones(slots.size, bool))

    # ----------------------------------------------------------------- tiers
    def _follow(self, slots: NDArray[np.int64], s: NDArray, d: NDArray) -> NDArray[np.bool_]:
        """Serve by following where the ends are within follow_m of the last search; True where
        done (the last solution then holds the followed arrivals)."""
        r2 = self.follow_m**2
        es = s - self._sa[slots]
        ed = d - self._da[slots]
        with np.errstate(invalid="ignore"):
            near = (es * es).sum(axis=1) <= r2
            near &= ((ed * ed).sum(axis=1) <= r2) & (self._n[slots] > 0) & self._fits[slots]
        idx = np.flatnonzero(near)
        done = np.zeros(slots.size, bool)
        if not idx.size:
            return done
        sub = slots[idx]
        got, ok = _arrivals.follow(
            self.env,
            self._last(sub),
            s[idx],
            d[idx],
            max_bounces=self.max_bounces,
            frequency_khz=self.frequency_khz,
            spreading=self.spreading,
        )
        good = idx[ok]
        if good.size:
            self._store(slots[good], _links_of(got, ok))
            self._sl[slots[good]], self._dl[slots[good]] = s[good], d[good]
            self._kappa[slots[good]] = np.inf  # the Taylor reference no longer matches the tables
        done[good] = True
        return done

    def _solve(self, s: NDArray, d: NDArray) -> Arrivals:
        return _arrivals.arrivals(
            self.env, s, d, max_bounces=self.max_bounces, frequency_khz=self.frequency_khz, spreading=self.spreading
        )

    def _fill(self, slots: NDArray[np.int64], s: NDArray, d: NDArray) -> None:
        """Search the links of ``slots`` at (s, d): their new reference (and, with the Taylor
        tier on, its gradients and bound)."""
        self._store(slots, self._solve(s, d))
        self._reference(slots, s, d, s, d)

    def _reference(self, slots: NDArray[np.int64], s: NDArray, d: NDArray, sa: NDArray, da: NDArray) -> None:
        """The slots' last solutions, solved at (s, d), become their reference; (sa, da): where
        their arrival set was last searched (the following tier's centre)."""
        self._sa[slots], self._da[slots] = sa, da
        self._sl[slots], self._dl[slots] = s, d
        self._s0[slots], self._d0[slots] = s, d
        self._t0[slots] = self._tab["delay"][slots]
        self._g[slots] = 0.0
        self._kappa[slots] = np.inf
        if self.tol_s > 0.0:
            kappa, g = self._gradients(slots, s, d)
            self._kappa[slots] = np.where(self._fits[slots], kappa, np.inf)
            self._g[slots] = g

    def _gradients(self, slots: NDArray[np.int64], s: NDArray, d: NDArray) -> tuple[NDArray, NDArray]:
        """(kappa (n,), gradients (n, A, 6)) of the Taylor tier at the searched (s, d); kappa
        inf where the link is not served (see the module docstring)."""
        n, A = slots.size, int(self.max_arrivals)
        tab = self._tab
        h = _SIDE_STEP_M
        ux, uy = d[:, 0] - s[:, 0], d[:, 1] - s[:, 1]
        hor = np.hypot(ux, uy)
        ux = np.where(hor > 0, ux / np.where(hor > 0, hor, 1.0), 1.0)
        uy = np.where(hor > 0, uy / np.where(hor > 0, hor, 1.0), 0.0)
        side = np.stack([-uy, ux, np.zeros(n)], axis=1) * h
        cnt = self._n[slots]
        valid = np.arange(A)[None, :] < cnt[:, None]
        tb = tab["delay"][slots]
        ths, thr = tab["launch_angle"][slots], tab["arrival_angle"][slots]
        cs, cr = tab["source_speed"][slots], tab["receiver_speed"][slots]
        cb = np.where(valid, tab["bounce_code"][slots], -1)
        # the same eigenrays followed to d + side, d - side, s + side, s - side (one batch)
        S = np.concatenate([s, s, s + side, s - side])
        D = np.concatenate([d + side, d - side, d, d])
        th4 = np.tile(ths, (4, 1))
        rows, ok, _sec = rangedep.follow(
            self.env, S, D, self.max_bounces, th4, np.tile(tab["dz_dlaunch"][slots], (4, 1)), np.tile(cb, (4, 1))
        )
        from . import _rangedep_search_jit as jit

        side_t = np.where(ok, rows[:, :, jit.F_TIME], np.nan).reshape(4, n, A)
        # followed onto a sibling of its bounce sequence: moved by half the gap to it or more
        c4 = np.tile(cb, (4, 1))
        same = (c4[:, :, None] == c4[:, None, :]) & (c4[:, :, None] >= 0)
        same &= ~np.eye(A, dtype=bool)[None]
        gap = np.min(np.where(same, np.abs(th4[:, :, None] - th4[:, None, :]), np.inf), axis=2)
        with np.errstate(invalid="ignore"):
            jumped = ~(np.abs(rows[:, :, jit.F_THETA0] - th4) < 0.5 * gap)
        side_t = np.where(jumped.reshape(4, n, A), np.nan, side_t)
        # unstable: an arrival that cannot be followed sideways (a path about to vanish) or
        # may have been followed onto a sibling
        stable = ~np.any(valid & np.isnan(side_t).any(axis=0), axis=1)
        # gradients: Fermat in the plane, central differences across it
        uxa, uya = ux[:, None], uy[:, None]
        gd_side = (side_t[0] - side_t[1]) / (2.0 * h)
        gs_side = (side_t[2] - side_t[3]) / (2.0 * h)
        vx, vy = -uya, uxa
        g = np.zeros((n, A, 6))
        g[:, :, 0] = -np.cos(ths) * uxa / cs + gs_side * vx
        g[:, :, 1] = -np.cos(ths) * uya / cs + gs_side * vy
        g[:, :, 2] = -np.sin(ths) / cs
        g[:, :, 3] = np.cos(thr) * uxa / cr + gd_side * vx
        g[:, :, 4] = np.cos(thr) * uya / cr + gd_side * vy
        g[:, :, 5] = np.sin(thr) / cr
        # curvature: eight times the straight-ray value over the chord, twice the sideways ones
        dist = np.linalg.norm(d - s, axis=1)
        cmin = np.nanmin(np.where(valid, np.minimum(cs, cr), np.inf), axis=1, initial=np.inf)
        k_side = np.nanmax(
            np.where(
                valid,
                np.maximum(np.abs(side_t[0] - 2 * tb + side_t[1]), np.abs(side_t[2] - 2 * tb + side_t[3])) / h**2,
                0.0,
            ),
            axis=1,
            initial=0.0,
        )
        with np.errstate(divide="ignore"):
            kappa = np.maximum(_SAFETY * 2.0 / (cmin * dist), 2.0 * k_side)
        # a bottom bounce near a kink of the floor polyline: the delay's gradient jumps where the
        # reflection point crosses it, so no Taylor bound holds across it; the reflection point
        # moves less than the ends do, so the served radius must stay below that distance
        with np.errstate(divide="ignore"):
            radius = np.sqrt(2.0 * self.tol_s / kappa)
        near_kink = np.any(valid & (tab["floor_kink_distance"][slots] <= 2.0 * radius[:, None]), axis=1)
        stable &= ~near_kink
        # a link without arrivals is searched every time (a path may appear anywhere)
        kappa = np.where(stable & np.isfinite(kappa) & (cnt > 0), kappa, np.inf)
        self.stats.uncacheable += int((~stable).sum())
        return kappa, np.nan_to_num(g)

    def _serve(self, slots: NDArray[np.int64], delay: NDArray, fresh: NDArray[np.bool_]) -> Arrivals:
        """Arrivals of ``slots`` from their tables, with delays ``delay`` (n, A) (Taylor rows:
        the reference's order; ``fresh`` rows: the last solution's)."""
        n = slots.size
        cnt = self._n[slots]
        mask = np.arange(self.max_arrivals)[None, :] < cnt[:, None]
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
