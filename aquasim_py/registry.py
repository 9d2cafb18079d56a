"""Protocol registry: a protocol name -> its :class:`~aquasim_py.node.Node` subclass.

Three sources; the first two are loaded lazily on the first lookup:

- built-ins: every family package of :mod:`aquasim_protocols` (the repository's top-level
  ``protocols/`` folder, installed under that name) is imported; its modules register their
  Node subclasses with the :func:`register` decorator. A family that fails to import does not break the registry (the
  others still load); its error is reported when its name is asked for.
- third-party packages: the entry-point group ``aquasim_py.protocols``, each entry point
  naming a Node subclass, e.g. in a plug-in's ``pyproject.toml``::

      [project.entry-points."aquasim_py.protocols"]
      my_mac = "my_package.my_module:MyMacNode"

- plug-ins, nothing installed: a scenario names the class where it is,
  ``protocol = "./myproto.py:MyNode"`` (a file, relative to the scenario file: ``base``) or
  ``protocol = "mymodule:MyNode"`` (an importable module); see :mod:`aquasim_py.plugins`. A
  loaded plug-in is also found by its class's ``name`` (what the trace tables record), unless
  that name belongs to a registered protocol, which is an error.

A protocol class declares ``name`` (str), ``Params`` (a pydantic model of its parameters, with
types, defaults and units in the field descriptions), and optionally the classmethods
``metrics(tables) -> dict[str, float]`` and ``report(tables) -> str | rich renderable``.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import pkgutil
import sys
import threading
from pathlib import Path
from typing import Any, TypeVar

from pydantic import BaseModel

from aquasim_py import plugins

__all__ = ["ProtocolDefinitionError", "UnknownProtocolError", "available", "get", "register"]

ENTRY_POINT_GROUP = "aquasim_py.protocols"
BUILTIN_PACKAGE = "aquasim_protocols"

_registry: dict[str, type] = {}
_plugins: dict[str, type] = {}  # class name -> plug-in class loaded by spec (file or module)
_load_errors: dict[str, str] = {}  # module or entry-point name -> why it did not load
_loaded = False
_lock = threading.RLock()

_C = TypeVar("_C", bound=type)


class UnknownProtocolError(KeyError):
    """No protocol of that name is registered."""

    def __init__(self, name: str, message: str) -> None:
        super().__init__(name)
        self.name = name
        self.message = message

    def __str__(self) -> str:
        return self.message


class ProtocolDefinitionError(TypeError):
    """A class handed to :func:`register` lacks what the registry needs."""


def _check(cls: type) -> str:
    name = getattr(cls, "name", None)
    if not isinstance(name, str) or not name:
        raise ProtocolDefinitionError(f"{cls.__qualname__}: a protocol needs a non-empty str `name`")
    params = getattr(cls, "Params", None)
    if not (isinstance(params, type) and issubclass(params, BaseModel)):
        raise ProtocolDefinitionError(f"{cls.__qualname__}: a protocol needs `Params`, a pydantic BaseModel subclass")
    return name


def register(cls: _C) -> _C:
    """Class decorator: register a Node subclass under its ``name``.

    Registering the same class twice is harmless (module reloads); two different classes
    under one name is an error, since a scenario could not tell them apart.
    """
    name = _check(cls)
    with _lock:
        old = _registry.get(name)
        if (
            old is not None
            and old is not cls
            and (old.__module__ != cls.__module__ or old.__qualname__ != cls.__qualname__)
        ):
            raise ProtocolDefinitionError(
                f"protocol name {name!r} is already taken by {old.__module__}.{old.__qualname__}"
            )
        _registry[name] = cls
    # lets a reloaded registry find it again without re-import; a marker set on an arbitrary
    # class, which declares no such attribute (hence setattr)
    setattr(cls, "_aquasim_registered", True)  # noqa: B010
    return cls


def _load_builtins() -> None:
    try:
        pkg = importlib.import_module(BUILTIN_PACKAGE)
    except ImportError as exc:  # aquasim_py imported from a source folder that is not installed
        _load_errors[BUILTIN_PACKAGE] = (
            f"the built-in protocols ({BUILTIN_PACKAGE}, the repository's protocols/ folder) did not import "
            f"({type(exc).__name__}: {exc}); install the package (pip install . or pip install -e .)"
        )
        return
    for info in sorted(pkgutil.iter_modules(pkg.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        modname = f"{BUILTIN_PACKAGE}.{info.name}"
        try:
            importlib.import_module(modname)
        except Exception as exc:  # a half-written protocol must not hide the others
            _load_errors[info.name] = f"{modname} failed to import ({type(exc).__name__}: {exc})"
            continue
        # a family imported before the registry loaded (or before a registry reset) registered
        # itself then; collect its classes again from every module of the family
        family = [m for n, m in list(sys.modules.items()) if n == modname or n.startswith(modname + ".")]
        for m in family:
            for obj in list(vars(m).values()):
                if isinstance(obj, type) and obj.__dict__.get("_aquasim_registered") and obj.__module__ == m.__name__:
                    _registry.setdefault(_check(obj), obj)  # validated when it registered


def _load_entry_points() -> None:
    for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        try:
            cls = ep.load()
            _check(cls)
            # the entry point's own name is what a scenario uses; the class may say otherwise
            with _lock:
                if ep.name not in _registry:
                    _registry[ep.name] = cls
        except Exception as exc:
            _load_errors[ep.name] = f"entry point {ep.value!r} failed to load ({type(exc).__name__}: {exc})"


def _ensure_loaded() -> None:
    global _loaded  # noqa: PLW0603  (one flag for the lazy, thread-safe load)
    with _lock:
        if _loaded:
            return
        _loaded = True
        _load_builtins()
        _load_entry_points()


def available() -> list[str]:
    """Sorted names of every protocol that loaded."""
    _ensure_loaded()
    return sorted(_registry)


#: what an unknown protocol's error says about adding one
HOW_TO_ADD = (
    'to use your own, name its class: protocol = "./myproto.py:MyNode" (a file, relative to the scenario) '
    'or "mymodule:MyNode" (an importable module); see docs/plugins.md'
)


def get(name: str, *, base: str | Path | None = None) -> type:
    """The Node subclass ``name`` stands for: a registered name, or a plug-in spec
    (``"./file.py:Class"``, ``"module:Class"``; a relative file from ``base``, the scenario
    file's directory, default the current directory). :class:`UnknownProtocolError` if none."""
    if plugins.is_spec(name):
        return _plugin(name, base)
    _ensure_loaded()
    cls = _registry.get(name) or _plugins.get(name)
    if cls is not None:
        return cls
    if name in _load_errors:
        raise UnknownProtocolError(name, f"protocol {name!r} is not available: {_load_errors[name]}")
    names = ", ".join(available()) or "none"
    why = f"; {_load_errors[BUILTIN_PACKAGE]}" if BUILTIN_PACKAGE in _load_errors else ""
    raise UnknownProtocolError(name, f"unknown protocol {name!r} (available: {names}){why}; {HOW_TO_ADD}")


def _plugin(spec: str, base: str | Path | None) -> type:
    from aquasim_py.node import Node

    try:
        cls = plugins.load(spec, base)
    except plugins.PluginError as e:
        raise UnknownProtocolError(spec, str(e)) from None
    if not issubclass(cls, Node):
        raise UnknownProtocolError(
            spec, f"protocol {spec!r}: {cls.__qualname__} is not a subclass of aquasim_py.node.Node"
        )
    try:
        name = _check(cls)
    except ProtocolDefinitionError as e:
        raise UnknownProtocolError(spec, f"protocol {spec!r}: {e}") from None
    if name == Node.name:
        raise UnknownProtocolError(
            spec,
            f"protocol {spec!r}: {cls.__qualname__} needs a `name` of its own (its metrics and trace rows carry it)",
        )
    _ensure_loaded()
    with _lock:
        taken = _registry.get(name)
        if taken is not None and taken is not cls:
            raise UnknownProtocolError(
                spec,
                f"protocol {spec!r}: its name {name!r} is the registered {taken.__module__}.{taken.__qualname__}'s; "
                "give the class another `name`",
            )
        _plugins[name] = cls
    return cls


def load_errors() -> dict[str, Any]:
    """Modules and entry points that failed to load, with the reason (for diagnostics)."""
    _ensure_loaded()
    return dict(_load_errors)
