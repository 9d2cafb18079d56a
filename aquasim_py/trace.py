"""Event tables of a run: cheap appends during the run, pandas / CSV / Parquet after.

Each table is a set of typed columns (``array.array`` for numbers, integer codes for
categorical strings, a list for anything else): appending a row costs a few list appends and
a packet trace of millions of rows stays compact. ``frames()`` turns the tables into pandas
DataFrames with the DESIGN.md columns first; ``write`` and :func:`load` round-trip them.

Floats are written with Python's shortest round-trip representation (``repr``), which is
exact and platform independent, so the same run gives byte-identical CSV files.
"""

from __future__ import annotations

import json
import math
import os
import re
from array import array
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

__all__ = ["SCHEMAS", "Table", "Trace", "TraceConfig", "load"]

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
_SORT_BY = {"packets": "time", "positions": None, "estimates": None, "clocks": None}


@dataclass(frozen=True)
class TraceConfig:
    """What the trace records.

    position_interval: seconds of true time between ground-truth position samples (None or
    0 disables the ``positions`` table).
    """

    position_interval: float | None = 1.0


class _Column:
    """One typed column: "f" float64 and "i" int64 in ``array.array``, "c" strings as int32
    codes into a category list, "o" anything in a list. Degrades ("i" -> "f", anything -> "o")
    when a value does not fit.

    Numbers and codes live outside Python containers, so a trace of millions of rows costs the
    garbage collector nothing to traverse (a list of strings would be rescanned on every full
    collection of a long run).
    """

    __slots__ = ("append", "cats", "data", "kind")

    def __init__(self, kind: str, n_missing: int = 0) -> None:
        self.kind = kind
        self.cats: dict[Any, int] = {}
        if kind == "f":
            self.data: Any = array("d", [math.nan]) * n_missing
        elif kind == "i" and not n_missing:
            self.data = array("q")
        elif kind == "i":  # an int column with earlier missing rows starts as float (NaN)
            self.kind = "f"
            self.data = array("d", [math.nan]) * n_missing
        elif kind == "c":
            self.data = array("i", [self._code(None)]) * n_missing
        else:
            self.kind = "o"
            self.data = [None] * n_missing
        self.append = self._append_cat if self.kind == "c" else self.data.append

    def _code(self, v: Any) -> int:
        c = self.cats.get(v)
        if c is None:
            if not (v is None or isinstance(v, str)):
                raise TypeError("categorical columns hold strings")
            c = self.cats[v] = len(self.cats)
        return c

    def _append_cat(self, v: Any) -> None:
        self.data.append(self._code(v))

    def values(self) -> list[Any]:
        if self.kind == "c":
            inv = list(self.cats)
            return [inv[c] for c in self.data]
        return list(self.data)

    def _to_kind(self, kind: str) -> None:
        old = self.values()
        self.kind = kind
        self.cats = {}
        if kind == "f":
            self.data = array("d", [math.nan if v is None else float(v) for v in old])
        else:
            self.data = old
        self.append = self.data.append

    def push(self, v: Any) -> None:
        """Append one value, widening the column type if it does not fit."""
        try:
            self.append(v)
            return
        except (TypeError, OverflowError):
            pass
        if self.kind == "i" and (v is None or isinstance(v, (float, np.floating))):
            self._to_kind("f")
            self.append(math.nan if v is None else v)
        else:
            self._to_kind("o")
            self.append(v)

    def push_many(self, values: tuple[Any, ...]) -> None:
        """Append a batch of values (C-level extend when they all fit)."""
        data = self.data
        if isinstance(data, list):
            data.extend(values)
            return
        try:
            if self.kind == "c":
                cats = self.cats
                codes = [cats[v] if v in cats else self._code(v) for v in values]
                data.extend(array("i", codes))
            else:
                # array(typecode, tuple) takes a fast path that array.extend(tuple) does not,
                # and it fails as a whole (no partial append) when a value does not fit
                data.extend(array(data.typecode, values))
        except (TypeError, OverflowError):
            for v in values:
                self.push(v)

    def fill_missing(self, count: int = 1) -> None:
        if self.kind == "f":
            self.data.extend([math.nan] * count)
        elif self.kind == "i":
            self._to_kind("f")
            self.data.extend([math.nan] * count)
        elif self.kind == "c":
            self.data.extend(array("i", [self._code(None)]) * count)
        else:
            self.data.extend([None] * count)

    def extend(self, values: np.ndarray) -> None:
        if self.kind == "f":
            self.data.frombytes(np.ascontiguousarray(values, dtype=np.float64).tobytes())
        elif self.kind == "i" and values.dtype.kind in "iub":
            self.data.frombytes(np.ascontiguousarray(values, dtype=np.int64).tobytes())
        else:
            self.push_many(tuple(values.tolist()))

    def series(self, name: str) -> pd.Series:
        if self.kind == "f":
            return pd.Series(np.frombuffer(self.data, dtype=np.float64).copy(), name=name)
        if self.kind == "i":
            return pd.Series(np.frombuffer(self.data, dtype=np.int64).copy(), name=name)
        if self.kind == "c":
            inv = np.empty(len(self.cats), dtype=object)
            inv[:] = list(self.cats)
            codes = np.frombuffer(self.data, dtype=np.int32) if len(self.data) else np.zeros(0, np.int32)
            return pd.Series(inv[codes] if len(inv) else np.empty(0, dtype=object), name=name, dtype=object)
        return pd.Series(self.data, name=name, dtype=object)


def _kind_of(v: Any) -> str:
    if isinstance(v, (bool, np.bool_)):
        return "o"
    if isinstance(v, (int, np.integer)):
        return "i"
    if isinstance(v, (float, np.floating)):
        return "f"
    if isinstance(v, str):
        return "c"
    return "o"


class Table:
    """A column store for one event table.

    The kernel's hot path (:meth:`append_fast`) buffers row tuples and moves them into the
    columns in batches (one C-level ``extend`` per column), so a row costs one list append.
    """

    _BATCH = 4096

    def __init__(self, name: str, schema: Iterable[tuple[str, str]] = ()) -> None:
        self.name = name
        self._n = 0
        self.columns: dict[str, _Column] = {c: _Column(k) for c, k in schema}
        self._schema = tuple(self.columns)
        self._buf: list[tuple[Any, ...]] = []

    @property
    def n(self) -> int:
        """Number of rows."""
        return self._n + len(self._buf)

    def _flush(self) -> None:
        if not self._buf:
            return
        buf = self._buf[:]
        self._buf.clear()  # the same list object: hot-path writers may hold it (see row_buffer)
        for key, values in zip(self._schema, zip(*buf)):
            self.columns[key].push_many(values)
        if len(self.columns) != len(self._schema):
            for key in list(self.columns)[len(self._schema) :]:
                self.columns[key].fill_missing(len(buf))
        self._n += len(buf)

    def append(self, **row: Any) -> None:
        """Append one row; unknown columns are created (earlier rows get missing values)."""
        if self._buf:
            self._flush()
        cols = self.columns
        for key, v in row.items():
            col = cols.get(key)
            if col is None:
                col = cols[key] = _Column(_kind_of(v), self._n)
            col.push(v)
        if len(row) != len(cols):
            for key, col in cols.items():
                if key not in row:
                    col.fill_missing()
        self._n += 1

    def row_buffer(self) -> list[tuple[Any, ...]]:
        """The list that :meth:`append_fast` appends to, for writers that append row tuples
        (schema order) themselves; they should call :meth:`flush_if_large` now and then."""
        return self._buf

    def flush_if_large(self) -> None:
        if len(self._buf) >= self._BATCH:
            self._flush()

    def append_fast(self, values: tuple[Any, ...]) -> None:
        """Append a row given in schema order (the kernel's hot path: no checks, no new columns)."""
        buf = self._buf
        buf.append(values)
        if len(buf) >= self._BATCH:
            self._flush()

    def extend(self, **cols: np.ndarray) -> None:
        """Append many rows at once from equal-length 1-D arrays (e.g. sampled positions)."""
        self._flush()
        lengths = {len(v) for v in cols.values()}
        if len(lengths) != 1:
            raise ValueError(f"table {self.name}: columns of unequal length {sorted(lengths)}")
        (m,) = lengths
        for key, v in cols.items():
            col = self.columns.get(key)
            arr = np.asarray(v)
            if col is None:
                kind = "f" if arr.dtype.kind == "f" else "i" if arr.dtype.kind in "iu" else "o"
                col = self.columns[key] = _Column(kind, self._n)
            col.extend(arr)
        for key, col in self.columns.items():
            if key not in cols:
                col.fill_missing(m)
        self._n += m

    def frame(self) -> pd.DataFrame:
        self._flush()
        if not self.columns:
            return pd.DataFrame()
        df = pd.DataFrame({k: c.series(k) for k, c in self.columns.items()})
        key = _SORT_BY.get(self.name)
        if key is not None and len(df):
            df = df.sort_values(key, kind="mergesort", ignore_index=True)
        return df


class Trace:
    """All event tables of a run. ``append(table, **row)`` from anywhere in the kernel."""

    def __init__(self, config: TraceConfig | None = None) -> None:
        self.config = config or TraceConfig()
        self.tables: dict[str, Table] = {name: Table(name, schema) for name, schema in SCHEMAS.items()}

    def table(self, name: str) -> Table:
        t = self.tables.get(name)
        if t is None:
            check_table_name(name)
            t = self.tables[name] = Table(name, SCHEMAS.get(name, ()))
        return t

    def append(self, table: str, **row: Any) -> None:
        self.table(table).append(**row)

    def frames(self) -> dict[str, pd.DataFrame]:
        """Every table as a DataFrame (DESIGN.md columns first, extra columns after)."""
        return {name: t.frame() for name, t in self.tables.items()}

    def write(self, directory: str | os.PathLike[str], fmt: str = "csv") -> list[Path]:
        """Write one file per table into ``directory`` (created); returns the paths."""
        return write_frames(self.frames(), directory, fmt)


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


def write_frames(frames: Mapping[str, pd.DataFrame], directory: str | os.PathLike[str], fmt: str = "csv") -> list[Path]:
    """Write DataFrames as ``<name>.csv`` (or ``.parquet``, which needs pyarrow); every name
    is checked (:func:`check_table_name`) before anything is written."""
    for name in frames:
        check_table_name(name)
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, df in frames.items():
        if fmt == "csv":
            p = out / f"{name}.csv"
            # lineterminator fixed so Windows and POSIX produce the same bytes
            df.to_csv(p, index=False, lineterminator="\n")
        elif fmt == "parquet":
            try:
                import pyarrow  # noqa: F401
            except ImportError as e:  # pragma: no cover - depends on the environment
                raise RuntimeError("fmt='parquet' needs pyarrow (pip install 'aquasim-py[parquet]')") from e
            p = out / f"{name}.parquet"
            df.to_parquet(p, index=False)
        else:
            raise ValueError(f"unknown trace format {fmt!r} (use 'csv' or 'parquet')")
        paths.append(p)
    return paths


def _pandas_version() -> tuple[int, int]:
    major, minor = pd.__version__.split(".")[:2]
    return int(major), int("".join(ch for ch in minor if ch.isdigit()) or 0)


# pandas' default C float parser is not correctly rounded through 3.0.x (measured: 3.0.6 reads
# 6.40422650443282e-273 one ulp off, ~30% of random doubles); "round_trip" hands every field to
# Python's correctly rounded parser. 3.1 made that the default and deprecates the option.
_READ_CSV_KW: dict[str, Any] = {"float_precision": "round_trip"} if _pandas_version() < (3, 1) else {}


def _read_csv(path: Path, name: str) -> pd.DataFrame:
    """One CSV table with exact floats and its schema's dtypes.

    Only an empty field is missing (the writer's ``na_rep``): pandas' default NA strings would
    turn a category such as "NA" or "null" into NaN. Schema columns get their dtypes back even
    where the text cannot show them (an empty table, a category that looks like a number, a
    category column that is all missing): "c" object strings with None for missing, as
    :meth:`Table.frame` makes; "f" float64 and "i" int64 in an empty table (with rows they read
    as written: an int column with missing values was written as floats)."""
    kinds = dict(SCHEMAS.get(name, ()))
    try:
        header = pd.read_csv(path, nrows=0).columns
    except pd.errors.EmptyDataError:  # a table without columns is written as an empty line
        return pd.DataFrame()
    # categories as text: "007" or "1.50" must not become numbers
    dtype = {c: str for c in header if kinds.get(c) == "c"}
    df = pd.read_csv(path, keep_default_na=False, na_values=[""], dtype=dtype, **_READ_CSV_KW)
    for c in header:
        kind = kinds.get(c)
        if kind in ("f", "i") and len(df) == 0:  # no rows: the header alone reads as object
            df[c] = df[c].astype(np.float64 if kind == "f" else np.int64)
        elif kind == "c":
            col = df[c]
            df[c] = pd.Series(
                np.where(col.isna(), None, col.to_numpy(dtype=object)), index=df.index, dtype=object, name=c
            )
    return df


def load(directory: str | os.PathLike[str]) -> dict[str, pd.DataFrame]:
    """Read every ``*.csv`` / ``*.parquet`` table of a trace directory (``summary.json`` as a dict
    under the key ``"summary"`` is left to the caller: only tables are returned).

    CSV floats are read back bit for bit, and writing the loaded frames again gives the same
    bytes (pandas 2.1 to 3.x)."""
    d = Path(directory)
    if not d.is_dir():
        raise FileNotFoundError(f"trace directory {d} does not exist")
    frames: dict[str, pd.DataFrame] = {}
    for p in sorted(d.iterdir()):
        if p.suffix == ".csv":
            frames[p.stem] = _read_csv(p, p.stem)
        elif p.suffix == ".parquet":
            frames[p.stem] = pd.read_parquet(p)
    return frames


def read_summary(directory: str | os.PathLike[str]) -> dict[str, Any]:
    """The ``summary.json`` of a trace directory."""
    return json.loads((Path(directory) / "summary.json").read_text())
