"""Every arrival of a link, its level, and the first one a modem detects (pure functions).

``arrivals(env, src, dst, max_bounces=...)`` lists, per link, every eigenray with at most
``max_bounces`` surface and bottom bounces (:mod:`.rangedep`) in increasing delay: delay (s),
level (dB re the source level at 1 m), launch and arrival angles, bounces, path class, arc
length. ``first_detectable`` applies a modem's detection rule to them.

Level of an arrival (dB) = - spreading - absorption - bottom reflection loss:

* spreading, ``spreading="ray"``: the ray tube of a point source in the link's plane,
  I / I(1 m) = (c_R / c_S) |cos th_S| / (R |dz_R / dth_S| |cos th_R|) (Jensen et al.,
  *Computational Ocean Acoustics*, eq 3.58 with the cylindrical spreading of the plane), capped
  at 6 dB above spherical spreading over the arc length (geometric rays fail at caustics, where
  dz_R / dth_S -> 0); a number k instead gives the practical law 10 k log10(arc length);
* absorption: Thorp at ``frequency_khz`` over the arc length (:mod:`.loss`);
* each bottom bounce: the Rayleigh loss of the environment's sediment at the local grazing angle
  against the sloping floor; the surface reflects without loss.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import IntEnum
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import rangedep
from .environment import Environment
from .loss import thorp_absorption_db_per_km

__all__ = ["ArrivalClass", "Arrivals", "arrivals", "detection_snr_db", "first_detectable", "follow", "slowness"]

FloatArray = NDArray[np.float64]
_CAUSTIC_CAP_DB = 6.0


class ArrivalClass(IntEnum):
    """How an arrival travelled."""

    DIRECT = 0  #: no bounce, no turning point
    REFRACTED = 1  #: no bounce, turned by refraction at least once
    SURFACE = 2  #: surface bounces only
    BOTTOM = 3  #: bottom bounces only
    SURFACE_BOTTOM = 4  #: both

    @property
    def label(self) -> str:
        return self.name.lower().replace("_", "-")


@dataclass(frozen=True)
class Arrivals:
    """Arrivals of n links, flattened: the arrivals of link l are rows offsets[l]:offsets[l+1],
    in increasing delay. ``shape`` is the links' broadcast shape (``link`` indexes its ravel)."""

    shape: tuple[int, ...]
    offsets: NDArray[np.int64]
    link: NDArray[np.int64]
    delay: FloatArray  #: s
    level_db: FloatArray  #: dB re source level at 1 m (<= 0 beyond a metre)
    launch_angle: FloatArray  #: rad, positive down
    arrival_angle: FloatArray  #: rad, positive down
    surface_bounces: NDArray[np.int64]
    bottom_bounces: NDArray[np.int64]
    path_class: NDArray[np.int8]  #: ArrivalClass codes
    length: FloatArray  #: arc length, m
    bottom_loss_db: FloatArray  #: summed Rayleigh loss of the bottom bounces, dB
    bounce_code: NDArray[np.int64]  #: bounce sequence, base 3 (1 surface, 2 bottom; first bounce lowest)
    dz_dlaunch: FloatArray  #: d (depth at the receiver's range) / d launch angle, m/rad (ray-tube width)
    #: m from the nearest bottom reflection point to a jump of the floor's slope or curvature (inf: none)
    floor_kink_distance: FloatArray
    source_speed: FloatArray  #: c at the source, m/s (the traced section's)
    receiver_speed: FloatArray  #: c at the receiver, m/s

    _FIELDS = (
        "link",
        "delay",
        "level_db",
        "launch_angle",
        "arrival_angle",
        "surface_bounces",
        "bottom_bounces",
        "path_class",
        "length",
        "bottom_loss_db",
        "bounce_code",
        "dz_dlaunch",
        "floor_kink_distance",
        "source_speed",
        "receiver_speed",
    )

    @property
    def count(self) -> NDArray[np.int64]:
        """Arrivals per link, shape ``shape``."""
        return np.diff(self.offsets).reshape(self.shape)

    def of(self, i: int) -> Arrivals:
        """The arrivals of link i (index into the raveled links) as an Arrivals of one link."""
        a, b = int(self.offsets[i]), int(self.offsets[i + 1])
        fields = {f: getattr(self, f)[a:b] for f in self._FIELDS}
        fields["link"] = np.zeros(b - a, np.int64)
        return Arrivals(shape=(), offsets=np.array([0, b - a], np.int64), **fields)

    @property
    def first_delay(self) -> FloatArray:
        """Delay of each link's first arrival (s), NaN where it has none; shape ``shape``."""
        n = self.offsets.size - 1
        out = np.full(n, np.nan)
        has = self.offsets[1:] > self.offsets[:-1]
        out[has] = self.delay[self.offsets[:-1][has]]
        return out.reshape(self.shape)

    def delay_spread(self) -> FloatArray:
        """Last minus first delay per link (s); 0 for one arrival, NaN for none."""
        n = self.offsets.size - 1
        out = np.full(n, np.nan)
        has = self.offsets[1:] > self.offsets[:-1]
        out[has] = self.delay[self.offsets[1:][has] - 1] - self.delay[self.offsets[:-1][has]]
        return out.reshape(self.shape)

    def records(self) -> list[dict[str, Any]]:
        """One plain dict per arrival (JSON-ready; angles in degrees)."""
        return [
            {
                "link": int(self.link[i]),
                "delay_s": float(self.delay[i]),
                "level_db": float(self.level_db[i]),
                "launch_angle_deg": float(np.degrees(self.launch_angle[i])),
                "arrival_angle_deg": float(np.degrees(self.arrival_angle[i])),
                "surface_bounces": int(self.surface_bounces[i]),
                "bottom_bounces": int(self.bottom_bounces[i]),
                "path": ArrivalClass(int(self.path_class[i])).label,
                "length_m": float(self.length[i]),
                "bottom_loss_db": float(self.bottom_loss_db[i]),
            }
            for i in range(self.delay.size)
        ]


def _classify(ns: NDArray[np.int64], nb: NDArray[np.int64], nturn: NDArray[np.int64]) -> NDArray[np.int8]:
    cls = np.where(
        (ns > 0) & (nb > 0),
        ArrivalClass.SURFACE_BOTTOM,
        np.where(ns > 0, ArrivalClass.SURFACE, np.where(nb > 0, ArrivalClass.BOTTOM, ArrivalClass.DIRECT)),
    )
    cls = np.where((cls == ArrivalClass.DIRECT) & (nturn > 0), ArrivalClass.REFRACTED, cls)
    return cls.astype(np.int8)


def arrivals(
    env: Environment,
    src: ArrayLike,
    dst: ArrayLike,
    *,
    max_bounces: int = 2,
    frequency_khz: float = 10.0,
    spreading: str | float = "ray",
) -> Arrivals:
    """Every eigenray from ``src`` to ``dst`` ((..., 3), m; broadcast) with at most
    ``max_bounces`` surface + bottom bounces, in increasing delay per link (see the module
    docstring for the level). Links with an end outside the water have none."""
    return watched_arrivals(env, src, dst, max_bounces=max_bounces, frequency_khz=frequency_khz, spreading=spreading)[0]


def watched_arrivals(
    env: Environment,
    src: ArrayLike,
    dst: ArrayLike,
    *,
    max_bounces: int = 2,
    frequency_khz: float = 10.0,
    spreading: str | float = "ray",
    watch_m: float | None = None,
) -> tuple[Arrivals, FloatArray, NDArray[np.int64]]:
    """:func:`arrivals`, and each link's watched intervals (margin below ``watch_m``, m) and
    their counts (flattened links: (n, WATCH_ROWS, NW), (n,); :func:`.rangedep.solve`,
    :func:`.rangedep.watch`), for a cache that follows the links."""
    shape = np.broadcast_shapes(np.shape(src)[:-1], np.shape(dst)[:-1])
    sec = rangedep.sections(env, src, dst)
    rows, cnt, watch, nwatch = rangedep.solve(env, sec, max_bounces, watch_m)
    used = np.arange(rows.shape[1])[None, :] < cnt[:, None]
    return _assemble(sec, rows, used, shape, frequency_khz, spreading), watch, nwatch


def follow(
    env: Environment,
    prev: Arrivals,
    src: ArrayLike,
    dst: ArrayLike,
    *,
    max_bounces: int = 2,
    frequency_khz: float = 10.0,
    spreading: str | float = "ray",
    src_from: ArrayLike | None = None,
    reach: ArrayLike | None = None,
) -> tuple[Arrivals, NDArray[np.bool_]]:
    """The arrivals ``prev`` (of n links, each solved at nearby end points) followed to the end
    points ``src``, ``dst`` ((n, 3), m): each eigenray from its launch angle by Newton's
    iteration on the depth miss with the walk's exact slope, keeping its bounce sequence
    (:func:`.rangedep.follow`), instead of a search. Returns (the arrivals, (n,) whether every arrival of the link was followed): a
    link is not followed where one of its eigenrays changed its bounce sequence (a path about to
    vanish), or two of one sequence met or swapped their order (a fold, where following one may
    land on the other); its arrivals are then meaningless and must be searched again. A
    followed link has exactly ``prev``'s eigenrays: one that appeared since is not found. The
    ray-tube width (for the level) is the walk's exact derivative, as a search's.
    ``src_from`` (n, 3): where the sources were when ``prev`` was solved; given, a moved
    source's move is followed backwards from the receiver (:func:`.rangedep.follow_ends`),
    which keeps far more eigenrays than following it from the source. ``reach`` (n,) m: how far
    the depth miss at a fixed launch angle may have moved (:func:`.rangedep.watch_reach`);
    given, an eigenray whose launch angle moved farther than that allows is not followed
    (:func:`.rangedep.turned_within`)."""

    n = prev.offsets.size - 1
    s = np.asarray(src, dtype=float).reshape(n, 3)
    d = np.asarray(dst, dtype=float).reshape(n, 3)
    theta, code = launch_table(prev)
    used = code >= 0
    # without src_from no source counts as moved: one leg
    s0 = s if src_from is None else np.asarray(src_from, dtype=float).reshape(n, 3)
    rows, ok, sec = rangedep.follow_ends(env, s0, s, d, max_bounces, theta, code)
    if reach is not None:
        from ._rangedep_search_jit import F_THETA0

        dz = _table(prev, prev.dz_dlaunch, np.nan)
        ok &= rangedep.turned_within(theta, rows[..., F_THETA0], dz, np.asarray(reach, float).reshape(n, 1))
    # a link is followed where every eigenray is: not one changed its bounce sequence, and none
    # moved by half the gap to a sibling of its sequence or more, or (with reach) farther than its
    # ray-tube width allows (a fold)
    whole = np.all(ok | ~used, axis=1)
    out = _assemble(sec, rows, used & whole[:, None], (n,), frequency_khz, spreading)
    return out, whole


def _table(arr: Arrivals, values: NDArray[Any], pad: Any) -> NDArray[Any]:
    """Per-arrival ``values`` as an (n, Q) table of the links, Q the most arrivals of a link (at
    least 1), padded with ``pad``."""
    n = arr.offsets.size - 1
    cnt = np.diff(arr.offsets)
    rows_of = np.repeat(np.arange(n), cnt)
    col = np.arange(arr.delay.size) - arr.offsets[:-1][rows_of]
    out = np.full((n, max(int(cnt.max(initial=0)), 1)), pad, dtype=values.dtype)
    out[rows_of, col] = values
    return out


def launch_table(arr: Arrivals) -> tuple[FloatArray, NDArray[np.int64]]:
    """Each link's launch angles (rad) and bounce sequences as (n, Q) tables, Q the most
    arrivals of a link (at least 1), padded with NaN and -1: the form :func:`.rangedep.follow`
    and :func:`.rangedep.watch` take."""
    return _table(arr, arr.launch_angle, np.nan), _table(arr, arr.bounce_code, -1)


def reversed_arrivals(arr: Arrivals) -> Arrivals:
    """The arrivals ``arr`` seen from each link's other end: the same rays travelled backwards
    (launch and arrival angles swapped and negated, the end speeds swapped, the bounce sequence
    reversed, the ray-tube width at the other end by :func:`.rangedep.reciprocal_width`)."""
    th0, thr = arr.launch_angle, arr.arrival_angle
    cs, cr = arr.source_speed, arr.receiver_speed
    return replace(
        arr,
        launch_angle=-thr,
        arrival_angle=-th0,
        source_speed=cr,
        receiver_speed=cs,
        dz_dlaunch=rangedep.reciprocal_width(arr.dz_dlaunch, th0, thr, cs, cr),
        bounce_code=rangedep.reversed_code(arr.bounce_code, arr.surface_bounces + arr.bottom_bounces),
    )


def _assemble(
    sec: rangedep.Sections,
    rows: FloatArray,
    used: NDArray[np.bool_],
    shape: tuple[int, ...],
    frequency_khz: float,
    spreading: str | float,
) -> Arrivals:
    """Arrivals from raw eigenray rows (n, cap, NF) of the sections ``sec``, the rows ``used``
    (n, cap) of each link; sorted by delay per link, with their levels."""
    from . import _rangedep_search_jit as jit

    n = rows.shape[0]
    cnt = used.sum(axis=1)
    t = np.where(used, rows[:, :, jit.F_TIME], np.inf)
    order = np.argsort(t, axis=1, kind="stable")
    rows = np.take_along_axis(rows, order[:, :, None], axis=1)
    flat = rows[np.take_along_axis(used, order, axis=1)]  # row-major: link by link, sorted by delay
    link = np.repeat(np.arange(n), cnt)
    offsets = np.zeros(n + 1, np.int64)
    offsets[1:] = np.cumsum(cnt)

    th0, thr = flat[:, jit.F_THETA0], flat[:, jit.F_THETAR]
    arc = flat[:, jit.F_ARC]
    R = sec.R[link]
    cs, cr = flat[:, jit.F_CS], flat[:, jit.F_CR]
    spherical = 20.0 * np.log10(np.maximum(arc, 1.0))
    if spreading == "ray":
        with np.errstate(divide="ignore", invalid="ignore"):
            inten = (cr / cs) * np.abs(np.cos(th0)) / (R * np.abs(flat[:, jit.F_DZDTH]) * np.abs(np.cos(thr)))
            tl = -10.0 * np.log10(inten)
        tl = np.where(np.isfinite(tl), np.maximum(tl, spherical - _CAUSTIC_CAP_DB), spherical - _CAUSTIC_CAP_DB)
    else:
        k = float(spreading)
        if not 1.0 <= k <= 2.0:
            raise ValueError(f"spreading must be 'ray' or a number in [1, 2], got {spreading!r}")
        tl = 10.0 * k * np.log10(np.maximum(arc, 1.0))
    absorption = thorp_absorption_db_per_km(frequency_khz) * arc * 1e-3
    bloss = flat[:, jit.F_LOSS]
    ns = flat[:, jit.F_NS].astype(np.int64)
    nb = flat[:, jit.F_NB].astype(np.int64)
    return Arrivals(
        shape=shape,
        offsets=offsets,
        link=link.astype(np.int64),
        delay=flat[:, jit.F_TIME],
        level_db=-(tl + absorption + bloss),
        launch_angle=th0,
        arrival_angle=thr,
        surface_bounces=ns,
        bottom_bounces=nb,
        path_class=_classify(ns, nb, flat[:, jit.F_NTURN].astype(np.int64)),
        length=arc,
        bottom_loss_db=bloss,
        bounce_code=flat[:, jit.F_CODE].astype(np.int64),
        dz_dlaunch=flat[:, jit.F_DZDTH],
        floor_kink_distance=flat[:, jit.F_KINK],
        source_speed=cs,
        receiver_speed=cr,
    )


def detection_snr_db(arr: Arrivals, source_level_db: float, noise_db: float) -> FloatArray:
    """SNR (dB) of each arrival: source level + level - noise (``noise_db`` = the noise power
    in the receiver's band, dB re 1 uPa^2, e.g. :func:`.loss.noise_psd_db` + 10 log10 B)."""
    return float(source_level_db) + arr.level_db - float(noise_db)


def slowness(ux: NDArray, uy: NDArray, theta: NDArray, c: NDArray) -> NDArray[np.float64]:
    """(..., 3) the slowness vector (s/m) of a ray at an end of its link, (cos theta u, sin theta)
    / c: theta (rad, positive down) its angle there in the link's vertical plane, c (m/s) the
    speed there, (ux, uy) the plane's horizontal unit vector (broadcast together). By Fermat,
    the gradient of the eigenray's delay with respect to the receiver's position at the arrival
    angle, and minus the gradient with respect to the source's at the launch angle."""
    h = np.cos(theta) / c
    return np.stack(np.broadcast_arrays(h * ux, h * uy, np.sin(theta) / c), axis=-1)


def first_detectable(
    arr: Arrivals, source_level_db: float, noise_db: float, threshold_db: float
) -> tuple[NDArray[np.int64], FloatArray]:
    """The modem's detection rule: per link, the first arrival (in delay) whose SNR reaches
    ``threshold_db``. Returns (row index into ``arr`` or -1, its delay or NaN), shape ``arr.shape``."""
    ok = detection_snr_db(arr, source_level_db, noise_db) >= float(threshold_db)
    n = arr.offsets.size - 1
    idx = np.full(n, -1, np.int64)
    rows = np.flatnonzero(ok)
    if rows.size:
        links = arr.link[rows]
        # the first ok row of each link: rows are sorted by link, then by delay
        first = np.unique(links, return_index=True)
        idx[first[0]] = rows[first[1]]
    delay = np.where(idx >= 0, arr.delay[np.maximum(idx, 0)] if arr.delay.size else np.nan, np.nan)
    return idx.reshape(arr.shape), delay.reshape(arr.shape)
