"""Kinematic mobility models: static, constant velocity, coordinated turn, random walk, noisy
constant velocity, waypoints."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .base import Array, Mobility, _need_rng, _per_node, _positive, _readonly, _Table
from .box import Box

__all__ = ["ConstantVelocity", "CoordinatedTurn", "NoisyConstantVelocity", "RandomWalk", "Static", "Waypoints"]


class Static(Mobility):
    """Nodes that never move (moored anchors, buoys)."""

    _folds = False

    def __init__(self, initial_positions: ArrayLike, box: Box, rng: np.random.Generator | None = None) -> None:
        super().__init__(initial_positions, box, rng)
        self._zero = _readonly(np.zeros_like(self._p0))

    def _raw_position(self, t: float) -> Array:
        return self._p0

    def _raw_velocity(self, t: float) -> Array:
        return self._zero

    def _raw_position_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        return self._p0[idx]

    def max_speed(self) -> float:
        return 0.0

    def _raw_velocity_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        return np.zeros((idx.size, 3))


class ConstantVelocity(Mobility):
    """Straight lines at constant velocity (m/s), ``velocity`` a 3-vector or (n, 3)."""

    def __init__(
        self,
        initial_positions: ArrayLike,
        box: Box,
        rng: np.random.Generator | None = None,
        *,
        velocity: ArrayLike = (0.0, 0.0, 0.0),
    ) -> None:
        super().__init__(initial_positions, box, rng)
        v = np.asarray(velocity, dtype=float)
        try:
            v = np.broadcast_to(v, (self.n, 3)).copy()
        except ValueError:
            raise ValueError(f"velocity must be a 3-vector or shape ({self.n}, 3), got {v.shape}") from None
        if not np.all(np.isfinite(v)):
            raise ValueError("velocity must be finite")
        self._v = _readonly(v)

    def _raw_position(self, t: float) -> Array:
        return self._p0 + self._v * t

    def max_speed(self) -> float:
        return float(np.sqrt(np.einsum("ij,ij->i", self._v, self._v)).max())

    def _raw_velocity(self, t: float) -> Array:
        return self._v

    def _raw_position_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        return self._p0[idx] + self._v[idx] * t[:, None]

    def _raw_velocity_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        return self._v[idx]


class CoordinatedTurn(Mobility):
    """Constant horizontal speed on circles in x-y plus a constant vertical speed.

    Heading h(t) = heading + turn_rate t (rad, from +x towards +y); the horizontal velocity is
    speed (cos h, sin h), so the circle radius is speed / |turn_rate|. Positions use the exact
    arc integral written with sinc so turn_rate -> 0 is the straight line without cancellation.

    Parameters (scalars or per node (n,)): ``speed`` (m/s, >= 0), ``turn_rate`` (rad/s),
    ``heading`` (rad; uniform on [0, 2 pi) from ``rng`` when None), ``vz`` (m/s, down positive).
    """

    def __init__(
        self,
        initial_positions: ArrayLike,
        box: Box,
        rng: np.random.Generator | None = None,
        *,
        speed: ArrayLike = 1.0,
        turn_rate: ArrayLike = 0.0,
        heading: ArrayLike | None = None,
        vz: ArrayLike = 0.0,
    ) -> None:
        super().__init__(initial_positions, box, rng)
        n = self.n
        self.speed = _readonly(_per_node("speed", speed, n, minimum=0.0))
        self.turn_rate = _readonly(_per_node("turn_rate", turn_rate, n))
        if heading is None:
            heading = _need_rng(rng, "CoordinatedTurn with heading=None").uniform(0.0, 2.0 * np.pi, n)
        self.heading = _readonly(_per_node("heading", heading, n))
        self.vz = _readonly(_per_node("vz", vz, n))

    @staticmethod
    def _arc(p0: Array, speed: Array, rate: Array, heading: Array, vz: Array, t: float | Array) -> Array:
        half = rate * (0.5 * t)
        mid = heading + half
        # sin(h0 + w t) - sin(h0) = 2 cos(h0 + w t / 2) sin(w t / 2) (and likewise for cos):
        # chord = speed t sinc(w t / 2), no cancellation as w -> 0.
        chord = np.ones(len(p0))
        np.divide(np.sin(half), half, out=chord, where=half != 0.0)
        chord *= speed * t
        d = np.empty((3, len(p0)))
        np.cos(mid, out=d[0])
        np.sin(mid, out=d[1])
        d[:2] *= chord
        np.multiply(vz, t, out=d[2])
        return p0 + d.T

    @staticmethod
    def _tangent(speed: Array, rate: Array, heading: Array, vz: Array, t: float | Array) -> Array:
        h = heading + rate * t
        d = np.empty((3, len(speed)))
        np.cos(h, out=d[0])
        np.sin(h, out=d[1])
        d[:2] *= speed
        d[2] = vz
        return np.ascontiguousarray(d.T)

    def max_speed(self) -> float:
        return float(np.hypot(self.speed, self.vz).max())

    def _raw_position(self, t: float) -> Array:
        return self._arc(self._p0, self.speed, self.turn_rate, self.heading, self.vz, t)

    def _raw_velocity(self, t: float) -> Array:
        return self._tangent(self.speed, self.turn_rate, self.heading, self.vz, t)

    def _raw_position_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        return self._arc(self._p0[idx], self.speed[idx], self.turn_rate[idx], self.heading[idx], self.vz[idx], t)

    def _raw_velocity_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        return self._tangent(self.speed[idx], self.turn_rate[idx], self.heading[idx], self.vz[idx], t)


class RandomWalk(Mobility):
    """Piecewise-constant velocity legs of ``leg_duration`` s, each drawn afresh.

    Leg speeds are uniform on [speed_min, speed_max] (m/s); directions are uniform on the
    horizontal circle (``vertical=False``, vz = 0) or on the sphere (``vertical=True``). Legs are
    drawn from ``rng`` in fixed blocks of 64, all nodes at once, as far as queries reach.
    """

    _BLOCK = 64

    def __init__(
        self,
        initial_positions: ArrayLike,
        box: Box,
        rng: np.random.Generator | None = None,
        *,
        speed_min: float = 0.0,
        speed_max: float = 1.0,
        leg_duration: float = 10.0,
        vertical: bool = False,
    ) -> None:
        super().__init__(initial_positions, box, rng)
        self._legs_rng = _need_rng(rng, "RandomWalk")
        self.speed_min = float(speed_min)
        self.speed_max = float(speed_max)
        if not (0.0 <= self.speed_min <= self.speed_max < math.inf):
            raise ValueError(f"need 0 <= speed_min <= speed_max < inf, got {speed_min!r}, {speed_max!r}")
        self.leg_duration = _positive("leg_duration", leg_duration)
        self.vertical = bool(vertical)
        # Leg k: raw start position _starts[k], velocity _vels[k].
        self._starts = _Table(self._p0)
        self._vels: _Table | None = None

    def _draw_block(self) -> None:
        rng, n, b = self._legs_rng, self.n, self._BLOCK
        speed = rng.uniform(self.speed_min, self.speed_max, (b, n))
        azimuth = rng.uniform(0.0, 2.0 * np.pi, (b, n))
        if self.vertical:
            cos_polar = rng.uniform(-1.0, 1.0, (b, n))  # uniform on the sphere (Archimedes)
            horiz = np.sqrt(1.0 - cos_polar**2)
        else:
            cos_polar = np.zeros((b, n))
            horiz = np.ones((b, n))
        vel = speed[..., None] * np.stack((horiz * np.cos(azimuth), horiz * np.sin(azimuth), cos_polar), axis=-1)
        ends = self._starts.last + np.cumsum(vel * self.leg_duration, axis=0)
        if self._vels is None:
            self._vels = _Table(vel[0])
            self._vels.append(vel[1:])
        else:
            self._vels.append(vel)
        self._starts.append(ends)

    @property
    def _vel_data(self) -> Array:
        # _leg / _legs_at have drawn at least one block before any read
        assert self._vels is not None
        return self._vels.data

    def _leg(self, t: float) -> tuple[int, float]:
        k = int(t // self.leg_duration)
        while self._vels is None or k >= self._vels.count:
            self._draw_block()
        return k, t - k * self.leg_duration

    def max_speed(self) -> float:
        return self.speed_max  # every leg: speed <= speed_max along a unit direction

    def _raw_position(self, t: float) -> Array:
        k, dt = self._leg(t)
        return self._starts.data[k] + self._vel_data[k] * dt

    def _raw_velocity(self, t: float) -> Array:
        k, _ = self._leg(t)
        return self._vel_data[k]

    def _legs_at(self, t: Array) -> tuple[NDArray[np.intp], Array]:
        k = np.floor(t / self.leg_duration).astype(np.intp)
        self._leg(float(k.max()) * self.leg_duration if k.size else 0.0)
        return k, t - k * self.leg_duration

    def _raw_position_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        k, dt = self._legs_at(t)
        return self._starts.data[k, idx] + self._vel_data[k, idx] * dt[:, None]

    def _raw_velocity_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        k, _ = self._legs_at(t)
        return self._vel_data[k, idx]

    def leg_velocities(self, count: int) -> Array:
        """Unconstrained velocities (count, n, 3) of the first ``count`` legs (for analysis)."""
        if count <= 0:
            return np.empty((0, self.n, 3))
        self._leg((count - 1) * self.leg_duration)
        return self._vel_data[:count].copy()


class NoisyConstantVelocity(Mobility):
    """The discrete-time nearly-constant-velocity target of tracking papers (e.g. MSWPF eqs 1-3,
    38-40): states sampled every ``dt`` s from ``start_s`` on, x_{k+1} = F x_k + w_k with the
    exactly discretized white-noise-acceleration covariance of density ``q`` (m^2/s^3) on each
    moving axis (x, y; and z with ``vertical``). Between samples the node moves in a straight
    line (the reported velocity is that segment's), so positions at the sample instants are
    exactly the model's; before ``start_s`` it rests at its initial position. Steps are drawn
    from ``rng`` in fixed blocks of 64, all nodes at once, as far as queries reach.

    ``confine_steps`` > 0: the first that many steps of a node are drawn again (from the same
    stream) until its track stays inside the box: the CV model conditioned on staying in the
    scenario volume (rejection sampling, so each accepted track is an exact draw of the
    conditioned model; e.g. a tracking paper's target that stays in its sensor field). Later
    steps, if queried, continue unconditioned. ``max_redraws`` bounds the attempts per node.
    """

    _BLOCK = 64

    def __init__(
        self,
        initial_positions: ArrayLike,
        box: Box,
        rng: np.random.Generator | None = None,
        *,
        velocity: ArrayLike = (0.0, 0.0, 0.0),
        q: float = 1.0,
        dt: float = 1.0,
        start_s: float = 0.0,
        vertical: bool = False,
        confine_steps: int = 0,
        max_redraws: int = 100000,
    ) -> None:
        super().__init__(initial_positions, box, rng)
        self._steps_rng = _need_rng(rng, "NoisyConstantVelocity")
        v = np.asarray(velocity, dtype=float)
        try:
            v = np.broadcast_to(v, (self.n, 3)).copy()
        except ValueError:
            raise ValueError(f"velocity must be a 3-vector or shape ({self.n}, 3), got {v.shape}") from None
        if not np.all(np.isfinite(v)):
            raise ValueError("velocity must be finite")
        if not (math.isfinite(q) and q >= 0.0):
            raise ValueError(f"q must be >= 0 and finite, got {q!r}")
        self.dt = _positive("dt", dt)
        self.start_s = float(start_s)
        if not (math.isfinite(self.start_s) and self.start_s >= 0.0):
            raise ValueError(f"start_s must be >= 0 and finite, got {start_s!r}")
        self.vertical = bool(vertical)
        if not self.vertical:
            v[:, 2] = 0.0
        self.q = float(q)
        T = self.dt
        # per axis: [p, v] covariance of the exact CWNA discretization, as a Cholesky factor
        self._L = np.linalg.cholesky(q * np.array([[T**3 / 3.0, T**2 / 2.0], [T**2 / 2.0, T]]) + 1e-300 * np.eye(2))
        self._P = _Table(self._p0)
        self._V = _Table(v)
        self.redraws = 0  # tracks drawn again by the confinement, all nodes
        if int(confine_steps) < 0 or int(max_redraws) < 1:
            raise ValueError(f"confine_steps must be >= 0 and max_redraws >= 1, got {confine_steps!r}, {max_redraws!r}")
        if confine_steps:
            self._confine(int(confine_steps), int(max_redraws))

    def _steps(self, z: Array, p: Array, v: Array) -> tuple[Array, Array]:
        """States after each of the steps of standard normals ``z`` (b, n, 3, 2) from (p, v)."""
        w = z @ self._L.T  # (b, n, 3, [p, v])
        if not self.vertical:
            w[:, :, 2, :] = 0.0
        ps, vs = np.empty(z.shape[:3]), np.empty(z.shape[:3])
        for j in range(z.shape[0]):  # a recursion in time (over steps, not nodes)
            p = p + self.dt * v + w[j, :, :, 0]
            v = v + w[j, :, :, 1]
            ps[j], vs[j] = p, v
        return ps, vs

    def _confine(self, steps: int, max_redraws: int) -> None:
        """Draw the first ``steps`` steps, each node's again until its track stays in the box."""
        p0, v0 = self._P.last.copy(), self._V.last.copy()
        ps, vs = self._steps(self._steps_rng.standard_normal((steps, self.n, 3, 2)), p0, v0)
        out: NDArray[np.bool_] = np.asarray(~self.box.contains(ps).all(axis=0))  # (n,)
        tries = 1
        while out.any():
            if tries >= max_redraws:
                raise ValueError(
                    f"no track of node(s) {np.flatnonzero(out).tolist()} stayed in {self.box!r} for "
                    f"{steps} steps in {max_redraws} draws: a larger volume, fewer confine_steps or a smaller q"
                )
            idx = np.flatnonzero(out)
            z = self._steps_rng.standard_normal((steps, idx.size, 3, 2))
            ps[:, idx], vs[:, idx] = self._steps(z, p0[idx], v0[idx])
            out[idx] = ~self.box.contains(ps[:, idx]).all(axis=0)
            self.redraws += idx.size
            tries += 1
        self._P.append(ps)
        self._V.append(vs)

    def _draw_block(self) -> None:
        z = self._steps_rng.standard_normal((self._BLOCK, self.n, 3, 2))
        ps, vs = self._steps(z, self._P.last.copy(), self._V.last.copy())
        self._P.append(ps)
        self._V.append(vs)

    def _seg(self, t: Array) -> tuple[NDArray[np.intp], Array]:
        """Segment index k (-1 before the start) and time into it."""
        u = (t - self.start_s) / self.dt
        k = np.where(u < 0.0, -1, np.floor(u)).astype(np.intp)
        kmax = int(k.max()) if k.size else 0
        while self._P.count <= kmax + 1:
            self._draw_block()
        return k, t - self.start_s - np.maximum(k, 0) * self.dt

    def _at(self, idx: NDArray[np.intp], t: Array) -> tuple[Array, Array]:
        k, tau = self._seg(t)
        kk = np.maximum(k, 0)
        p0 = self._P.data[kk, idx]
        seg_v = (self._P.data[kk + 1, idx] - p0) / self.dt
        before = (k < 0)[:, None]
        pos = np.where(before, self._p0[idx], p0 + seg_v * tau[:, None])
        return pos, np.where(before, 0.0, seg_v)

    def _raw_position(self, t: float) -> Array:
        idx = np.arange(self.n)
        return self._at(idx, np.full(self.n, t))[0]

    def _raw_velocity(self, t: float) -> Array:
        idx = np.arange(self.n)
        return self._at(idx, np.full(self.n, t))[1]

    def _raw_position_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        return self._at(idx, t)[0]

    def _raw_velocity_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        return self._at(idx, t)[1]


class Waypoints(Mobility):
    """Constant speed along straight segments: initial position -> waypoints[i][0] -> ... .

    ``waypoints``: per node a sequence of points (array (n, m, 3) or a list of n arrays
    (m_i, 3)), all inside the box (the box is convex, so paths never need folding). ``speed``
    (m/s, scalar or (n,)). After the last point a node stops (``loop=False``) or heads back to
    its initial position and repeats the cycle (``loop=True``).
    """

    _folds = False

    def __init__(
        self,
        initial_positions: ArrayLike,
        box: Box,
        rng: np.random.Generator | None = None,
        *,
        waypoints: ArrayLike | Sequence[ArrayLike],
        speed: ArrayLike = 1.0,
        loop: bool = False,
    ) -> None:
        super().__init__(initial_positions, box, rng)
        n = self.n
        wps: Sequence[ArrayLike] = waypoints  # type: ignore[assignment]  # an (n, m, 3) array is a sequence too
        if len(wps) != n:
            raise ValueError(f"waypoints must give one list of points per node ({n}), got {len(wps)}")
        self.speed = _readonly(_per_node("speed", speed, n, minimum=0.0))
        self.loop = bool(loop)
        paths = []
        for i, w in enumerate(wps):
            wa = np.asarray(w, dtype=float)
            if wa.ndim != 2 or wa.shape[1] != 3 or wa.shape[0] < 1:
                raise ValueError(f"waypoints of node {i} must have shape (m, 3) with m >= 1, got {wa.shape}")
            if not np.all(np.isfinite(wa)) or not np.all(box.contains(wa)):
                raise ValueError(f"waypoints of node {i} must be finite and inside {box!r}")
            legs = [self._p0[i : i + 1], wa] + ([self._p0[i : i + 1]] if self.loop else [])
            paths.append(np.concatenate(legs))
        m = max(len(p) for p in paths)
        # Pad with repeats of the last point: zero-length segments take no time.
        pts = np.stack([np.concatenate([p, np.repeat(p[-1:], m - len(p), axis=0)]) for p in paths])
        #: Path corners per node (n, M + 1, 3), starting at the initial position.
        self.points = _readonly(pts)
        seg = np.diff(pts, axis=1)  # (n, M, 3)
        length = np.linalg.norm(seg, axis=-1)
        with np.errstate(invalid="ignore", divide="ignore"):
            unit = np.where(length[..., None] > 0.0, seg / length[..., None], 0.0)
        self._starts = _readonly(pts[:, :-1])
        self._unit = _readonly(unit)
        self._cum = _readonly(np.concatenate([np.zeros((n, 1)), np.cumsum(length, axis=1)[:, :-1]], axis=1))
        self.path_length = _readonly(length.sum(axis=1))
        segs = self._cum.shape[1]
        self._row_base = np.arange(n) * segs - 1
        self._starts_flat = self._starts.reshape(n * segs, 3)
        self._unit_flat = self._unit.reshape(n * segs, 3)
        self._cum_flat = self._cum.reshape(n * segs)
        self._closed = self.path_length > 0.0
        self._safe_total = np.where(self._closed, self.path_length, 1.0)

    def _locate(self, idx: NDArray[np.intp] | slice, t: float | Array) -> tuple[Array, NDArray[np.intp], Array]:
        """(arc length travelled, flat segment index, speed now) for nodes ``idx`` at ``t``."""
        speed = self.speed[idx]
        s = speed * t
        if self.loop:
            closed = self._closed[idx]
            s = np.where(closed, np.mod(s, self._safe_total[idx]), 0.0)
            speed_now = np.where(closed, speed, 0.0)
        else:
            total = self.path_length[idx]
            speed_now = np.where(s < total, speed, 0.0)
            np.minimum(s, total, out=s)
        # Last segment starting at or before s: skips zero-length segments.
        k = np.count_nonzero(self._cum[idx] <= s[:, None], axis=1)
        k += self._row_base[idx]  # row * M - 1
        return s, k, speed_now

    def _place(self, s: Array, k: NDArray[np.intp]) -> Array:
        along = s - np.take(self._cum_flat, k)
        return np.take(self._starts_flat, k, axis=0) + np.take(self._unit_flat, k, axis=0) * along[:, None]

    def _raw_position(self, t: float) -> Array:
        s, k, _ = self._locate(slice(None), t)
        return self._place(s, k)

    def _raw_velocity(self, t: float) -> Array:
        _, k, speed_now = self._locate(slice(None), t)
        return np.take(self._unit_flat, k, axis=0) * speed_now[:, None]

    def _raw_position_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        s, k, _ = self._locate(idx, t)
        return self._place(s, k)

    def _raw_velocity_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        _, k, speed_now = self._locate(idx, t)
        return np.take(self._unit_flat, k, axis=0) * speed_now[:, None]
