"""Current-driven mobility: nodes drifting with an ocean current field (the SLMP / STVF kinematic
model, Bower's meandering jet)."""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .base import Array, Mobility, _need_rng, _positive, _readonly, _Table, _time
from .box import Box

__all__ = ["Kinematic", "MeanderingCurrent", "MeanderingJet"]


class _CurrentDrift(Mobility):
    """Passive drift in a 2-D velocity field given in dimensionless units (shared machinery).

    Physical units: x = origin_x + length_scale x', y = origin_y + length_scale y',
    t = time_scale (t' - phase), v = (length_scale / time_scale) v'. Subclasses give the field
    in :meth:`_dimensionless` (per-node parameters broadcast on the last axis).

    Trajectories are integrated once, in fixed chunks of ``_CHUNK`` table steps from t = 0
    (scipy DOP853, rtol 1e-12, all nodes in one state vector), into a table of positions and
    velocities every ``time_scale / steps_per_unit`` seconds (packed: one (2, 3) row per knot
    and node, so a batch of queries gathers each knot's position and velocity at once), and
    read back by cubic Hermite interpolation: ``position`` is C1, ``velocity`` its exact
    derivative, a query costs microseconds and the result does not depend on the order of
    queries. The field acts on the unconstrained path, which is then folded into the box
    (mirror walls). Depth is constant.
    """

    _CHUNK = 256
    _NAME = "current"

    def _init_scales(
        self, length_scale: float, time_scale: float, phase: float, steps_per_unit: int, origin: ArrayLike
    ) -> None:
        self.length_scale = _positive("length_scale", length_scale)
        self.time_scale = _positive("time_scale", time_scale)
        self.phase = float(phase)
        if not math.isfinite(self.phase):
            raise ValueError(f"phase must be finite, got {phase!r}")
        if int(steps_per_unit) != steps_per_unit or steps_per_unit < 16:
            raise ValueError(f"steps_per_unit must be an integer >= 16, got {steps_per_unit!r}")
        self.steps_per_unit = int(steps_per_unit)
        o = np.asarray(origin, dtype=float).reshape(-1)
        if o.shape != (2,) or not np.all(np.isfinite(o)):
            raise ValueError(f"origin must be a finite (x, y) pair in m, got {origin!r}")
        self.origin = _readonly(o)
        self._ox, self._oy = float(o[0]), float(o[1])

    def _init_table(self) -> None:
        self._speed_scale = self.length_scale / self.time_scale
        self._h = self.time_scale / self.steps_per_unit  # table step, s
        self._inv_h = 1.0 / self._h
        p0 = self._p0.copy()
        self._pv = _Table(np.stack((p0, self.field(p0, 0.0)), axis=1))  # (K, n, 2, 3): position, velocity
        self._state_t = math.nan  # the time of the kept state (see state)
        self._state: tuple[Array, Array] = (p0, p0)

    def _dimensionless(self, x: Array, y: Array, tp: Array | float) -> tuple[Array, Array]:
        raise NotImplementedError

    def field(self, p: ArrayLike, t: ArrayLike) -> Array:
        """Current velocity (m/s), shape (..., n, 3) with vz = 0, at unfolded positions ``p`` (..., n, 3), time ``t`` (s, broadcast to p[..., 0])."""
        pa = np.asarray(p, dtype=float)
        tp = np.asarray(t, dtype=float) / self.time_scale + self.phase
        L = self.length_scale
        # origin 0 leaves x exactly as it is (x - 0.0 == x): the kinematic model's traces
        # stayed byte-identical when the origin was introduced.
        vx, vy = self._dimensionless((pa[..., 0] - self._ox) / L, (pa[..., 1] - self._oy) / L, tp)
        return np.stack((vx, vy, np.zeros_like(vx)), axis=-1) * self._speed_scale

    def _rhs(self, tp: float, s: Array) -> Array:
        """Dimensionless ODE right-hand side, state (x'_1..x'_n, y'_1..y'_n)."""
        n = self.n
        return np.concatenate(self._dimensionless(s[:n], s[n:], tp))

    def _extend(self) -> None:
        """Integrate one more chunk of ``_CHUNK`` table steps from the last knot."""
        from scipy.integrate import solve_ivp

        n, spu, L = self.n, self.steps_per_unit, self.length_scale
        k0 = self._pv.count - 1
        last = self._pv.last[:, 0]
        s0 = np.concatenate(((last[:, 0] - self._ox) / L, (last[:, 1] - self._oy) / L))
        # Knot times in dimensionless units; computed from integers so chunks tile exactly.
        tgrid = self.phase + np.arange(k0, k0 + self._CHUNK + 1) / spu
        sol = solve_ivp(self._rhs, (tgrid[0], tgrid[-1]), s0, method="DOP853", t_eval=tgrid[1:], rtol=1e-12, atol=1e-13)
        if not sol.success:  # pragma: no cover - the fields are smooth and bounded
            raise RuntimeError(f"{type(self).__name__} integration failed: {sol.message}")
        xy = sol.y.T * L  # (C, 2n)
        pos = np.empty((self._CHUNK, n, 3))
        pos[:, :, 0] = xy[:, :n] + self._ox
        pos[:, :, 1] = xy[:, n:] + self._oy
        pos[:, :, 2] = self._p0[:, 2]
        times = (np.arange(k0 + 1, k0 + self._CHUNK + 1)) * self._h
        vel = self.field(pos, times[:, None])
        self._pv.append(np.stack((pos, vel), axis=2))

    def _knots_at(self, idx: NDArray[np.intp], t: Array) -> tuple[NDArray[np.intp], NDArray[np.intp], Array]:
        """Flat row indices of (knot i, knot i + 1) per pair, and the fraction u (m, 1)."""
        x = t * self._inv_h
        i = x.astype(np.intp)  # t >= 0: truncation is floor
        if i.size:
            self._knot(float(t.max()))
        flat = i * self.n + idx
        return flat, flat + self.n, (x - i)[:, None]

    def _gather(self, idx: NDArray[np.intp], t: Array) -> tuple[Array, Array, Array, Array, Array]:
        """(P_a, V_a, P_b, V_b, u): position and velocity at the knots around each (node, time)
        pair (each (m, 3), strided views of two gathers) and the fraction u (m, 1)."""
        a, b, u = self._knots_at(idx, t)
        pv = self._pv.data.reshape(-1, 2, 3)
        ga, gb = pv.take(a, 0), pv.take(b, 0)
        return ga[:, 0], ga[:, 1], gb[:, 0], gb[:, 1], u

    def _hermite(self, pa: Array, va: Array, pb: Array, vb: Array, u: Array | float) -> Array:
        um = 1.0 - u
        h00 = (1.0 + 2.0 * u) * um * um
        h10 = u * um * um * self._h
        h01 = u * u * (3.0 - 2.0 * u)
        h11 = -u * u * um * self._h
        return h00 * pa + h10 * va + h01 * pb + h11 * vb

    def _hermite_derivative(self, pa: Array, va: Array, pb: Array, vb: Array, u: Array | float) -> Array:
        um = 1.0 - u
        d00 = 6.0 * u * um * self._inv_h
        d10 = um * (1.0 - 3.0 * u)
        d11 = u * (3.0 * u - 2.0)
        return d00 * (pb - pa) + d10 * va + d11 * vb

    def state(self, t: float) -> tuple[Array, Array]:
        """``Mobility.state``, kept for the last time asked (read-only arrays): at one instant
        a group's positions and velocities are asked for several times (a beacon's position
        fix, depth and velocity sensors, then the channel), each a full evaluation before."""
        tf = _time(t)
        if tf != self._state_t:
            pos, vel = super().state(tf)
            pos.flags.writeable = False
            vel.flags.writeable = False
            self._state_t, self._state = tf, (pos, vel)
        return self._state

    def position(self, t: float) -> Array:
        """Positions (n, 3) in m at true time ``t`` (s), read-only (see :meth:`state`)."""
        return self.state(t)[0]

    def _raw_position_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        return self._hermite(*self._gather(idx, t))

    def _raw_velocity_at(self, idx: NDArray[np.intp], t: Array) -> Array:
        return self._hermite_derivative(*self._gather(idx, t))

    def _raw_state_at(self, idx: NDArray[np.intp], t: Array) -> tuple[Array, Array]:
        g = self._gather(idx, t)
        return self._hermite(*g), self._hermite_derivative(*g)

    def _knot(self, t: float) -> tuple[int, float]:
        x = t * self._inv_h
        i = int(x)
        while i + 1 >= self._pv.count:
            self._extend()
        return i, x - i

    def _raw_position(self, t: float) -> Array:
        # cubic Hermite on [t_i, t_i + h], every node (the rows of the knots i and i + 1)
        i, u = self._knot(t)
        a, b = self._pv.data[i], self._pv.data[i + 1]
        return self._hermite(a[:, 0], a[:, 1], b[:, 0], b[:, 1], u)

    def _raw_velocity(self, t: float) -> Array:
        i, u = self._knot(t)
        a, b = self._pv.data[i], self._pv.data[i + 1]
        return self._hermite_derivative(a[:, 0], a[:, 1], b[:, 0], b[:, 1], u)


class Kinematic(_CurrentDrift):
    """Drift in the kinematic ocean-current model of SLMP (STVF, Sensors 2018, Sec. 5.1).

    Scenario name ``kinematic`` (``meandering_current`` is its deprecated alias). Dimensionless
    velocity field (STVF's unnumbered equation after Table 1), x, y, t dimensionless::

        Vx = k1 iota omega sin(k2 x) cos(k3 y) + k1 iota cos(2 k1 t) + k4
        Vy = -iota omega cos(k2 x) sin(k3 y) + k5

    Each node draws its own k1..k5, iota, omega from N(mean, (rel_std * mean)^2) (Table 1 gives
    N(mean, precision) with std 10 % of the mean). Physical units: see :class:`_CurrentDrift`
    (``origin`` defaults to (0, 0)). Defaults: ``time_scale`` = 44712 s (12.42 h, the
    semidiurnal M2 tide: cos(2 k1 t') then has the tidal period at the mean k1 = pi) and
    ``length_scale`` = 4471.2 m (speed scale 0.1 m/s), which give a mean speed of about
    1.0 m/s at phase 0 and about 105 m covered in 100 s, as in STVF's sample trajectory
    (~110 m in 100 s). Depth stays constant (the model is 2-D).
    """

    _PARAMS = ("k1", "k2", "k3", "iota", "omega", "k4", "k5")
    # per-node draws (n,), set in __init__ by name
    k1: Array
    k2: Array
    k3: Array
    k4: Array
    k5: Array
    iota: Array
    omega: Array

    def __init__(
        self,
        initial_positions: ArrayLike,
        box: Box,
        rng: np.random.Generator | None = None,
        *,
        length_scale: float = 4471.2,
        time_scale: float = 44712.0,
        phase: float = 0.0,
        origin: ArrayLike = (0.0, 0.0),
        k1: float = math.pi,
        k2: float = math.pi,
        k3: float = 2.0 * math.pi,
        iota: float = 3.0,
        omega: float = 1.0,
        k4: float = 1.0,
        k5: float = 1.0,
        rel_std: float = 0.1,
        steps_per_unit: int = 2048,
    ) -> None:
        super().__init__(initial_positions, box, rng)
        self._init_scales(length_scale, time_scale, phase, steps_per_unit, origin)
        self.rel_std = float(rel_std)
        if not (0.0 <= self.rel_std < math.inf):
            raise ValueError(f"rel_std must be >= 0, got {rel_std!r}")
        means = dict(k1=k1, k2=k2, k3=k3, iota=iota, omega=omega, k4=k4, k5=k5)
        gen = _need_rng(rng, type(self).__name__) if self.rel_std > 0.0 else None
        for name in self._PARAMS:  # fixed draw order: the same seed gives the same nodes
            mean = float(means[name])
            if not math.isfinite(mean):
                raise ValueError(f"{name} must be finite, got {means[name]!r}")
            vals = gen.normal(mean, self.rel_std * abs(mean), self.n) if gen is not None else np.full(self.n, mean)
            setattr(self, name, _readonly(vals))
        self._init_table()

    def _dimensionless(self, x: Array, y: Array, tp: Array | float) -> tuple[Array, Array]:
        """(Vx', Vy') of the STVF field at dimensionless x', y', t' (per-node parameters broadcast on the last axis)."""
        a = self.iota * self.omega
        tide = self.k1 * self.iota * np.cos(2.0 * self.k1 * tp)
        vx = self.k1 * a * np.sin(self.k2 * x) * np.cos(self.k3 * y) + tide + self.k4
        vy = -a * np.cos(self.k2 * x) * np.sin(self.k3 * y) + self.k5
        return vx, vy


class MeanderingCurrent(Kinematic):
    """Deprecated name of :class:`Kinematic` (the STVF/SLMP model, not Caruso's meandering
    current): warns on construction. The Bower/Caruso model is :class:`MeanderingJet`."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        warnings.warn(
            "mobility.MeanderingCurrent is deprecated: it is the STVF/SLMP kinematic model, now "
            "mobility.Kinematic; the Bower/Caruso meandering current is mobility.MeanderingJet",
            DeprecationWarning,
            stacklevel=2,
        )
        super().__init__(*args, **kwargs)


class MeanderingJet(_CurrentDrift):
    """Drift in Bower's (1991) kinematic meandering jet, the "meandering current mobility
    model" of Caruso, Paparella, Vieira, Erol and Gerla (IEEE INFOCOM 2008).

    Scenario name ``meandering_jet``. Dimensionless stream function (Bower 1991, as used by
    Caruso et al.), with theta = k (x' - c t') and B(t') = A + epsilon cos(omega t')::

        psi(x', y', t') = 1 - tanh( (y' - B cos theta) / sqrt(1 + k^2 B^2 sin^2 theta) )

    and velocity u' = -d psi / d y', v' = d psi / d x' (analytic derivatives below): an
    eastward jet of unit peak speed and unit half-width whose axis y' = B cos(theta) meanders
    with wavelength 2 pi / k, moves east at c and breathes with period 2 pi / omega (the
    breathing makes fluid cross between jet and recirculation cells: chaotic transport).
    The authors' SmmLib code writes the same field as sin theta over sqrt(1 + k^2 B^2 cos^2),
    i.e. shifted by a quarter wavelength in x.

    Defaults are Caruso et al.'s: A = 1.2, c = 0.12, k = 2 pi / 7.5 (``wavelength`` 7.5),
    omega = 0.4, epsilon = 0.3, with the authors' scaling (their SmmLib, README and test
    driver) of one length unit = 1 km and one time unit = 0.03 days = 2592 s: peak jet speed
    1000 / 2592 = 0.386 m/s, meander wavelength 7.5 km, amplitude 1.2 km, phase speed
    0.046 m/s, breathing period 2 pi / 0.4 units = 11.3 h. ``origin`` (m) is where x' = y' = 0
    (default: the box centre in x-y, so the jet axis crosses the scenario volume); ``phase`` is
    t' at t = 0 (Caruso et al. draw it uniformly on [0, 2 pi / (c k)); ``random_phase=True``
    or ``phase=None`` does so from ``rng``). All nodes share one field (no per-node parameters); depth stays constant.
    The field is divergence-free, so the flow preserves area in x-y.
    """

    def __init__(
        self,
        initial_positions: ArrayLike,
        box: Box,
        rng: np.random.Generator | None = None,
        *,
        amplitude: float = 1.2,
        phase_speed: float = 0.12,
        wavelength: float = 7.5,
        omega: float = 0.4,
        epsilon: float = 0.3,
        length_scale: float = 1000.0,
        time_scale: float = 2592.0,
        phase: float | None = 0.0,
        random_phase: bool = False,
        origin: ArrayLike | None = None,
        steps_per_unit: int = 128,
    ) -> None:
        super().__init__(initial_positions, box, rng)
        vals = dict(amplitude=amplitude, phase_speed=phase_speed, omega=omega, epsilon=epsilon)
        for name, v in vals.items():
            if not math.isfinite(float(v)):
                raise ValueError(f"{name} must be finite, got {v!r}")
        self.amplitude = float(amplitude)
        self.phase_speed = float(phase_speed)
        self.wavelength = _positive("wavelength", wavelength)
        self.k = 2.0 * math.pi / self.wavelength
        self.omega = float(omega)
        self.epsilon = float(epsilon)
        if phase is None or random_phase:
            # Caruso et al.: a random shift over one meander passage period 2 pi / (c k).
            period = 2.0 * math.pi / (abs(self.phase_speed) * self.k) if self.phase_speed else 2.0 * math.pi
            phase = float(_need_rng(rng, "MeanderingJet with a random phase").uniform(0.0, period))
        if origin is None:
            origin = 0.5 * (box.lo[:2] + box.hi[:2])
        self._init_scales(length_scale, time_scale, phase, steps_per_unit, origin)
        self._init_table()

    def _axis(self, x: Array, y: Array, tp: Array | float) -> tuple[Array, Array, Array, Array, Array]:
        """(B, sin theta, cos theta, D, eta) with eta = (y' - B cos theta) / D."""
        B = self.amplitude + self.epsilon * np.cos(self.omega * np.asarray(tp, dtype=float))
        th = self.k * (x - self.phase_speed * tp)
        s, c = np.sin(th), np.cos(th)
        D = np.sqrt(1.0 + (self.k * B * s) ** 2)
        return B, s, c, D, (y - B * c) / D

    def stream_function(self, p: ArrayLike, t: ArrayLike) -> Array:
        """Dimensionless psi at positions ``p`` (..., 3) in m and times ``t`` (s, broadcast)."""
        pa = np.asarray(p, dtype=float)
        L = self.length_scale
        tp = np.asarray(t, dtype=float) / self.time_scale + self.phase
        eta = self._axis((pa[..., 0] - self._ox) / L, (pa[..., 1] - self._oy) / L, tp)[4]
        return 1.0 - np.tanh(eta)

    def _dimensionless(self, x: Array, y: Array, tp: Array | float) -> tuple[Array, Array]:
        B, s, c, D, eta = self._axis(x, y, tp)
        # sech^2 eta = 4 e^{-2|eta|} / (1 + e^{-2|eta|})^2: no overflow far from the jet.
        e = np.exp(-2.0 * np.abs(eta))
        sech2 = 4.0 * e / (1.0 + e) ** 2
        k = self.k
        # d eta / d y' = 1 / D;  d eta / d x' = k B sin / D - eta k^3 B^2 sin cos / D^2
        u = sech2 / D
        deta_dx = k * B * s / D - eta * (k**3 * B * B * s * c) / (D * D)
        return u, -sech2 * deta_dx
