"""Output directories: staged writes that delete or replace only what aquasim-py wrote itself.

Every output directory the tool writes carries a manifest, :data:`MANIFEST`
(``.aquasim-output.json``), listing the files it wrote there (relative paths). The rules:

* a directory that does not exist is staged whole in a hidden ``.NAME.tmp-*`` directory beside
  it and renamed into place when complete (all or nothing);
* an existing directory is written into file by file, after everything is staged inside it:
  the files of the old manifest that the new run does not write are removed, the new files
  replace their namesakes, anything else (the user's files) is left alone;
* an existing directory is only written into when it is empty, carries a manifest, or holds
  nothing but such directories (``--variant`` runs under an all-variants directory); any other
  non-empty directory is refused (:class:`OutputRefused`) unless ``overwrite`` is given, and
  even then only the files this run writes are replaced;
* every staging directory holds a marker, :data:`STAGING_MARKER`, with the owning process id;
  staging directories whose owner is dead (a SIGKILL, a power cut) are removed by the next run
  that stages in the same place. Nothing without a marker is ever removed. The scratch
  directories of trace tables only metrics read (:func:`scratch_dir`, in ``TMPDIR``) follow
  the same rule.
"""

from __future__ import annotations

import json
import os
import secrets
import shutil
import signal
import socket
import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path, PurePosixPath
from typing import Any

from aquasim_py.errors import ScenarioError

__all__ = [
    "MANIFEST",
    "STAGING_MARKER",
    "OutputRefused",
    "clean_stale",
    "is_own_output",
    "listed_files",
    "record_files",
    "scratch_dir",
    "staged_output",
]

#: the manifest of an output directory: the files aquasim-py wrote there
MANIFEST = ".aquasim-output.json"
#: the marker inside a staging directory: who is writing it
STAGING_MARKER = ".aquasim-staging.json"


class OutputRefused(ScenarioError):
    """A non-empty directory that is not an aquasim-py output, without ``overwrite``."""

    def __str__(self) -> str:
        if self.key_path.startswith("--"):  # a command-line option: "--out DIR: problem"
            return f"{self.key_path} {self.message}"
        return super().__str__()


# --------------------------------------------------------------------------- manifests
def _read_manifest(d: Path) -> list[str] | None:
    """The files the manifest of ``d`` lists (safe relative paths only), None without one."""
    try:
        data = json.loads((d / MANIFEST).read_text())
    except (OSError, ValueError):
        return None
    files = data.get("files") if isinstance(data, dict) else None
    if not isinstance(files, list):
        return None
    return [f for f in files if isinstance(f, str) and _safe_relative(f)]


def _safe_relative(name: str) -> bool:
    """A relative path that stays inside its directory (a tampered manifest deletes nothing
    outside)."""
    p = PurePosixPath(name)
    return (
        bool(name) and not p.is_absolute() and "\\" not in name and all(part not in ("", ".", "..") for part in p.parts)
    )


def listed_files(d: Path) -> list[str]:
    """The files the manifest of ``d`` lists (relative paths); empty without one."""
    return _read_manifest(Path(d)) or []


def is_own_output(d: Path) -> bool:
    """``d`` is empty, carries a manifest, or holds only such directories and our own staging
    leftovers."""
    if (d / MANIFEST).is_file():
        return True
    try:
        entries = list(d.iterdir())
    except OSError:
        return False
    for e in entries:
        if e.is_symlink() or not e.is_dir():
            return False
        if not ((e / STAGING_MARKER).is_file() or is_own_output(e)):
            return False
    return True


def _write_manifest(d: Path, files: list[str]) -> None:
    from aquasim_py._version import __version__

    body = {"tool": "aquasim-py", "version": __version__, "files": sorted(files)}
    (d / MANIFEST).write_text(json.dumps(body, indent=2) + "\n")


def record_files(d: Path, names: list[str]) -> None:
    """Add files written into the output directory ``d`` after its run (a report's plots) to
    its manifest, and to the manifests above it that list ``d``'s files (a variant directory
    inside an all-variants run), so a later run replaces them like the rest."""
    d = Path(d)
    own = _read_manifest(d) if (d / MANIFEST).is_file() else []
    _write_manifest(d, sorted({*(own or []), *names}))
    child, prefix = d, ""
    while True:
        parent = child.parent
        prefix = f"{child.name}/{prefix}"
        listed = _read_manifest(parent) if parent != child else None
        if not listed or not any(f.startswith(prefix) for f in listed):
            return
        _write_manifest(parent, sorted({*listed, *(prefix + n for n in names)}))
        child = parent


def _files_under(d: Path) -> list[str]:
    return sorted(
        p.relative_to(d).as_posix()
        for p in d.rglob("*")
        if p.is_file() and p.name != STAGING_MARKER and p != d / MANIFEST
    )


def _write_manifests(tmp: Path) -> list[str]:
    """A manifest in every directory of the staged tree, deepest first (so that a variant's
    ``DIR/NAME/`` is an output directory of its own, as a ``--variant`` run writes it); returns
    the files of the top one."""
    dirs = sorted((p for p in tmp.rglob("*") if p.is_dir()), key=lambda p: len(p.parts), reverse=True)
    for d in dirs:
        _write_manifest(d, _files_under(d))
    files = _files_under(tmp)
    _write_manifest(tmp, files)
    return files


# --------------------------------------------------------------------------- stale staging
def _proc_start(pid: int) -> str | None:
    """The start time of ``pid`` in clock ticks since boot (Linux), so that a reused pid is
    not taken for the owner; None where /proc is not available."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return stat.rsplit(")", 1)[1].split()[19]  # field 22 counted from the pid


def _alive(pid: int, start: str | None) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process: alive
        return True
    now = _proc_start(pid)
    return start is None or now is None or now == start


def _marker() -> dict[str, Any]:
    return {"pid": os.getpid(), "start": _proc_start(os.getpid()), "host": socket.gethostname()}


def clean_stale(where: Path) -> list[Path]:
    """Remove the staging directories in ``where`` (``.*.tmp-*`` with a marker) whose owning
    process, on this host, is dead. Returns what was removed."""
    removed: list[Path] = []
    try:
        candidates = [p for p in where.iterdir() if p.name.startswith(".") and ".tmp-" in p.name]
    except OSError:
        return removed
    host = socket.gethostname()
    for p in candidates:
        if p.is_symlink() or not p.is_dir():
            continue
        try:
            m = json.loads((p / STAGING_MARKER).read_text())
            pid, start = int(m["pid"]), m.get("start")
        except (OSError, ValueError, KeyError, TypeError):
            continue  # not ours (or not readable): never touched
        if m.get("host") != host or _alive(pid, start):
            continue
        shutil.rmtree(p, ignore_errors=True)
        removed.append(p)
    return removed


SCRATCH_PREFIX = ".aquasim-trace.tmp-"


def scratch_dir(made: list[Path] | None = None) -> Path:
    """A new private directory for a run's trace tables that nobody asked to keep (the ones
    only metrics read), in the system's temporary directory (``TMPDIR``). It carries a staging
    marker, so that one left by a killed run is removed by the next run (:func:`clean_stale`).
    A kill between making it and marking it (or while removing it, after the marker) leaves
    it empty and unmarked: such a one, older than a minute, is removed too (``rmdir`` only
    removes an empty directory, and a live run marks its own within microseconds).

    ``made``: its path is appended there before it is made (a name of this process's own), so
    that a caller removing what ``made`` holds on an exception (SIGINT / SIGTERM raised at any
    point in here) leaves nothing behind."""
    where = Path(tempfile.gettempdir())
    clean_stale(where)
    now = time.time()
    for p in where.glob(SCRATCH_PREFIX + "*"):
        with suppress(OSError):
            if now - p.lstat().st_mtime > 60.0 and not p.is_symlink():
                p.rmdir()
    d = _private_dir(where, SCRATCH_PREFIX, [] if made is None else made)
    (d / STAGING_MARKER).write_text(json.dumps(_marker()))
    return d


def _private_dir(where: Path, prefix: str, made: list[Path]) -> Path:
    """A new directory ``where/prefix<pid>-<random>``, private (0700, as ``mkdtemp``'s), its
    path appended to ``made`` before it is made: a caller removing what ``made`` holds when an
    exception (SIGINT / SIGTERM raised by the CLI's handlers) arrives at any point leaves
    nothing behind, where ``mkdtemp`` names it only once made."""
    while True:
        d = where / f"{prefix}{os.getpid()}-{secrets.token_hex(4)}"
        made.append(d)
        try:
            d.mkdir(mode=0o700)
            return d
        except FileExistsError:  # (a dead process of the same pid left it: the next name)
            made.remove(d)


# --------------------------------------------------------------------------- staging
def refuse_foreign(target: Path, file: Any, key: str, *, overwrite: bool = False, hint: str | None = None) -> bool:
    """The one check before writing into ``target``: refuse a file in its place, and a
    non-empty directory that is not an aquasim-py output unless ``overwrite`` (one-line
    :class:`OutputRefused` naming ``key``). Returns whether ``target`` is (or will be) the
    tool's own: absent, empty, or carrying a manifest."""
    target = Path(target)
    if target.exists() and not target.is_dir():
        raise ScenarioError(file, key, f"{target} exists and is not a directory")
    own = not target.exists() or is_own_output(target)
    if not own and not overwrite:
        why = hint if hint is not None else _refusal_hint(key)
        raise OutputRefused(file, key, f"{target}: not empty and not an aquasim-py output directory ({why})")
    return own


#: The interruptions (SIGINT / SIGTERM) raised during the current command, which the CLI's
#: signal handler notes before raising each one and clears when the command ends. Their
#: exception can be lost on its way out: raised while a finalizer runs, Python only prints it,
#: and the run goes on. staged_output raises it again instead of moving the outputs of an
#: interrupted run into place.
INTERRUPTIONS: list[BaseException] = []


@contextmanager
def _signals_held() -> Iterator[None]:
    """Hold SIGINT / SIGTERM while the staged files are moved into place (a few renames), so
    an interruption cannot leave half of the old and half of the new outputs."""
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "pthread_sigmask"):
        yield
        return
    sigs = {signal.SIGINT, signal.SIGTERM}
    old = signal.pthread_sigmask(signal.SIG_BLOCK, sigs)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _refusal_hint(key: str) -> str:
    if key.startswith("--"):
        return "use --overwrite to write into it"
    if key == "out":
        return "use overwrite=True to write into it"
    return "use --overwrite to write into it"


@contextmanager
def staged_output(target: str | Path, file: Path | None, key: str, *, overwrite: bool = False) -> Iterator[Path]:
    """Yield a fresh staging directory for the outputs of ``target``; move them into place on
    success (see the module's rules).

    Fails with :class:`ScenarioError` (naming ``key``; :class:`OutputRefused` for a foreign
    non-empty directory) before yielding if the location cannot or may not be written. On any
    exception (including an interruption) the staging directory and any parent directory
    created here are removed and ``target`` is left as it was.
    """
    target = Path(target)
    refuse_foreign(target, file, key, overwrite=overwrite)
    into = target.is_dir()  # an existing directory: stage inside it, then move file by file
    where = target if into else target.parent
    label = target.resolve().name or "out"
    created: list[Path] = []

    def _unmake() -> None:
        for d in reversed(created):
            with suppress(OSError):
                d.rmdir()

    staged: list[Path] = []  # the staging directory, recorded before it is made
    try:
        missing = []
        d = where
        while not d.exists():
            missing.append(d)
            if d.parent == d:
                break
            d = d.parent
        for d in reversed(missing):
            d.mkdir()
            created.append(d)
        clean_stale(where)
        tmp = _private_dir(where, f".{label}.tmp-", staged)
        (tmp / STAGING_MARKER).write_text(json.dumps(_marker()) + "\n")
        # made private (0700); the final directory gets the usual permissions
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o777 & ~umask)
    except BaseException as e:  # an OSError, or SIGINT / SIGTERM before the yield: leave nothing
        for t in staged:
            shutil.rmtree(t, ignore_errors=True)
        _unmake()
        if isinstance(e, OSError):
            raise ScenarioError(file, key, f"cannot write to {target}: {e.strerror or e}") from None
        raise
    ok = False
    try:
        yield tmp
        if INTERRUPTIONS:  # interrupted, but the exception was swallowed (see INTERRUPTIONS)
            raise INTERRUPTIONS[-1]
        ok = True
    finally:
        if not ok:
            shutil.rmtree(tmp, ignore_errors=True)
            _unmake()
    try:
        with _signals_held():
            if into:
                _merge(tmp, target)
            else:
                _write_manifests(tmp)
                (tmp / STAGING_MARKER).unlink()
                os.rename(tmp, target)
    except OSError as e:  # e.g. a directory of the user's where an output file goes
        raise ScenarioError(file, key, f"cannot write to {target}: {e.strerror or e}") from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _merge(tmp: Path, target: Path) -> None:
    """Move the staged files of ``tmp`` into the existing ``target``: remove the old manifest's
    files that are not written again, replace the others, keep everything else."""
    new = _write_manifests(tmp)
    old = _read_manifest(target) or []
    top = target.resolve()
    for name in sorted(set(old) - set(new)):
        p = target / name
        if p.is_file() and not p.is_symlink() and top in p.resolve().parents:
            p.unlink()
            _prune_empty(p.parent, target)
    for name in new:
        dst = target / name
        dst.parent.mkdir(parents=True, exist_ok=True)
        os.replace(tmp / name, dst)
    os.replace(tmp / MANIFEST, target / MANIFEST)


def _prune_empty(d: Path, top: Path) -> None:
    """Remove ``d`` and its parents up to (not including) ``top`` while they are empty."""
    while d != top and top in d.parents:
        try:
            d.rmdir()
        except OSError:
            return
        d = d.parent
