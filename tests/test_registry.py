"""The protocol registry: built-ins, broken modules, entry points, definition checks."""

from __future__ import annotations

import importlib.metadata
import sys
import textwrap

import pytest
from pydantic import BaseModel

from aquasim_py import registry
from aquasim_py.node import Node


@pytest.fixture
def fresh(monkeypatch):
    """An empty, not-yet-loaded registry (the real one is restored afterwards)."""
    monkeypatch.setattr(registry, "_registry", {})
    monkeypatch.setattr(registry, "_load_errors", {})
    monkeypatch.setattr(registry, "_loaded", False)
    return registry


def test_beacon_is_built_in():
    from aquasim_protocols.beacon import BeaconNode

    assert registry.get("beacon") is BeaconNode
    assert "beacon" in registry.available()
    assert issubclass(BeaconNode.Params, BaseModel)


def test_unknown_name_lists_available():
    with pytest.raises(registry.UnknownProtocolError) as ei:
        registry.get("no-such-protocol")
    assert "unknown protocol 'no-such-protocol'" in str(ei.value) and "beacon" in str(ei.value)
    assert isinstance(ei.value, KeyError)


def test_broken_builtin_module_does_not_break_the_others(fresh, tmp_path, monkeypatch):
    pkg = tmp_path / "fakeprotos"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "good.py").write_text(
        textwrap.dedent("""
        from pydantic import BaseModel
        from aquasim_py.node import Node
        from aquasim_py.registry import register

        @register
        class Good(Node):
            name = "good"
            class Params(BaseModel):
                k: int = 1
    """)
    )
    (pkg / "bad.py").write_text("raise ImportError('half written')\n")
    (pkg / "_private.py").write_text("raise RuntimeError('never imported')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(fresh, "BUILTIN_PACKAGE", "fakeprotos")
    monkeypatch.setattr(importlib.metadata, "entry_points", lambda **kw: [])
    for m in [m for m in sys.modules if m.startswith("fakeprotos")]:
        monkeypatch.delitem(sys.modules, m)
    assert fresh.get("good").__name__ == "Good"
    assert fresh.available() == ["good"]
    with pytest.raises(
        registry.UnknownProtocolError, match=r"'bad' is not available: fakeprotos.bad failed to import .*half written"
    ):
        fresh.get("bad")
    assert "_private" not in fresh.load_errors()


def test_entry_point_protocols(fresh, tmp_path, monkeypatch):
    (tmp_path / "plugin_mac.py").write_text(
        textwrap.dedent("""
        from pydantic import BaseModel
        from aquasim_py.node import Node

        class MacNode(Node):
            name = "mac"
            class Params(BaseModel):
                slots: int = 4
    """)
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    eps = [
        importlib.metadata.EntryPoint(name="plugin_mac", value="plugin_mac:MacNode", group=registry.ENTRY_POINT_GROUP),
        importlib.metadata.EntryPoint(name="broken", value="no_such_module:X", group=registry.ENTRY_POINT_GROUP),
    ]
    monkeypatch.setattr(
        importlib.metadata, "entry_points", lambda group=None, **kw: eps if group == registry.ENTRY_POINT_GROUP else []
    )
    assert fresh.get("plugin_mac").__name__ == "MacNode"
    assert "beacon" in fresh.available()  # built-ins still there
    with pytest.raises(registry.UnknownProtocolError, match="entry point 'no_such_module:X' failed to load"):
        fresh.get("broken")


def test_register_checks_the_class(fresh):
    class NoName(Node):
        name = ""

    with pytest.raises(registry.ProtocolDefinitionError, match="name"):
        registry.register(NoName)

    class NoParams:
        name = "np"
        Params = dict

    with pytest.raises(registry.ProtocolDefinitionError, match="Params"):
        registry.register(NoParams)


def test_register_refuses_a_second_class_under_one_name(fresh):
    class A(Node):
        name = "dup"

    class B(Node):
        name = "dup"

    assert registry.register(A) is A
    assert registry.register(A) is A  # idempotent
    with pytest.raises(registry.ProtocolDefinitionError, match="already taken"):
        registry.register(B)
