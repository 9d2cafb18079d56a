"""A node's own position estimates stamped at their measurement epochs, carried to any instant.

A period-based localization (STVF) measures its ranges while the references' beacons arrive
(0.05-0.55 s into a 1-s period) and solves at the end of the listening window, 0.9 s in; the
node moves about 1 m/s. An estimate is therefore the node's position at its *measurement
epoch* (the mean receive stamp of the measurements it used), and whatever reads it later (its
own beacon as a promoted reference, the ``estimates`` row logged at the end of the window)
needs it carried from that epoch to its own instant with a velocity.

The velocity is the least-squares slope of the estimates of the last ``window_s`` seconds (at
least two): one period's difference of two estimates of a few metres' error each is a
velocity error of metres per second, while the ocean current accelerates by millimetres per
second squared (docs/stvf.md, "Beacon timing"). ``window_s = 0`` keeps the last two estimates
only: the one-period difference (the former behaviour).
"""

from __future__ import annotations

from collections import deque

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["EpochTrack"]


class EpochTrack:
    """Estimates ``(epoch, xy)`` (local s, m) of the last ``window_s`` seconds (plus the one
    before them, so that two periods' estimates always give a slope)."""

    def __init__(self, window_s: float) -> None:
        if not window_s >= 0:
            raise ValueError(f"window_s must be >= 0, got {window_s!r}")
        self.window_s = float(window_s)
        self._t: deque[float] = deque()
        self._xy: deque[NDArray[np.float64]] = deque()

    def __len__(self) -> int:
        return len(self._t)

    def add(self, epoch: float, xy: ArrayLike) -> None:
        """Record the estimate ``xy`` of the position at local time ``epoch``."""
        if self._t and epoch <= self._t[-1]:
            raise ValueError(f"epochs must increase: {epoch!r} after {self._t[-1]!r}")
        self._t.append(float(epoch))
        self._xy.append(np.asarray(xy, float).copy())
        while len(self._t) > 2 and self._t[-1] - self._t[1] >= self.window_s:
            self._t.popleft()
            self._xy.popleft()

    @property
    def last(self) -> tuple[float, NDArray[np.float64]] | None:
        """The latest ``(epoch, xy)``, or None before the first estimate."""
        return (self._t[-1], self._xy[-1]) if self._t else None

    def velocity(self) -> NDArray[np.float64]:
        """Least-squares velocity (m/s) over the window; zero with fewer than two estimates."""
        if len(self._t) < 2:
            return np.zeros(2)
        t = np.asarray(self._t)
        xy = np.asarray(self._xy)
        dt = t - t.mean()
        return np.asarray(dt @ (xy - xy.mean(axis=0)) / (dt @ dt), float)

    def at(self, t: float) -> NDArray[np.float64]:
        """The latest estimate carried to local time ``t`` with :meth:`velocity`."""
        if not self._t:
            raise ValueError("no estimate yet")
        return np.asarray(self._xy[-1] + self.velocity() * (t - self._t[-1]), float)
