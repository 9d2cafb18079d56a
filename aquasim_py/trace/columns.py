"""The column store of a trace table: typed columns that a row costs a few appends to, and
the chunks a streamed table hands to its file."""

from __future__ import annotations

import math
from array import array
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

__all__ = ["Chunk", "Column", "kind_of", "series"]


class Column:
    """One typed column: "f" float64 and "i" int64 in ``array.array``, "c" strings as int32
    codes into a category list, "o" anything in a list. Degrades ("i" -> "f", anything -> "o")
    when a value does not fit.

    Numbers and codes live outside Python containers, so a trace of millions of rows costs the
    garbage collector nothing to traverse (a list of strings would be rescanned on every full
    collection of a long run).
    """

    __slots__ = ("append", "cats", "data", "floated", "kind")

    def __init__(self, kind: str, n_missing: int = 0, streamed: int = 0) -> None:
        """``n_missing`` rows held here without a value; ``streamed`` earlier rows already
        handed to the table's sink (also without a value, and they count for the type)."""
        self.kind = kind
        # an int column turned float here (its ints became floats, whatever it became later):
        # the text of ints already written must change as the whole column's would
        self.floated = False
        self.cats: dict[Any, int] = {}
        if kind == "f":
            self.data: Any = array("d", [math.nan]) * n_missing
        elif kind == "i" and not (n_missing or streamed):
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
        self.floated = self.floated or (self.kind == "i" and kind == "f")
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
                try:  # every value a known category: one C-level map
                    codes = list(map(cats.__getitem__, values))
                except KeyError:  # new categories (a chunk's columns start without any)
                    for v in dict.fromkeys(values):  # in order of first appearance
                        if v not in cats:
                            self._code(v)
                    codes = list(map(cats.__getitem__, values))
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

    def array(self) -> Any:
        """The values as an array without a copy: float64 ("f"), int64 ("i"), int32 codes into
        :attr:`cats` ("c"); the list itself ("o"). A view: valid until the column grows."""
        if self.kind == "o":
            return self.data
        dtype = np.float64 if self.kind == "f" else np.int64 if self.kind == "i" else np.int32
        return np.frombuffer(self.data, dtype=dtype) if len(self.data) else np.zeros(0, dtype)


def series(name: str, kind: str, values: Any, cats: list[Any], index: pd.Index | None) -> pd.Series:
    """A column as a Series (``kind``, ``values`` and ``cats`` as :meth:`Column.array` gives
    them; float64 / int64 values are used, not copied): "c" and "o" as object columns."""
    if kind in "fi":
        return pd.Series(values, name=name, index=index)
    if kind == "c":
        inv = np.empty(len(cats), dtype=object)
        inv[:] = cats
        values = inv[values] if len(inv) else np.empty(0, dtype=object)
    return pd.Series(values, name=name, dtype=object, index=index)


def kind_of(v: Any) -> str:
    if isinstance(v, (bool, np.bool_)):
        return "o"
    if isinstance(v, (int, np.integer)):
        return "i"
    if isinstance(v, (float, np.floating)):
        return "f"
    if isinstance(v, str):
        return "c"
    return "o"


class Chunk:
    """Rows a streamed table hands to its sink, as arrays in the table's column order: the CSV
    sink formats them as they are (no DataFrame round trip), :meth:`frame` gives the DataFrame
    :meth:`Table.frame` would (the parquet sink, pandas' CSV path).

    ``columns``: name -> (kind, values, categories), as :meth:`Column.array` gives them
    (float64 / int64 arrays, int32 codes into the categories, a list of objects), each owned."""

    __slots__ = ("columns", "n")

    def __init__(self, columns: dict[str, tuple[str, Any, list[Any]]], n: int) -> None:
        self.columns = columns
        self.n = n

    @classmethod
    def take(cls, columns: Mapping[str, Column], n: int, rows: np.ndarray | None = None) -> Chunk:
        """Copies of the ``n`` rows held in ``columns``, or of the rows ``rows`` (indices, in
        that order)."""
        out: dict[str, tuple[str, Any, list[Any]]] = {}
        for key, col in columns.items():
            a = col.array()
            if col.kind == "o":
                a = list(a) if rows is None else [a[i] for i in rows.tolist()]
            else:
                a = a.copy() if rows is None else a[rows]
            out[key] = (col.kind, a, list(col.cats))
        return cls(out, n if rows is None else len(rows))

    def frame(self) -> pd.DataFrame:
        # one index object shared by every column: pandas then skips aligning them (half the cost)
        index = pd.RangeIndex(self.n) if self.columns else None  # (no columns: no rows)
        return pd.DataFrame(
            {k: series(k, kind, a, cats, index) for k, (kind, a, cats) in self.columns.items()}, index=index
        )
