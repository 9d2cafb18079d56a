"""Per-link arrival cache over positions, with an error bound on the travel time it serves.

In the spirit of WOSS's channel cache: the arrivals of a link (:func:`.arrivals.arrivals`) are
solved at reference positions (s0, d0) and, while the two ends stay close to them, served
by a first-order Taylor expansion of each delay:

    t(s, d) = t0 + g_s . (s - s0) + g_d . (d - d0)

g_s, g_d are the exact gradients of the link's N x 2-D travel time: in the link's vertical
plane the slowness vectors at the ends (Fermat: -(cos th_S u, sin th_S) / c_S at the source,
(cos th_R u, sin th_R) / c_R at the receiver, u the horizontal unit vector of the link);
across the plane (moving an end sideways turns the plane, which then samples another part of a
front or a flank) a central difference of the delays with that end moved by +-h = 0.5 m, each
eigenray followed there from its launch angle by a few secant steps (:func:`.rangedep.track`).

Error bound. The Taylor remainder is at most 1/2 |H| |delta|^2, |delta|^2 = |s - s0|^2 +
|d - d0|^2, |H| the largest curvature of t over the move. For a straight ray |H| = 2 / (c L)
(L the end-to-end distance); the cache takes kappa = max(16 / (c_min D), 2 k_side) per link,
eight times the straight-ray value (refraction, and reflections off a sloping floor, which turn
the image sources as an end moves, curve the delays more: with four times, served errors up to
1.004x the bound were measured on the shelf-break benchmark, tools/bench_arrivals.py), and twice
the sideways curvatures seen by the central differences; plus 1e-12 s for the solver's own
accuracy. The factor is measured, not derived: the tests check the bound on random moves. A link
is served while 1/2 kappa |delta|^2 + 1e-12 s <= tol_s (default 1e-7 s), else solved again.

Arrival-set changes. The sideways steps double as a guard: a link with an eigenray that cannot
be followed to +-h (its bounce sequence changes: a grazing ray, a direct path about to be
blocked), or with two eigenrays of one bounce sequence (a fold, where following one may land on
the other), or with a bottom reflection point within twice the served radius of a kink of the
floor polyline (where the delay's gradient jumps), is never served from the cache. Not detected: a path that appears (a new eigenray)
within the radius of a cached link, or one that vanishes closer than h in another direction.

Levels and angles are served unchanged (they vary on scales of metres, not of the delay's 1e-7
s). Vectorized: links are integer ids into fixed-size arrays, no Python loop over links.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import rangedep
from .arrivals import Arrivals, arrivals
from .environment import Environment

__all__ = ["ArrivalCache", "CacheStats"]

_SIDE_STEP_M = 0.5
_SAFETY = 8.0  # curvature allowed over a straight ray's 2 / (c L), see the module docstring
_SOLVER_S = 1e-12  # the eigenray solver's own accuracy, added to the bound


@dataclass
class CacheStats:
    hits: int = 0
    misses: int = 0
    uncacheable: int = 0  #: misses of links whose arrival set is not stable sideways

    @property
    def hit_rate(self) -> float:
        n = self.hits + self.misses
        return self.hits / n if n else 0.0


@dataclass
class ArrivalCache:
    """Arrivals of links ``0 .. n_links-1`` (the caller's ids, e.g. src * n_nodes + dst)."""

    env: Environment
    n_links: int
    max_bounces: int = 2
    tol_s: float = 1e-7
    frequency_khz: float = 10.0
    spreading: str | float = "ray"
    max_arrivals: int = 24
    stats: CacheStats = field(default_factory=CacheStats)

    def __post_init__(self) -> None:
        L, A = int(self.n_links), int(self.max_arrivals)
        if L < 1 or A < 1:
            raise ValueError("ArrivalCache: n_links and max_arrivals must be >= 1")
        if not self.tol_s > 0.0:
            raise ValueError(f"ArrivalCache: tol_s must be positive, got {self.tol_s!r}")
        self._s0 = np.full((L, 3), np.nan)
        self._d0 = np.full((L, 3), np.nan)
        self._kappa = np.full(L, np.inf)  # s/m^2; inf: never served
        self._n = np.zeros(L, np.int64)
        self._t = np.full((L, A), np.nan)
        self._g = np.zeros((L, A, 6))
        self._rows: dict[str, NDArray] = {}

    # ----------------------------------------------------------------- public
    def get(self, links: ArrayLike, src: ArrayLike, dst: ArrayLike) -> Arrivals:
        """Arrivals of ``links`` (n,) between ``src`` and ``dst`` (n, 3): from the cache where
        its bound allows, else solved (and cached)."""
        ids = np.asarray(links, np.int64).ravel()
        s = np.asarray(src, float).reshape(-1, 3)
        d = np.asarray(dst, float).reshape(-1, 3)
        if not (ids.size == s.shape[0] == d.shape[0]):
            raise ValueError("ArrivalCache.get: links, src and dst differ in length")
        if ids.size and (ids.min() < 0 or ids.max() >= self.n_links):
            raise ValueError(f"ArrivalCache.get: link ids must be in [0, {self.n_links})")
        if np.unique(ids).size != ids.size:
            raise ValueError("ArrivalCache.get: a link id appears twice in one call")
        ds = s - self._s0[ids]
        dd = d - self._d0[ids]
        move2 = (ds * ds).sum(axis=1) + (dd * dd).sum(axis=1)
        with np.errstate(invalid="ignore"):
            hit = 0.5 * self._kappa[ids] * move2 + _SOLVER_S <= self.tol_s
        hit &= np.isfinite(move2)
        miss = np.flatnonzero(~hit)
        self.stats.hits += int(hit.sum())
        self.stats.misses += int(miss.size)
        if miss.size:
            self._fill(ids[miss], s[miss], d[miss])
            ds[miss] = 0.0
            dd[miss] = 0.0
        return self._serve(ids, ds, dd)

    def bound(self, links: ArrayLike, src: ArrayLike, dst: ArrayLike) -> NDArray[np.float64]:
        """The error bound (s) the cache would give for serving these positions (inf: it
        would not serve them)."""
        ids = np.asarray(links, np.int64).ravel()
        ds = np.asarray(src, float).reshape(-1, 3) - self._s0[ids]
        dd = np.asarray(dst, float).reshape(-1, 3) - self._d0[ids]
        with np.errstate(invalid="ignore"):
            return 0.5 * self._kappa[ids] * ((ds * ds).sum(axis=1) + (dd * dd).sum(axis=1)) + _SOLVER_S

    # ----------------------------------------------------------------- internals
    def _solve(self, s: NDArray, d: NDArray) -> Arrivals:
        return arrivals(
            self.env, s, d, max_bounces=self.max_bounces, frequency_khz=self.frequency_khz, spreading=self.spreading
        )

    def _fill(self, ids: NDArray[np.int64], s: NDArray, d: NDArray) -> None:
        n = ids.size
        A = self.max_arrivals
        h = _SIDE_STEP_M
        ux, uy = d[:, 0] - s[:, 0], d[:, 1] - s[:, 1]
        hor = np.hypot(ux, uy)
        ux = np.where(hor > 0, ux / np.where(hor > 0, hor, 1.0), 1.0)
        uy = np.where(hor > 0, uy / np.where(hor > 0, hor, 1.0), 0.0)
        side = np.stack([-uy, ux, np.zeros(n)], axis=1) * h
        arr = self._solve(s, d)
        cnt = np.diff(arr.offsets)
        k = np.arange(A)
        valid = k[None, :] < np.minimum(cnt, A)[:, None]

        def padded(x: NDArray, fill: float) -> NDArray:
            out = np.full((n, A), fill, dtype=float)
            rows = np.repeat(np.arange(n), cnt)
            pos = np.arange(arr.delay.size) - arr.offsets[:-1][rows]
            keep = pos < A
            out[rows[keep], pos[keep]] = x[keep]
            return out

        tb = padded(arr.delay, np.nan)
        cb = padded(arr.bounce_code.astype(float), -1.0).astype(np.int64)
        ths = padded(arr.launch_angle, np.nan)
        thr = padded(arr.arrival_angle, np.nan)
        cs = padded(arr.source_speed, np.nan)
        cr = padded(arr.receiver_speed, np.nan)
        slope = padded(arr.dz_dlaunch, np.nan)
        kink = padded(arr.floor_kink_distance, np.inf)
        # the same eigenrays followed to d + side, d - side, s + side, s - side (one batch)
        S = np.concatenate([s, s, s + side, s - side])
        D = np.concatenate([d + side, d - side, d, d])
        four = rangedep.track(
            self.env, S, D, self.max_bounces, np.tile(ths, (4, 1)), np.tile(slope, (4, 1)), np.tile(cb, (4, 1))
        )
        side_t = four.reshape(4, n, A)
        # unstable: an arrival that cannot be followed sideways (a path about to vanish), two
        # eigenrays of one bounce sequence (a fold: following one may land on the other), or
        # more arrivals than the table holds
        dup = valid & (((cb[:, :, None] == cb[:, None, :]) & valid[:, None, :]).sum(axis=2) > 1)
        stable = ~np.any(valid & (np.isnan(side_t).any(axis=0) | dup), axis=1) & (cnt <= A)
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
        # curvature: twice the straight-ray value over the chord, twice the sideways ones
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
        near_kink = np.any(valid & (kink <= 2.0 * radius[:, None]), axis=1)
        stable &= ~near_kink
        # a link without arrivals is solved every time (a path may appear anywhere)
        kappa = np.where(stable & np.isfinite(kappa) & (cnt > 0), kappa, np.inf)
        self.stats.uncacheable += int((~stable).sum())
        self._s0[ids], self._d0[ids] = s, d
        self._kappa[ids] = kappa
        self._n[ids] = np.minimum(cnt, A)
        self._t[ids] = tb
        self._g[ids] = np.nan_to_num(g)
        # the other fields of the base solution, padded
        for name in (
            "level_db",
            "launch_angle",
            "arrival_angle",
            "length",
            "bottom_loss_db",
            "source_speed",
            "receiver_speed",
            "dz_dlaunch",
            "floor_kink_distance",
        ):
            self._table(name, float, np.nan)[ids] = padded(getattr(arr, name), np.nan)
        for name in ("surface_bounces", "bottom_bounces", "path_class", "bounce_code"):
            self._table(name, np.int64, -1)[ids] = padded(getattr(arr, name).astype(float), -1.0).astype(np.int64)

    def _table(self, name: str, dtype: type, fill: float) -> NDArray:
        if name not in self._rows:
            self._rows[name] = np.full((self.n_links, self.max_arrivals), fill, dtype=dtype)
        return self._rows[name]

    def _serve(self, ids: NDArray[np.int64], ds: NDArray, dd: NDArray) -> Arrivals:
        n = ids.size
        cnt = self._n[ids]
        mask = np.arange(self.max_arrivals)[None, :] < cnt[:, None]
        move = np.concatenate([ds, dd], axis=1)  # (n, 6)
        t = self._t[ids] + np.einsum("naj,nj->na", self._g[ids], move)
        offsets = np.zeros(n + 1, np.int64)
        offsets[1:] = np.cumsum(cnt)
        # first-order moves keep the order except where two delays cross: re-sort per link
        tt = np.where(mask, t, np.inf)
        order = np.argsort(tt, axis=1, kind="stable")

        def take(a: NDArray) -> NDArray:
            return np.take_along_axis(a, order, axis=1)[np.take_along_axis(mask, order, axis=1)]

        rows = self._rows
        return Arrivals(
            shape=(n,),
            offsets=offsets,
            link=np.repeat(np.arange(n), cnt).astype(np.int64),
            delay=take(t),
            level_db=take(rows["level_db"][ids]),
            launch_angle=take(rows["launch_angle"][ids]),
            arrival_angle=take(rows["arrival_angle"][ids]),
            surface_bounces=take(rows["surface_bounces"][ids]),
            bottom_bounces=take(rows["bottom_bounces"][ids]),
            path_class=take(rows["path_class"][ids]).astype(np.int8),
            length=take(rows["length"][ids]),
            bottom_loss_db=take(rows["bottom_loss_db"][ids]),
            bounce_code=take(rows["bounce_code"][ids]),
            source_speed=take(rows["source_speed"][ids]),
            receiver_speed=take(rows["receiver_speed"][ids]),
            dz_dlaunch=take(rows["dz_dlaunch"][ids]),
            floor_kink_distance=take(rows["floor_kink_distance"][ids]),
        )
