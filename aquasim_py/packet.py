"""Packets on the acoustic channel and what a receiving node gets back.

Payloads are copied, never shared: a packet carries a snapshot taken when the sender calls
``broadcast``/``send`` (:func:`snapshot_payload`), and each receiver gets its own copy of that
snapshot (:func:`copy_payload`) when it takes the reception (``recv``; the snapshot itself
reaches no node, so a copy made later is the same copy). So a sender changing its object after
sending reaches no receiver, and receivers cannot write into each other's packets (either would
be an instant, distance-free side channel). Cost: both are a deep copy, O(payload size) per
send and per reception taken; immutable parts (None, numbers, strings, bytes, numpy scalars,
and tuples and frozensets made only of those) are shared, not copied, so the usual payloads
(small dicts of numbers, tuples of numbers, short lists, 3-vectors) cost a few microseconds. Built-in
containers (dict, list, tuple, set, frozenset) and numpy arrays are copied by hand (fast
path); anything else goes through :func:`copy.deepcopy`.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Packet", "Reception", "copy_payload", "snapshot_payload"]

_ATOMS = (type(None), bool, int, float, complex, str, bytes)


def copy_payload(obj: Any) -> Any:
    """A deep copy of ``obj`` that shares only immutable parts (returns ``obj`` itself if it
    is immutable: an atom, or a tuple / frozenset of immutable parts); numpy arrays are copied
    (writable), mutable containers rebuilt with their type."""
    t = type(obj)
    if t in _ATOMS or isinstance(obj, np.generic):
        return obj
    if t is dict:
        out = obj.copy()  # keys and atoms shared; the rest replaced by copies (rarely needed)
        for k, v in obj.items():
            if type(v) not in _ATOMS:
                c = copy_payload(v)
                if c is not v:
                    out[k] = c
        return out
    if t is list:
        return [v if type(v) in _ATOMS else copy_payload(v) for v in obj]
    if t is tuple or t is frozenset:
        # A tuple whose items all come back as themselves holds nothing mutable, so no
        # receiver can change it: shared, not rebuilt (per reception, the common case).
        for v in obj:
            if type(v) not in _ATOMS and copy_payload(v) is not v:
                return t([copy_payload(u) for u in obj])
        return obj
    if t is np.ndarray and obj.dtype != object:
        return obj.copy()
    if t is set:
        return {copy_payload(v) for v in obj}
    return copy.deepcopy(obj)


#: The send-time snapshot is the same deep copy (kept as its own name: the two call sites
#: guard different things, see the module docstring).
snapshot_payload = copy_payload


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
