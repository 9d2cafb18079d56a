"""The kernel's compiled event queue (aquasim_py/events.py, _events.c) against SimPy's own
Environment: random SimPy programs (timeouts with tied, int and float delays, shared events
succeeded and failed, conditions, interrupts, urgent and normal priorities) must log the same
steps at the same times with the same time types, and end the same way; and the queue alone,
at sizes of thousands, pops in key order."""

from __future__ import annotations

import bisect
import math
from typing import Any

import numpy as np
import pytest
import simpy
from hypothesis import given, settings
from hypothesis import strategies as st

from aquasim_py import events

pytestmark = pytest.mark.skipif(events._events is None, reason="aquasim_py._events is not built")

DELAYS = [0, 0, 1, 2, 0.5, 1.0, 0.25, 3]

op = st.one_of(
    st.tuples(st.just("sleep"), st.sampled_from(DELAYS)),
    st.tuples(st.just("succeed"), st.integers(0, 3)),
    st.tuples(st.just("fail"), st.integers(0, 3), st.booleans()),
    st.tuples(st.just("wait"), st.integers(0, 3), st.sampled_from(DELAYS)),
    st.tuples(st.just("all"), st.integers(0, 3), st.sampled_from(DELAYS)),
    st.tuples(st.just("interrupt"), st.integers(0, 4)),
    st.tuples(st.just("spawn"), st.sampled_from(DELAYS)),
)
programs = st.lists(st.lists(op, max_size=8), min_size=1, max_size=5)


def play(env: simpy.Environment, program: list[list[tuple[Any, ...]]], until: Any) -> list[Any]:
    """Run ``program`` on ``env``; the log of every step a process saw, and how the run ended."""
    log: list[Any] = []
    shared = [env.event() for _ in range(4)]
    procs: list[simpy.Process] = []

    def note(*what: Any) -> None:
        log.append((env.now, type(env.now).__name__, *what))

    def proc(i: int, ops: list[tuple[Any, ...]]) -> Any:
        for step, o in enumerate(ops):
            try:
                if o[0] == "sleep":
                    v = yield env.timeout(o[1], value=(i, step))
                    note(i, "slept", v)
                elif o[0] == "succeed":
                    if not shared[o[1]].triggered:
                        shared[o[1]].succeed((i, step))
                        note(i, "succeeded", o[1])
                elif o[0] == "fail":
                    ev = shared[o[1]]
                    if not ev.triggered:
                        ev.fail(ValueError(f"from {i}"))
                        if o[2]:
                            ev.defused = True
                        note(i, "failed", o[1], o[2])
                elif o[0] == "wait":
                    r = yield shared[o[1]] | env.timeout(o[2])
                    note(i, "woke", sorted(str(v) for v in r.values()))
                elif o[0] == "all":
                    r = yield shared[o[1]] & env.timeout(o[2])
                    note(i, "all", sorted(str(v) for v in r.values()))
                elif o[0] == "interrupt":
                    if o[1] < len(procs) and procs[o[1]].is_alive and procs[o[1]] is not env.active_process:
                        procs[o[1]].interrupt((i, step))
                        note(i, "interrupted", o[1])
                elif o[0] == "spawn":

                    def child(d: Any = o[1], j: int = i) -> Any:
                        yield env.timeout(d)
                        note(j, "child")

                    env.process(child())
            except simpy.Interrupt as e:
                note(i, "was interrupted", e.cause)
            except ValueError as e:
                note(i, "caught", str(e))
        return i

    for i, ops in enumerate(program):
        procs.append(env.process(proc(i, ops)))
    try:
        out = env.run(until=until)
        log.append(("end", env.now, type(env.now).__name__, out))
    except Exception as e:  # how the run ended is what is compared
        cause = e.__cause__
        log.append(("raised", env.now, type(e).__name__, str(e), type(cause).__name__, str(cause)))
    log.append(("peek", env.peek()))
    return log


@settings(max_examples=200)
@given(program=programs, until=st.sampled_from([None, 2, 2.5, 4.0, "event"]))
def test_random_programs_run_as_on_simpy(program: list[list[tuple[Any, ...]]], until: Any) -> None:
    logs = []
    for env in (simpy.Environment(), events.Environment()):
        u = env.timeout(1.5, value="until") if until == "event" else until
        logs.append(play(env, program, u))
    assert logs[1] == logs[0]


def test_order_is_time_then_priority_then_sequence() -> None:
    env = events.Environment()
    seen: list[str] = []
    for name, prio, delay in [("b", 1, 1.0), ("a", 1, 1.0), ("u", 0, 1.0), ("early", 1, 0.5), ("c", 1, 1)]:
        ev = env.event()
        ev._ok, ev._value = True, None
        ev.callbacks.append(lambda _e, n=name: seen.append(n))
        env.schedule(ev, prio, delay)
    assert [e[:3] for e in env._queue.entries()] == [  # type: ignore[attr-defined]
        (0.5, 1, 3),
        (1.0, 0, 2),
        (1.0, 1, 0),
        (1.0, 1, 1),
        (1, 1, 4),
    ]
    env.run()
    assert seen == ["early", "u", "b", "a", "c"]


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 3000), pop_share=st.sampled_from([0.1, 0.4, 0.5]))
def test_the_queue_pops_in_key_order_at_any_size(seed: int, n: int, pop_share: float) -> None:
    """Pushes and pops interleaved, with ties of time and priority, in queues of up to a
    couple of thousand entries (several levels of the heap): every pop gives the least pending
    key (time, priority, sequence number), checked against a sorted list of the keys."""
    rng = np.random.default_rng(seed)
    times = rng.choice([0.0, 0.5, 1.0, 1.0, 2.0, 3.5], size=n).tolist()
    prios = rng.integers(-1, 3, size=n).tolist()
    pops = (rng.random(n) < pop_share).tolist()
    q = events._events.Queue()
    pending: list[tuple[float, int, int]] = []  # the reference: the pending keys, kept sorted
    popped, expected = [], []
    eid = 0  # the queue's sequence number of the next push
    for t, prio, pop in zip(times, prios, pops):
        if pop:
            if pending:
                expected.append(pending.pop(0))
                popped.append(q.pop())
        else:
            key = (t, prio, eid)
            q.push(t, prio, key)  # the event object is the key itself
            bisect.insort(pending, key)
            eid += 1
    popped.extend(q.pop() for _ in range(len(q)))
    expected.extend(pending)
    assert popped == expected


@pytest.mark.parametrize("requeue", [True, False])
def test_stop_simulation_as_the_installed_simpy_and_both_releases(
    requeue: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """run(until=event) stops inside the event's callbacks. SimPy >= 4.1.2 puts the callbacks
    not yet run back on the event (they run when the run goes on); 4.1.0 and 4.1.1 drop them.
    The compiled queue does what the installed SimPy does, and either on request."""

    def play(env: simpy.Environment) -> list[Any]:
        seen: list[Any] = []
        ev = env.timeout(1.0)
        ev.callbacks.append(lambda _e: seen.append(("first", env.now)))
        first = env.run(until=ev)
        ev.callbacks = ev.callbacks or []  # dropped (None) before 4.1.2
        ev.callbacks.append(lambda _e: seen.append(("late", env.now)))
        env.timeout(1.0).callbacks.append(lambda _e: seen.append(("next", env.now)))
        env.run()
        return [first, *seen]

    assert play(events.Environment()) == play(simpy.Environment())
    monkeypatch.setattr(events, "SIMPY_REQUEUES", requeue)
    late = [("late", 1.0)] if requeue else []
    assert play(events.Environment()) == [None, ("first", 1.0), *late, ("next", 2.0)]


def test_a_failed_event_nobody_defused_crashes_the_run_with_a_copy() -> None:
    env = events.Environment()
    original = KeyError("lost")
    env.event().fail(original)
    with pytest.raises(KeyError) as info:
        env.run()
    assert info.value is not original and info.value.__cause__ is original


def test_empty_schedule_and_peek() -> None:
    env = events.Environment()
    assert env.peek() == math.inf and len(env._queue) == 0  # type: ignore[arg-type]
    assert env.run() is None
    with pytest.raises(simpy.core.EmptySchedule):
        env.step()
    with pytest.raises(RuntimeError, match="No scheduled events left"):
        env.run(until=env.event())
    env.timeout(2)
    assert env.peek() == 2 and type(env.peek()) is int


def test_a_nan_time_is_refused() -> None:
    env = events.Environment()
    with pytest.raises(ValueError, match="NaN"):
        env.timeout(math.nan)
    assert len(env._queue) == 0  # type: ignore[arg-type]


def test_the_sequence_counter_is_shared() -> None:
    """next(env._eid) takes the number the next push would have taken (the channel draws it)."""
    env = events.Environment()
    env.timeout(1.0)
    assert next(env._eid) == 1
    env.timeout(1.0)
    assert [e[2] for e in env._queue.entries()] == [0, 2]  # type: ignore[attr-defined]


def test_environment_gives_simpy_when_switched_off(monkeypatch: pytest.MonkeyPatch) -> None:
    assert type(events.environment()) is events.Environment
    monkeypatch.setattr(events, "compiled", False)
    assert type(events.environment()) is simpy.Environment
