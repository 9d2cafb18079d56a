"""The MAC library: one small component per node between its protocol and its modem, chosen
per node group by name (``mac = "..."`` with ``mac_params``), so any protocol runs over any MAC.

==================  ==========================================================================
``direct``          none: the modem's own FIFO, the default (:mod:`.direct`)
``aloha``           pure ALOHA, Abramson 1970 (:mod:`.aloha`)
``slotted_aloha``   slotted ALOHA with a guard time, Roberts 1975 (:mod:`.slotted_aloha`)
``csma``            non-persistent CSMA, Kleinrock and Tobagi 1975 (:mod:`.csma`)
``sfama``           Slotted FAMA, an RTS / CTS / DATA / ACK handshake, Molins and Stojanovic
                    2006 (:mod:`.sfama`)
``tdma``            fixed-assignment TDMA with guard times (:mod:`.tdma`)
==================  ==========================================================================

The contract every MAC keeps with its node and protocol is in :mod:`.base`.
"""

from __future__ import annotations

from .aloha import Aloha
from .base import ACK, CONTROL_KINDS, CTS, DROP_REASONS, RTS, Frame, Mac, MacParams, MacPort
from .csma import Csma
from .direct import Direct
from .sfama import SlottedFama
from .slotted_aloha import SlottedAloha
from .tdma import Tdma

__all__ = [
    "ACK",
    "CONTROL_KINDS",
    "CTS",
    "DROP_REASONS",
    "MACS",
    "RTS",
    "Aloha",
    "Csma",
    "Direct",
    "Frame",
    "Mac",
    "MacParams",
    "MacPort",
    "SlottedAloha",
    "SlottedFama",
    "Tdma",
    "UnknownMacError",
    "get",
]

#: name -> MAC class
MACS: dict[str, type[Mac]] = {cls.name: cls for cls in (Direct, Aloha, SlottedAloha, Csma, SlottedFama, Tdma)}


class UnknownMacError(KeyError):
    """No MAC of that name."""

    def __str__(self) -> str:
        return f"unknown MAC {self.args[0]!r} (available: {', '.join(MACS)})"


def get(name: str) -> type[Mac]:
    """The MAC class called ``name``."""
    try:
        return MACS[name]
    except KeyError:
        raise UnknownMacError(name) from None
