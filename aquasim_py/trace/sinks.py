"""Where a streamed table's chunks go: a CSV file, a Parquet file, or nowhere."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import pandas as pd

from .columns import Chunk
from .csvfmt import QUOTED_MAX, csv_bytes
from .schema import CHUNK_ROWS

__all__ = ["CsvSink", "Discard", "ParquetSink", "Sink"]


class Sink(Protocol):
    """Where a streamed table's chunks go (:meth:`Trace.stream`)."""

    @property
    def path(self) -> Path | None:
        """The file written (None: nothing is)."""
        ...

    def write(self, chunk: Chunk, kinds: Mapping[str, str], floated: frozenset[str] = frozenset()) -> None:
        """Append the rows of ``chunk``; ``kinds``: every column's type so far (as :class:`Column`);
        ``floated``: the columns that went from int to float in this chunk (even if they are
        objects now)."""
        ...

    def close(self, empty: pd.DataFrame) -> None:
        """Finish the file; ``empty``: the table's columns without rows (for a table never written)."""
        ...


class Discard:
    """A table nobody reads (not written, not used by a metric): its rows are dropped."""

    path: Path | None = None

    def write(self, chunk: Chunk, kinds: Mapping[str, str], floated: frozenset[str] = frozenset()) -> None:
        pass

    def close(self, empty: pd.DataFrame) -> None:
        pass


def _widened(old: Mapping[str, str], new: Mapping[str, str], floated: frozenset[str], k: str) -> bool:
    """Whether the ints written so far in column ``k`` are floats in the whole table: it was
    an int column and turned float since, even if it holds objects now (int -> float ->
    object converts the ints on the way; int -> object keeps them)."""
    return old[k] == "i" and (new[k] == "f" or k in floated)


def _reformats(old: Mapping[str, str], new: Mapping[str, str], floated: frozenset[str] = frozenset()) -> bool:
    """Whether text already written must change: a column added (a new header field and an
    empty field on every earlier row) or an int column turned float ("3" becomes "3.0",
    :func:`_widened`). Any other change (to "o", any object) keeps each value's text: pandas
    writes a float, an int or a string in an object column as in a typed one."""
    return any(k not in old for k in new) or any(_widened(old, new, floated, k) for k in old)


class CsvSink:
    """A table appended to ``path`` chunk by chunk, byte for byte what :func:`write_frames`
    writes for the whole table.

    pandas formats each field from its value and its column's dtype alone, so chunks written
    one after another give the whole table's bytes as long as each chunk has the column types
    the table ends with. When a later chunk changes them in a way that changes earlier text
    (:func:`_reformats`), the file written so far is rewritten once, chunk by chunk."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._kinds: dict[str, str] | None = None
        self._quoted: dict[Any, str] = {}  # a string (None, bool) -> its CSV field (_object_fields), kept across chunks

    def write(self, chunk: Chunk, kinds: Mapping[str, str], floated: frozenset[str] = frozenset()) -> None:
        if self._kinds is not None and _reformats(self._kinds, kinds, floated):
            self._rewrite(kinds, floated)
        first = self._kinds is None
        data = csv_bytes(list(chunk.columns), list(chunk.columns.values()), chunk.n, first, self._quoted)
        if data is None:  # a column the bulk formatter does not take: pandas writes the chunk
            with open(self.path, "w" if first else "a", encoding="utf-8", newline="") as f:
                chunk.frame().to_csv(f, index=False, header=first, lineterminator="\n")
        else:
            with open(self.path, "wb" if first else "ab") as f:
                f.write(data)
        self._kinds = dict(kinds)
        if len(self._quoted) > QUOTED_MAX:  # a column of ever new strings: do not keep them all
            self._quoted.clear()

    def _rewrite(self, kinds: Mapping[str, str], floated: frozenset[str]) -> None:
        assert self._kinds is not None
        widened = [k for k in self._kinds if _widened(self._kinds, kinds, floated, k)]
        added = [k for k in kinds if k not in self._kinds]
        tmp = self.path.with_name(self.path.name + ".rewrite")
        with open(tmp, "w", encoding="utf-8", newline="") as f:
            pd.DataFrame(columns=list(kinds)).to_csv(f, index=False, lineterminator="\n")
            # every field read back as its exact text ("" = missing) and written again as is,
            # except the widened ints, which become floats as an in-memory column does
            chunks = pd.read_csv(self.path, dtype=str, keep_default_na=False, na_filter=False, chunksize=CHUNK_ROWS)
            for chunk in chunks:
                for k in widened:
                    chunk[k] = pd.to_numeric(chunk[k].mask(chunk[k] == "")).astype(np.float64)
                for k in added:
                    chunk[k] = ""
                chunk[list(kinds)].to_csv(f, index=False, header=False, lineterminator="\n")
        os.replace(tmp, self.path)

    def close(self, empty: pd.DataFrame) -> None:
        if self._kinds is None:  # no rows at all: the header alone, as write_frames gives
            empty.to_csv(self.path, index=False, lineterminator="\n")


class ParquetSink:
    """A table written to ``path`` as one Parquet row group per chunk (pyarrow). Column types
    are inferred as ``DataFrame.to_parquet`` infers them for the whole table; a chunk that
    widens them (int to float, a new column, a type for a column all missing so far) rewrites
    the row groups written so far once, row group by row group."""

    def __init__(self, path: Path, name: str) -> None:
        self.path = path
        self.name = name
        self._file = path  # the file being written (another name while rewriting)
        self._writer: Any = None
        self._schema: Any = None

    @staticmethod
    def _arrow(df: pd.DataFrame) -> Any:
        import pyarrow as pa

        return pa.Table.from_pandas(df, preserve_index=False).replace_schema_metadata(None)

    def write(self, chunk: Chunk, kinds: Mapping[str, str], floated: frozenset[str] = frozenset()) -> None:
        import pyarrow as pa
        import pyarrow.parquet as pq

        t = self._arrow(chunk.frame())
        if self._writer is None:
            self._schema = t.schema
            self._writer = pq.ParquetWriter(self._file, t.schema)
        elif not t.schema.equals(self._schema):
            try:
                schema = pa.unify_schemas([self._schema, t.schema], promote_options="permissive")
            except (pa.ArrowInvalid, pa.ArrowTypeError) as e:
                raise RuntimeError(f"trace table {self.name}: a column changed type mid-run ({e})") from None
            if not schema.equals(self._schema):
                self._rewrite(schema)
            t = _conform(t, self._schema)
        self._writer.write_table(t)

    def _rewrite(self, schema: Any) -> None:
        import pyarrow.parquet as pq

        self._writer.close()
        old = self._file
        self._file = self.path.with_name(self.path.name + ".rewrite") if old == self.path else self.path
        self._writer = pq.ParquetWriter(self._file, schema)
        src = pq.ParquetFile(old)
        for i in range(src.num_row_groups):
            self._writer.write_table(_conform(src.read_row_group(i), schema))
        src.close()
        old.unlink()
        self._schema = schema

    def close(self, empty: pd.DataFrame) -> None:
        import pyarrow.parquet as pq

        if self._writer is None:  # no rows at all
            pq.write_table(self._arrow(empty), self.path)
            return
        self._writer.close()
        if self._file != self.path:
            os.replace(self._file, self.path)


def _conform(t: Any, schema: Any) -> Any:
    """Arrow table ``t`` with ``schema``'s columns (missing ones null) and types."""
    import pyarrow as pa

    cols = [t.column(f.name).cast(f.type) if f.name in t.column_names else pa.nulls(len(t), f.type) for f in schema]
    return pa.Table.from_arrays(cols, schema=schema)
