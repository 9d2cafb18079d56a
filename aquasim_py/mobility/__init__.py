"""Node mobility: exact, deterministic trajectories inside the scenario volume.

Coordinates are metres, (x, y, z) with z = depth, positive down; times are seconds of true
simulation time. One :class:`Mobility` object drives a group of ``n`` nodes, vectorized over
them: ``position(t)`` and ``velocity(t)`` return ``(n, 3)`` arrays, exact at any ``t >= 0``
and independent of the order of queries (queries never advance hidden state; random legs and
integrated current tables are extended lazily, always in the same fixed blocks from ``t = 0``).

Walls, surface and bottom reflect like mirrors: each model computes its *unconstrained*
trajectory and :meth:`Box.fold` folds it into the box coordinate-wise (a triangle wave per
axis). Folding is an exact specular reflection for any path, and the velocity is the folded
derivative (each component's sign flips on every bounce).

Models: :class:`Static`, :class:`ConstantVelocity`, :class:`CoordinatedTurn` (circle arcs in
x-y), :class:`RandomWalk` (piecewise-constant random legs), :class:`Kinematic` (the
kinematic ocean-current model of SLMP used in STVF's Table 1; ``MeanderingCurrent`` is its
deprecated alias), :class:`MeanderingJet` (Bower's meandering jet, the meandering current
mobility model of Caruso et al. 2008) and :class:`Waypoints`.
"""

from .base import Mobility
from .box import Box
from .currents import Kinematic, MeanderingCurrent, MeanderingJet
from .models import ConstantVelocity, CoordinatedTurn, NoisyConstantVelocity, RandomWalk, Static, Waypoints

__all__ = [
    "Box",
    "ConstantVelocity",
    "CoordinatedTurn",
    "Kinematic",
    "MeanderingCurrent",
    "MeanderingJet",
    "Mobility",
    "NoisyConstantVelocity",
    "RandomWalk",
    "Static",
    "Waypoints",
]
