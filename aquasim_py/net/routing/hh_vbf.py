"""``hh_vbf``: hop-by-hop vector-based forwarding (N. Nicolaou, A. See, P. Xie, J.-H. Cui and
D. Maggiorini, "Improving the Robustness of Location-Based Routing for Underwater Sensor
Networks", IEEE OCEANS 2007 Europe; also in the journal version of VBF, Xie et al., EURASIP
JWCN 2010).

VBF's single pipe from the source to the target is empty in a sparse network or around a void.
HH-VBF redefines the routing pipe at every hop: its axis runs from the node that sent the copy
(F) to the target, so each forwarder steers the packet from where it is. Everything else is
VBF's (:mod:`.vbf`): the pipe radius W, the desirableness factor, the holding time and the
self-adaptation, in which a node's factor relative to each forwarder it heard is taken in that
forwarder's own pipe (Aqua-Sim NG's ``HopByHop`` keeps the first copy's pipe for all of them).
"""

from __future__ import annotations

from .vbf import Point, Vbf, VbfHeader

__all__ = ["HhVbf"]


class HhVbf(Vbf):
    """Hop-by-hop VBF: the pipe of each copy starts at its sender (module docstring)."""

    name = "hh_vbf"

    def pipe_start(self, header: VbfHeader, forwarder: Point) -> Point:
        """Where the pipe's axis starts: the forwarder."""
        return forwarder
