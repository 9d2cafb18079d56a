"""Event tables of a run: cheap appends during the run, pandas / CSV / Parquet after.

Each table is a set of typed columns (``array.array`` for numbers, integer codes for
categorical strings, a list for anything else): appending a row costs a few list appends and
a packet trace of millions of rows stays compact. ``frames()`` turns the tables into pandas
DataFrames with the schema's columns first; ``write`` and :func:`load` round-trip them.

Modules: :mod:`.schema` (the tables' columns and types), :mod:`.columns` (the column store),
:mod:`.table` (one table: appends, streaming), :mod:`.store` (all tables of a run),
:mod:`.csvfmt` (CSV text), :mod:`.sinks` (where streamed chunks go), :mod:`.read` (reading
files back).
"""

from .read import TableNotKept, TraceFiles, load, read_summary, read_table, table_columns
from .schema import CHUNK_ROWS, SCHEMAS, TABLE_NAME, TraceConfig, check_table_name
from .store import Trace, write_frames
from .table import Table

__all__ = [
    "CHUNK_ROWS",
    "SCHEMAS",
    "TABLE_NAME",
    "Table",
    "TableNotKept",
    "Trace",
    "TraceConfig",
    "TraceFiles",
    "check_table_name",
    "load",
    "read_summary",
    "read_table",
    "table_columns",
    "write_frames",
]
