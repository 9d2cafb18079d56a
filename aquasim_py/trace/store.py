"""All event tables of a run (:class:`Trace`), and writing DataFrames as trace files."""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping
from pathlib import Path

import pandas as pd

from .schema import CHUNK_ROWS, SCHEMAS, TraceConfig, check_table_name
from .sinks import CsvSink, Discard, ParquetSink, Sink
from .table import Table

__all__ = ["Trace", "write_frames"]


class Trace:
    """All event tables of a run: ``table(name)`` (made on first use), then its ``append``.

    By default every table is kept in memory (:meth:`frames`). After :meth:`stream` each table
    goes where ``route(name)`` says, as the run goes: a file (written in chunks) or nowhere;
    :meth:`close` then finishes the files.
    """

    def __init__(self, config: TraceConfig | None = None) -> None:
        self.config = config or TraceConfig()
        self.tables: dict[str, Table] = {name: Table(name, schema) for name, schema in SCHEMAS.items()}
        self._route: Callable[[str], Path | None] | None = None
        self._fmt = "csv"
        self._chunk_rows = CHUNK_ROWS

    def table(self, name: str) -> Table:
        t = self.tables.get(name)
        if t is None:
            check_table_name(name)
            t = self.tables[name] = Table(name, SCHEMAS.get(name, ()))
            if self._route is not None:
                self._attach(t)
        return t

    def stream(self, route: Callable[[str], Path | None], fmt: str = "csv", chunk_rows: int | None = None) -> None:
        """Stream every table (those that exist and those made later): ``route(name)`` is the
        file to write it to (``.csv`` or ``.parquet`` as ``fmt``), or None to keep none of
        its rows. Rows go out in chunks of ``chunk_rows``; the files are byte for byte what
        :meth:`write` gives for the same rows."""
        if fmt not in ("csv", "parquet"):
            raise ValueError(f"unknown trace format {fmt!r} (use 'csv' or 'parquet')")
        self._route, self._fmt = route, fmt
        self._chunk_rows = CHUNK_ROWS if chunk_rows is None else chunk_rows
        for t in self.tables.values():
            self._attach(t)

    def _attach(self, t: Table) -> None:
        assert self._route is not None
        path = self._route(t.name)
        sink: Sink
        if path is None:
            sink = Discard()
        elif self._fmt == "csv":
            sink = CsvSink(path)
        else:
            sink = ParquetSink(path, t.name)
        t.stream_to(sink, self._chunk_rows)

    def close(self) -> dict[str, tuple[Path | None, int]]:
        """Finish streaming: table name -> (its file or None, its number of rows)."""
        return {name: (t.close(), t.n) for name, t in self.tables.items()}

    def frames(self) -> dict[str, pd.DataFrame]:
        """Every table as a DataFrame (DESIGN.md columns first, extra columns after)."""
        if self._route is not None:
            raise RuntimeError("frames(): the tables are streamed to files; read those (trace.load)")
        return {name: t.frame() for name, t in self.tables.items()}

    def write(self, directory: str | os.PathLike[str], fmt: str = "csv") -> list[Path]:
        """Write one file per table into ``directory`` (created); returns the paths."""
        return write_frames(self.frames(), directory, fmt)


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
