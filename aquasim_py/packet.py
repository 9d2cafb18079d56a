"""Packets on the acoustic channel and what a receiving node gets back."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

__all__ = ["Packet", "Reception"]


@dataclass(frozen=True, slots=True)
class Packet:
    """One acoustic frame.

    ``dst`` is ``None`` for a broadcast. ``tx_local`` is the sender's MAC transmit stamp (s,
    sender's local clock): the instant the first bit left, as the sender's clock read it.
    ``bits`` sets the air time (bits / bitrate, s). ``payload`` is whatever the protocol put in it.
    """

    uid: int
    src: int
    dst: int | None
    kind: str
    payload: Any
    bits: int
    tx_local: float


@dataclass(frozen=True, slots=True)
class Reception:
    """A packet as a receiver got it.

    ``rx_local`` is the receiver's MAC stamp (s, receiver's local clock) of the first bit's
    arrival; ``snr_db`` the signal-to-noise ratio of the reception (NaN without a loss model).
    ``pressure`` is the received acoustic pressure the receiver's hydrophone measured (with its
    noise), for packets of the channel's ``pressure_kind`` (sound emissions); NaN otherwise.
    """

    packet: Packet
    rx_local: float
    snr_db: float
    pressure: float = math.nan
