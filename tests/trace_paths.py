"""The trace's two code paths, for tests that hold them equal: the C loops of
``aquasim_py._fastcsv`` (when built) and their Python references in ``aquasim_py.trace``;
and :func:`row`, a keyword row as ``Table.append`` takes it."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from types import ModuleType
from typing import Any

import numpy as np
import pandas as pd

from aquasim_py.trace import csvfmt

#: path name -> the module trace uses (None: the Python reference); "c" only where it was built
PATHS: dict[str, ModuleType | None] = {"python": None, **({"c": csvfmt.fastcsv} if csvfmt.fastcsv else {})}


@contextmanager
def using(name: str) -> Iterator[None]:
    """Run the trace on path ``name`` of :data:`PATHS` inside the block."""
    old = csvfmt.fastcsv
    csvfmt.fastcsv = PATHS[name]
    try:
        yield
    finally:
        csvfmt.fastcsv = old


def csv_text(df: pd.DataFrame, header: bool, quoted: dict[Any, str]) -> str | None:
    """What the streamed CSV sink writes for ``df``'s rows (``csvfmt.csv_bytes``, on the path
    in use), for tests that hold it equal to ``df.to_csv(index=False, header=header,
    lineterminator="\\n")``. None when ``df`` has a column other than float64, int64 or
    object, or a label that is not a string (the sink never hands over such a chunk), or where
    ``csv_bytes`` declines."""
    labels = list(df.columns)
    if not all(type(c) is str for c in labels):
        return None
    columns: list[tuple[str, Any, list[Any]]] = []
    for c in labels:
        a = df[c].to_numpy()
        kind = {np.dtype(np.float64): "f", np.dtype(np.int64): "i", np.dtype(object): "o"}.get(a.dtype)
        if kind is None:
            return None
        columns.append((kind, a.tolist() if kind == "o" else a, []))
    data = csvfmt.csv_bytes(labels, columns, len(df), header, quoted)
    return None if data is None else data.decode("utf-8")


def row(**columns: Any) -> tuple[tuple[Any, ...], tuple[str, ...]]:
    """``(values, column names)`` of a row given as keywords: ``table.append(*row(a=1, b=2))``."""
    return tuple(columns.values()), tuple(columns)
