"""The energy a node's modem draws, by modem state, and the node's optional battery.

Kernel side, fed by the channel: the channel tells a node's :class:`EnergyMeter` each of its
transmissions (at their first bit), each signal its modem detects (when the signal is sent, its
arrival and end already known), and each sleep and wake; the meter charges the time in between
lazily, at the power of the state the modem was in, when asked (:meth:`EnergyMeter.advance`),
as ns-3's ``AcousticModemEnergyModel`` charges at each state change. No event and no polling:
the battery's depletion instant is found exactly, inside the piece of constant power where the
drawn energy reaches the capacity, the first time anyone asks about a later instant (the
channel, before the node sends or receives; the kernel, at the end of a run).

States and their power (``[channel] tx_power_w``, ``rx_power_w``, ``idle_power_w``,
``sleep_power_w``), by precedence:

- "tx": while the node transmits (each packet's whole airtime, preamble included);
- "sleep": while the protocol has put the modem to sleep (``Node.modem_sleep``);
- "rx": while a signal the modem detects is arriving (its SNR at or above the detection
  threshold; overlapping signals count once); weaker signals leave the modem idle, as ns-3
  bills its CCA-busy state at idle power;
- "idle": listening otherwise.

A node whose battery is empty (the energy drawn reached ``capacity_j``) is dead from that
instant: its modem neither sends nor receives (the channel drops what it would have sent or
received with reason "energy") and draws nothing. A transmission under way when the battery
empties still reaches its receivers (its signal is already in the water; ns-3 does the same),
but its energy is charged only up to the depletion.

The kernel writes one ``energy`` row per node at the end of each run (:data:`ENERGY_COLUMNS`);
the ``energy.*`` metrics (:func:`aquasim_py.metrics.energy_metrics`) are computed from it.
"""

from __future__ import annotations

import math

__all__ = ["ENERGY_COLUMNS", "STATES", "EnergyMeter"]

#: modem states, in the order of the power tuple (tx, rx, idle, sleep)
STATES = ("tx", "rx", "idle", "sleep")
_TX, _RX, _IDLE, _SLEEP = range(4)

#: the ``energy`` table's columns: at true time ``time`` (s, the end of a run), per node the
#: energy drawn (J) in total and by state, the seconds spent in each state, the battery's
#: capacity (J; NaN: no battery) and the true time it was depleted (s; NaN: it was not)
ENERGY_COLUMNS = (
    "time",
    "node",
    "energy_j",
    "tx_j",
    "rx_j",
    "idle_j",
    "sleep_j",
    "tx_s",
    "rx_s",
    "idle_s",
    "sleep_s",
    "capacity_j",
    "depleted_at",
)

#: pending intervals a meter keeps before it charges up to now on its own (bounds its memory
#: for a node that is told of many signals and asked about none)
_PENDING_CAP = 64


class EnergyMeter:
    """One node's modem energy, charged lazily by state (see the module docstring).

    power: (tx, rx, idle, sleep) in W. capacity_j: the battery (None: unlimited).

    Intervals are given in true seconds; a transmission or a sleep starts at the instant it is
    reported, a detected signal may start later (it is reported when it is sent). :meth:`advance`
    to t charges [since, t): every interval that starts before t is known by then.
    """

    __slots__ = ("capacity", "depleted_at", "joules", "power", "rx", "seconds", "since", "sleeps", "tx")

    def __init__(self, power: tuple[float, float, float, float], capacity_j: float | None = None) -> None:
        if len(power) != 4 or not all(math.isfinite(p) and p >= 0.0 for p in power):
            raise ValueError(f"EnergyMeter: power must be four values >= 0 W (tx, rx, idle, sleep), got {power!r}")
        if capacity_j is not None and not (math.isfinite(capacity_j) and capacity_j > 0.0):
            raise ValueError(f"EnergyMeter: a battery needs a capacity > 0 J, got {capacity_j!r}")
        self.power = tuple(float(p) for p in power)
        self.capacity = capacity_j
        self.since = 0.0  # charged up to this true time (s)
        self.joules = [0.0, 0.0, 0.0, 0.0]  # by state
        self.seconds = [0.0, 0.0, 0.0, 0.0]
        self.depleted_at = math.inf
        self.tx: list[tuple[float, float]] = []  # pending (start, end) of each kind
        self.rx: list[tuple[float, float]] = []
        self.sleeps: list[tuple[float, float]] = []  # end inf: asleep now

    # -- what the channel reports -------------------------------------------------------------

    def transmit(self, start: float, end: float) -> None:
        """The node transmits over [start, end) (true s)."""
        self.tx.append((start, end))

    def receive(self, start: float, end: float, now: float) -> None:
        """A signal the modem detects arrives over [start, end) (true s), reported at ``now``."""
        self.rx.append((start, end))
        if len(self.rx) > _PENDING_CAP:
            self.advance(now)

    def sleep(self, t: float) -> None:
        """The modem sleeps from ``t`` (true s) until :meth:`wake`."""
        if not (self.sleeps and self.sleeps[-1][1] == math.inf):
            self.sleeps.append((t, math.inf))

    def wake(self, t: float) -> None:
        """The modem wakes at ``t`` (true s); a sleep that has not begun yet is cancelled."""
        if self.sleeps and self.sleeps[-1][1] == math.inf:
            start = self.sleeps[-1][0]
            self.sleeps[-1] = (start, t)
            if start >= t:
                self.sleeps.pop()

    # -- charging -----------------------------------------------------------------------------

    def depleted_by(self, t: float) -> bool:
        """Whether the battery is empty at true time ``t`` (charging up to ``t`` first)."""
        self.advance(t)
        return self.depleted_at <= t

    def advance(self, t: float) -> None:
        """Charge the energy drawn over [since, t) (true s), state by state."""
        c = self.since
        if not t > c:
            return
        if self.depleted_at <= c:  # dead: draws nothing, and nothing more is reported
            self.since = t
            self.tx.clear()
            self.rx.clear()
            self.sleeps.clear()
            return
        # the instants where a state starts or ends inside [c, t), with the kind and the step
        events: list[tuple[float, int, int]] = []
        for kind, spans in ((_TX, self.tx), (_SLEEP, self.sleeps), (_RX, self.rx)):
            for a, b in spans:
                if a < t and b > c:
                    events.append((a if a > c else c, kind, 1))
                    if b < t:
                        events.append((b, kind, -1))
        events.sort()
        count = [0, 0, 0, 0]
        here = c
        for when, kind, step in events:
            if when > here and self._charge(here, when, count):
                break
            here = when if when > here else here
            count[kind] += step
        else:
            if t > here:
                self._charge(here, t, count)
        self.since = t
        for name in ("tx", "rx", "sleeps"):  # keep what goes on after t
            spans = getattr(self, name)
            if any(b <= t for _, b in spans):
                setattr(self, name, [s for s in spans if s[1] > t])

    def _charge(self, a: float, b: float, count: list[int]) -> bool:
        """Charge [a, b) at the state ``count`` says (by precedence tx, sleep, rx, idle); True
        when the battery empties inside it (``depleted_at`` is then set)."""
        state = _TX if count[_TX] else _SLEEP if count[_SLEEP] else _RX if count[_RX] else _IDLE
        p = self.power[state]
        dt = b - a
        cap = self.capacity
        if cap is not None and p > 0.0:
            left = cap - sum(self.joules)
            if p * dt >= left:
                dt = left / p
                self.joules[state] += left
                self.seconds[state] += dt
                self.depleted_at = a + dt
                return True
        self.joules[state] += p * dt
        self.seconds[state] += dt
        return False

    # -- the record ---------------------------------------------------------------------------

    def row(self, t: float) -> tuple[float, ...]:
        """The ``energy`` row values after ``time`` and ``node`` (:data:`ENERGY_COLUMNS`), charged
        up to ``t`` (true s)."""
        self.advance(t)
        j, s = self.joules, self.seconds
        return (
            sum(j),
            *j,
            *s,
            math.nan if self.capacity is None else self.capacity,
            math.nan if math.isinf(self.depleted_at) else self.depleted_at,
        )
