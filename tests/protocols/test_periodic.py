"""The period cycle shared by STVF, SLMP and the multilateration bound: taking the inbox at once
and localizing in turn (``_Turns``) gives the traces of one ``recv()`` event per reception."""

import tomllib
from pathlib import Path

import pandas as pd
import pytest

from aquasim_protocols.common import periodic
from aquasim_py import scenario
from aquasim_py.node import Node

QUICK = Path(__file__).resolve().parents[2] / "scenarios" / "stvf_quick.toml"


def _tables(monkeypatch: pytest.MonkeyPatch, drain: bool, sets: list[str]) -> tuple[dict[str, pd.DataFrame], int]:
    """The quick scenario's tables with the drain on or off, and how many recv() calls it made."""
    calls = 0
    recv = Node.recv

    def counted(self, *args, **kwargs):
        nonlocal calls
        calls += 1
        return recv(self, *args, **kwargs)

    monkeypatch.setattr(periodic.PeriodicBeaconNode, "drain_inbox", drain)
    monkeypatch.setattr(Node, "recv", counted)
    raw = tomllib.loads(QUICK.read_text())
    raw.pop("variants", None)
    sc = scenario.load_dict(raw, QUICK, overrides=["simulation.duration_s=10.0", *sets])
    sim = scenario.build(sc)
    sim.run(sc.simulation.duration_s)
    monkeypatch.undo()
    return sim.trace.frames(), calls


@pytest.mark.parametrize(
    "sets",
    [
        [],  # STVF
        # SLMP and the bound after a short anchor training (both localize from 4 s on)
        [f"nodes.{g}.{k}" for g in (0, 1) for k in ("protocol=slmp", "params.training_s=4.0")],
        [f"nodes.{g}.{k}" for g in (0, 1) for k in ("protocol=multilateration_all_refs", "params.training_s=4.0")],
    ],
    ids=["stvf", "slmp", "bound"],
)
def test_drained_inbox_gives_the_per_reception_traces(monkeypatch: pytest.MonkeyPatch, sets: list[str]) -> None:
    loop, loop_calls = _tables(monkeypatch, False, sets)
    drained, drained_calls = _tables(monkeypatch, True, sets)
    est = loop["estimates"]
    assert len(est) > 150 and est["time"].duplicated().any()  # many nodes localize per instant
    assert loop_calls > 1000 and drained_calls == 0  # one recv() per reception before, none now
    assert set(drained) == set(loop)
    for name, table in loop.items():
        pd.testing.assert_frame_equal(drained[name], table, check_exact=True, obj=name)


def test_turns_follow_reception_count_then_wake_order() -> None:
    """The order a recv() per reception gives: fewest receptions first, ties in wake-up order."""

    class _Env:
        def __init__(self) -> None:
            self.late: list = []

        def at_instant_end(self, cb):
            self.late.append(cb)

        def event(self):
            return _Ev(order)

    class _Ev:
        def __init__(self, log: list) -> None:
            self.log = log

        def succeed(self) -> None:
            self.log.append(self)

    class _Node:
        env = _Env()

    order: list = []
    turns = periodic._Turns()
    counts = [3, 0, 2, 3, 0, 1]
    events = [turns.take(_Node(), c) for c in counts]
    assert len(_Node.env.late) == 1  # one release per instant
    _Node.env.late[0](None)
    assert [events.index(e) for e in order] == [1, 4, 5, 2, 0, 3]
    assert turns.waiting == []
