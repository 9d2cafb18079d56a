"""A node that transmits on a plan, shared by the channel's tests (not a test module)."""

from __future__ import annotations

from typing import ClassVar

from aquasim_py.node import Node

#: id -> [(local time s, dst or None for a broadcast, bits)]
Plan = dict[int, list[tuple[float, int | None, int]]]


class Script(Node):
    """Transmits at given local times: params-free, the plan is set on a subclass (:func:`planned`).
    Each packet's payload names its sender; each send's MAC stamp goes to the ``sent`` table."""

    name = "script"
    plan: ClassVar[Plan] = {}

    def run(self):
        for t_local, dst, bits in self.plan.get(self.id, []):
            wait = t_local - self.local_time()
            if wait > 0:
                yield self.sleep(wait)
            if dst is None:
                stamp = yield self.broadcast("data", {"from": self.id}, bits)
            else:
                stamp = yield self.send(dst, "data", {"from": self.id}, bits)
            self.log("sent", stamp=stamp)


def planned(plan: Plan) -> type[Node]:
    """A :class:`Script` that follows ``plan``."""
    return type("Planned", (Script,), {"plan": plan, "name": "planned"})
