"""The routing library: one small component per node between its protocol and its MAC that
carries packets over several hops to the surface sinks, chosen per node group by name
(``routing = "..."`` with ``routing_params``).

==================  ==========================================================================
``flooding``        every node forwards every datagram once (:mod:`.flooding`)
``vbf``             vector-based forwarding, Xie, Cui and Lao 2006 (:mod:`.vbf`)
``hh_vbf``          hop-by-hop VBF, Nicolaou et al. 2007 (:mod:`.hh_vbf`)
``dbr``             depth-based routing, Yan, Shi and Cui 2008 (:mod:`.dbr`)
``eedbr``           energy-efficient DBR, Wahid et al. 2011 (:mod:`.eedbr`)
==================  ==========================================================================

The contract every router keeps with its node, its MAC and the sinks is in :mod:`.base`; the
network metrics from its ``routes`` trace in :mod:`.metrics`.
"""

from __future__ import annotations

from .base import ROUTE_COLUMNS, Datagram, Header, Router, RouterParams, RouterPort
from .dbr import Dbr
from .eedbr import Eedbr
from .flooding import Flooding
from .hh_vbf import HhVbf
from .vbf import Vbf

__all__ = [
    "ROUTERS",
    "ROUTE_COLUMNS",
    "Datagram",
    "Dbr",
    "Eedbr",
    "Flooding",
    "Header",
    "HhVbf",
    "Router",
    "RouterParams",
    "RouterPort",
    "UnknownRouterError",
    "Vbf",
    "get",
]

#: name -> router class
ROUTERS: dict[str, type[Router]] = {cls.name: cls for cls in (Flooding, Vbf, HhVbf, Dbr, Eedbr)}


class UnknownRouterError(KeyError):
    """No router of that name."""

    def __str__(self) -> str:
        return f"unknown routing protocol {self.args[0]!r} (available: {', '.join(ROUTERS)})"


def get(name: str) -> type[Router]:
    """The router class called ``name``."""
    try:
        return ROUTERS[name]
    except KeyError:
        raise UnknownRouterError(name) from None
