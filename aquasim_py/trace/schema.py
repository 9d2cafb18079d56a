"""The trace tables' schemas: their columns and types, what the trace records, valid names."""

from __future__ import annotations

import re
from dataclasses import dataclass

__all__ = ["CHUNK_ROWS", "SCHEMAS", "SORT_BY", "TABLE_NAME", "TraceConfig", "check_table_name"]

#: Column kinds: "f" float64, "i" int64, "c" string category (None = missing), "o" any object.
SCHEMAS: dict[str, tuple[tuple[str, str], ...]] = {
    "packets": (
        ("time", "f"),
        ("event", "c"),
        ("reason", "c"),
        ("node", "i"),
        ("src", "i"),
        ("dst", "i"),
        ("uid", "i"),
        ("kind", "c"),
        ("bits", "i"),
        ("tof", "f"),
        ("snr_db", "f"),
        ("path", "c"),
        ("local_time", "f"),
    ),
    "positions": (
        ("time", "f"),
        ("node", "i"),
        ("x", "f"),
        ("y", "f"),
        ("z", "f"),
        ("vx", "f"),
        ("vy", "f"),
        ("vz", "f"),
    ),
    "estimates": (
        ("time", "f"),
        ("node", "i"),
        ("protocol", "c"),
        ("x", "f"),
        ("y", "f"),
        ("z", "f"),
        ("true_x", "f"),
        ("true_y", "f"),
        ("true_z", "f"),
        ("error", "f"),
        ("confidence", "f"),
        ("is_reference", "o"),
        # after the DESIGN.md columns: horizontal / vertical error (the bound of the geometry
        # a node declared is computed after the run: aquasim_py.estimate_bounds, bounds table)
        ("error_h", "f"),
        ("error_v", "f"),
    ),
    "clocks": (
        ("time", "f"),
        ("node", "i"),
        ("protocol", "c"),
        ("skew", "f"),
        ("offset", "f"),
        ("true_skew", "f"),
        ("true_offset", "f"),
        ("error", "f"),
    ),
}

# Sort key of the packets table in frames(): rows are appended when the kernel decides them
# (a reception when its last bit arrives), so the table is re-ordered by event time.
SORT_BY = {"packets": "time", "positions": None, "estimates": None, "clocks": None}


@dataclass(frozen=True)
class TraceConfig:
    """What the trace records.

    position_interval: seconds of true time between ground-truth position samples (None or
    0 disables the ``positions`` table).
    """

    position_interval: float | None = 1.0


#: rows a streamed table holds before handing them to its file (~0.5 MB of columns for
#: ``packets``; formatting a chunk as CSV briefly takes several times that, and the heap keeps
#: that high-water mark: 16384 rows cost STVF's Table-1 run, at 100 s, 17 MiB more peak
#: memory for no measurable CPU)
CHUNK_ROWS = 4096


#: what a table name may be: it becomes a file name inside the output directory
TABLE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")


def check_table_name(name: object) -> None:
    """Raise ValueError unless ``name`` is a valid trace table name (:data:`TABLE_NAME`: letters,
    digits, ``_``, ``.``, ``-``, not starting with ``.`` or ``-``), so that no table can be
    written outside the output directory or as a hidden file."""
    if not isinstance(name, str) or not TABLE_NAME.fullmatch(name):
        raise ValueError(
            f"invalid trace table name {name!r}: use letters, digits, '_', '.' and '-' (not first), no path separators"
        )
