"""Protocols outside any package: a scenario names a class by where it is, nothing installed.

Two forms of ``protocol`` in a scenario (``[[nodes]] protocol = ...``):

- ``"./myproto.py:MyNode"``: the class ``MyNode`` of a Python file, the path relative to the
  scenario file's directory (or absolute; ``~`` expands). The file is executed as a module of
  its own (private name ``aquasim_plugin_<stem>_<hash>``), so it may import installed packages
  but not files beside it: for several files, use the module form.
- ``"mymodule:MyNode"`` or ``"mypackage.sub:MyNode"``: the class of a module importable by
  Python (installed, or on ``PYTHONPATH``).

A path is told from a module by a ``/`` (or ``\\``) or a ``.py`` ending.

Sweeps run plug-ins in other processes. A module plug-in must be importable there (local
worker processes inherit ``sys.path``; a Dask worker needs the module installed or on its
path). A file plug-in travels with the jobs instead: :func:`sources` reads the files in the
sweep's process and :func:`provide` hands their text to the worker's loader, keyed by the
same path as the worker computes it from the same scenario path string, so a Dask worker on
another machine runs the file without having it.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import os
import sys
import threading
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

__all__ = ["PluginError", "is_spec", "load", "provide", "sources"]

_lock = threading.RLock()
#: (path key, sha256 of the source) -> the module executed from it
_modules: dict[tuple[str, str], Any] = {}
#: path key -> source text handed over by the process that planned a sweep
_provided: dict[str, str] = {}


class PluginError(LookupError):
    """A plug-in spec that does not lead to a class (missing file or module, failed import,
    no such class); the message is one line for the user."""


def is_spec(name: str) -> bool:
    """``name`` names a class by file or module (``TARGET:CLASS``), not a registered name."""
    target, sep, cls = name.rpartition(":")
    return bool(sep and target and cls)


def _is_path(target: str) -> bool:
    return "/" in target or "\\" in target or target.endswith(".py")


def _split(spec: str) -> tuple[str, str]:
    target, _, cls = spec.rpartition(":")
    if not cls.isidentifier():
        raise PluginError(f"protocol {spec!r}: {cls!r} is not a class name (expected FILE.py:Class or module:Class)")
    return target, cls


def _key(target: str, base: str | os.PathLike[str] | None) -> str:
    """The file's path as a string, from the spec and the scenario's directory alone (no
    resolution against the current directory or the file system), so the same strings give
    the same key in every process."""
    p = Path(os.path.expanduser(target))
    if not p.is_absolute() and base is not None:
        p = Path(base) / p
    return os.path.normpath(p)


def load(spec: str, base: str | os.PathLike[str] | None = None) -> type:
    """The class a spec names; ``base``: the scenario file's directory (None: the current one).

    Raises :class:`PluginError` with a one-line message when the file or module cannot be
    found or imported, or has no such class."""
    target, cls_name = _split(spec)
    if _is_path(target):
        module = _load_file(spec, target, base)
        where = f"file {target}"
    else:
        module = _import_module(spec, target)
        where = f"module {target}"
    try:
        obj = getattr(module, cls_name)
    except AttributeError:
        classes = sorted(n for n, v in vars(module).items() if isinstance(v, type) and v.__module__ == module.__name__)
        hint = f" (classes there: {', '.join(classes)})" if classes else " (it defines no class)"
        raise PluginError(f"protocol {spec!r}: {where} has no {cls_name!r}{hint}") from None
    if not isinstance(obj, type):
        raise PluginError(f"protocol {spec!r}: {cls_name!r} in {where} is not a class")
    return obj


def _one_line(e: BaseException) -> str:
    text = " ".join(str(e).split())
    return f"{type(e).__name__}: {text}" if text else type(e).__name__


def _import_module(spec: str, name: str) -> Any:
    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as e:
        if e.name is not None and (name == e.name or name.startswith(e.name + ".")):
            raise PluginError(
                f"protocol {spec!r}: no module {name!r} on the Python path (install it or add its folder to "
                f"PYTHONPATH; a file beside the scenario is named as ./{name.replace('.', '/')}.py:CLASS)"
            ) from None
        raise PluginError(f"protocol {spec!r}: module {name} failed to import ({_one_line(e)})") from None
    except Exception as e:  # the plug-in's own error, as one line
        raise PluginError(f"protocol {spec!r}: module {name} failed to import ({_one_line(e)})") from None


def _read(spec: str, target: str, key: str) -> str:
    with _lock:
        if key in _provided:
            return _provided[key]
    try:
        return Path(key).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise PluginError(f"protocol {spec!r}: no file {key} (a path is relative to the scenario file)") from None
    except (OSError, UnicodeDecodeError) as e:
        raise PluginError(f"protocol {spec!r}: cannot read {key} ({_one_line(e)})") from None


def _load_file(spec: str, target: str, base: str | os.PathLike[str] | None) -> Any:
    key = _key(target, base)
    text = _read(spec, target, key)
    digest = hashlib.sha256(text.encode()).hexdigest()
    with _lock:
        module = _modules.get((key, digest))
        if module is not None:
            return module
        stem = "".join(ch if ch.isalnum() else "_" for ch in Path(key).stem)
        name = f"aquasim_plugin_{stem}_{hashlib.sha256(key.encode()).hexdigest()[:10]}"
        mod_spec = importlib.util.spec_from_loader(name, loader=None, origin=key)
        assert mod_spec is not None
        module = importlib.util.module_from_spec(mod_spec)
        module.__file__ = key
        # in sys.modules while it runs: dataclasses, pydantic and pickling look the module up by name
        old = sys.modules.get(name)
        sys.modules[name] = module
        try:
            exec(compile(text, key, "exec"), module.__dict__)
        except BaseException as e:
            if old is None:
                sys.modules.pop(name, None)
            else:
                sys.modules[name] = old
            if not isinstance(e, Exception):
                raise
            raise PluginError(f"protocol {spec!r}: {key} failed to import ({_one_line(e)})") from None
        _modules[(key, digest)] = module
        return module


def sources(specs: Iterable[str], base: str | os.PathLike[str] | None) -> dict[str, str]:
    """Path key -> source text of every file plug-in among ``specs`` (names and module
    plug-ins are skipped), for :func:`provide` in a worker process."""
    out: dict[str, str] = {}
    for spec in specs:
        if not is_spec(spec):
            continue
        target, _ = _split(spec)
        if _is_path(target):
            key = _key(target, base)
            out[key] = _read(spec, target, key)
    return out


def provide(texts: Mapping[str, str]) -> None:
    """Load file plug-ins from these texts (path key -> source) rather than from disk: what a
    sweep's worker gets from the process that planned the sweep (:func:`sources`)."""
    with _lock:
        _provided.update(texts)
