"""The bulk CSV formatter of streamed traces (trace.csvfmt.csv_bytes, through trace_paths.csv_text): the bytes pandas' own
``DataFrame.to_csv(index=False, lineterminator="\\n")`` writes, on adversarial values, and
pandas' path whenever a column is of a kind the formatter does not take; both the C formatter
(aquasim_py._fastcsv, when built) and the Python reference (trace_paths.PATHS)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from trace_paths import PATHS, csv_text, row, using

from aquasim_py.trace.columns import Chunk
from aquasim_py.trace.sinks import CsvSink

# values that trip formatters: signed zero, subnormals, the repr switch to exponents at 1e16
# and 1e-4, integers beyond 2**53, NaN with another payload, the extremes
_EDGE_FLOATS = [
    -0.0,
    0.0,
    1e-300,
    5e-324,
    -5e-324,
    2.2250738585072014e-308,
    1e16,
    9999999999999998.0,
    1e15,
    0.0001,
    0.00001,
    2.0**53 + 2.0,
    1.7976931348623157e308,
    math.inf,
    -math.inf,
    math.nan,
    float(np.frombuffer(np.array([0x7FF8000000000123], dtype=np.int64).tobytes(), dtype=np.float64)[0]),
    0.1,
    1.0 / 3.0,
    -123456789.125,
]
_floats = st.one_of(st.floats(width=64), st.sampled_from(_EDGE_FLOATS))
_ints = st.one_of(st.integers(-(2**63), 2**63 - 1), st.integers(-3, 300), st.sampled_from([0, -1, 2**63 - 1, -(2**63)]))
# strings of a category column: empty, csv's specials (delimiter, quote, line breaks), spaces,
# texts pandas reads as missing or as numbers, non-ASCII; None is a missing value
_texts = st.one_of(
    st.none(),
    st.booleans(),
    st.text(max_size=6),
    st.text(alphabet=',"\n\r x0.', max_size=4),
    st.sampled_from(["", " ", "NA", "nan", "None", "null", "1.50", "007", "a,b", 'say "hi"', "é", "\t"]),
)
_kind = st.sampled_from(["f", "i", "o"])


@st.composite
def _frames(draw: st.DrawFn) -> pd.DataFrame:
    n = draw(st.integers(1, 25))
    kinds = draw(st.lists(_kind, min_size=2, max_size=6))
    cols: dict[str, object] = {}
    for j, kind in enumerate(kinds):
        name = draw(st.sampled_from([f"c{j}", f"c{j},x", f'c{j}"q', f"c{j} "]))
        if kind == "f":
            # a column of few distinct values too (the formatter formats each distinct one once)
            pool = draw(st.lists(_floats, min_size=1, max_size=n))
            cols[name] = np.array([draw(st.sampled_from(pool)) for _ in range(n)], dtype=np.float64)
        elif kind == "i":
            cols[name] = np.array(draw(st.lists(_ints, min_size=n, max_size=n)), dtype=np.int64)
        else:
            cols[name] = pd.Series(draw(st.lists(_texts, min_size=n, max_size=n)), dtype=object)
    return pd.DataFrame(cols)


def _pandas(df: pd.DataFrame, header: bool) -> str:
    return df.to_csv(index=False, header=header, lineterminator="\n")


@settings(max_examples=120, deadline=None)
@given(df=_frames(), header=st.booleans())
@example(
    df=pd.DataFrame(
        {
            "t": np.array(_EDGE_FLOATS),
            "i": np.arange(len(_EDGE_FLOATS), dtype=np.int64) * (2**61),
            "c": pd.Series(([None, "", "a,b", 'q"', "\n", True] * 4)[: len(_EDGE_FLOATS)], dtype=object),
        }
    ),
    header=True,
)
def test_bulk_csv_is_what_pandas_writes(df: pd.DataFrame, header: bool) -> None:
    """Float64, int64 and object columns of strings / None / bools: formatted in bulk (not
    handed back to pandas), and the text is pandas' to the byte, on every path."""
    want = _pandas(df, header)
    for path in PATHS:
        with using(path):
            assert csv_text(df, header, {}) == want, path


def test_string_cache_across_chunks_keeps_the_bytes() -> None:
    """The sink's cache of quoted strings, reused by a later chunk, gives the same fields."""
    a = pd.DataFrame({"k": pd.Series(["x,y", None, 'z"'], dtype=object), "v": [1.5, -0.0, np.nan]})
    b = pd.DataFrame({"k": pd.Series(['z"', "x,y", ""], dtype=object), "v": [0.1, 1e16, 2.0]})
    for path in PATHS:
        quoted: dict[str, str] = {}
        with using(path):
            assert csv_text(a, True, quoted) == _pandas(a, True)
            assert quoted  # the strings were cached
            assert csv_text(b, False, quoted) == _pandas(b, False)


def test_columns_it_does_not_take_go_to_pandas(tmp_path) -> None:
    """A column of another dtype or of other objects (NaN, numpy scalars), a lone column, no
    rows: the formatter declines, and the streamed file is still pandas' bytes."""
    frames = [
        pd.DataFrame({"a": [1.0, 2.0], "b": pd.Series([np.nan, "x"], dtype=object)}),
        pd.DataFrame({"a": [1.0, 2.0], "b": pd.Series([np.float64(0.1), "x"], dtype=object)}),
        pd.DataFrame({"a": [1.0, 2.0], "b": np.array([True, False])}),
        pd.DataFrame({"a": np.array([1.0, 2.0], dtype=np.float32), "b": [1, 2]}),
        pd.DataFrame({"a": pd.Series(["", None], dtype=object)}),
        pd.DataFrame({"a": [1.0], "b": [2]}).iloc[:0],
    ]
    for path in PATHS:
        for i, df in enumerate(frames):
            with using(path):
                assert csv_text(df, True, {}) is None
            if df.dtypes.eq(np.float32).any():
                continue  # a table holds no float32 column: no sink sees one
            # the chunk a table of these columns hands its sink (float64 "f", int64 "i", others "o")
            kinds = {c: {"float64": "f", "int64": "i"}.get(str(df[c].dtype), "o") for c in df.columns}
            chunk = Chunk(
                {c: (k, df[c].tolist() if k == "o" else df[c].to_numpy(), []) for c, k in kinds.items()}, len(df)
            )
            sink = CsvSink(tmp_path / f"{path}{i}.csv")
            with using(path):
                sink.write(chunk, kinds)
            assert (tmp_path / f"{path}{i}.csv").read_text(encoding="utf-8") == _pandas(df, True)


def test_float_text_is_python_repr() -> None:
    """The premise of _float_fields: numpy's astype(str), which pandas writes, gives the digits
    of Python's repr, here on 10^5 random bit patterns (every exponent) and the edge values."""
    bits = np.random.default_rng(7).integers(-(2**63), 2**63 - 1, 100_000, dtype=np.int64, endpoint=True)
    x = np.concatenate([bits.view(np.float64), np.array(_EDGE_FLOATS)])
    x = x[~np.isnan(x)]
    assert x.astype(str).tolist() == list(map(float.__repr__, x.tolist())), sys.version


@pytest.mark.skipif("c" not in PATHS, reason="aquasim_py._fastcsv not built")
def test_c_float_text_is_python_repr() -> None:
    """The C formatter's float fields are float.__repr__'s text ("" for NaN, any payload), on
    10^5 random bit patterns (every exponent, subnormals, NaNs) and the edge values; its int
    fields are str's on the extremes and random int64s."""
    fast = PATHS["c"]
    assert fast is not None
    rng = np.random.default_rng(11)
    x = rng.integers(-(2**63), 2**63 - 1, 100_000, dtype=np.int64, endpoint=True).view(np.float64)
    x = np.concatenate([x, np.array(_EDGE_FLOATS), np.array([1e-5, -1e-5, 1e-4, 1e22, 123456789012345680.0])])
    i = rng.integers(-(2**63), 2**63 - 1, len(x), dtype=np.int64, endpoint=True)
    i[:4] = [0, -1, 2**63 - 1, -(2**63)]
    want = "".join(f"{'' if math.isnan(v) else repr(v)},{k}\n" for v, k in zip(x.tolist(), i.tolist()))
    assert fast.csv_rows([("f", x, None), ("i", i, None)], len(x)).decode() == want


@pytest.mark.skipif("c" not in PATHS, reason="aquasim_py._fastcsv not built")
def test_c_short_float_text_is_python_repr() -> None:
    """The C formatter's own shortest round trip (fast_repr, without CPython's dtoa) for
    2^-10 <= |v| < 2^51, the magnitudes of times, delays and SNRs: repr's text for 3000 random
    mantissas of every binary exponent from 2^-12 to 2^52 (both edges of that range crossed),
    the mantissas at the edges (a power of two has a closer neighbour below), and values whose
    two shortest candidates are exactly as close (repr takes the even digit)."""
    fast = PATHS["c"]
    assert fast is not None
    rng = np.random.default_rng(5)
    exps = np.repeat(np.arange(-12, 53), 3000)
    mant = rng.integers(0, 2**52, len(exps), dtype=np.int64)
    mant[::1000] = 0
    mant[1::1000] = 2**52 - 1
    x = (((exps + 1023).astype(np.int64) << 52) | mant).view(np.float64)
    x[::2] *= -1
    ties = [258428801846949.88, 32734755089552.188, 2.0**51 - 0.5, 9007199254740.992]
    taken = 0
    for v in x.tolist() + ties:
        text = fast.fast_repr(v)
        assert text is None or text == repr(v), v
        if 2.0**-10 <= abs(v) < 2.0**51:
            assert text is not None, v
            taken += 1
    assert taken == 3000 * 61 + len(ties)


@given(
    x=st.lists(
        st.one_of(_floats, st.floats(2.0**-12, 2.0**52), st.floats(-(2.0**52), -(2.0**-12))), min_size=1, max_size=40
    )
)
def test_c_float_text_is_python_repr_hypothesis(x: list[float]) -> None:
    """As above, on hypothesis' floats (its own edge cases: -0.0, inf, subnormals, 1e16, ...),
    each value repeated so the formatter's cache of distinct values is read as well as filled."""
    fast = PATHS.get("c")
    if fast is None:
        pytest.skip("aquasim_py._fastcsv not built")
    a = np.array(x + x[::-1], dtype=np.float64)
    want = "".join(f"{'' if math.isnan(v) else repr(v)},{v!r}\n" for v in a.tolist())
    fields = [repr(v) for v in a.tolist()]
    assert fast.csv_rows([("f", a, None), ("s", fields, None)], len(a)).decode() == want


def test_columns_read_alone_are_the_whole_tables_columns(tmp_path) -> None:
    """TraceFiles.columns parses only the columns asked for, into exactly the dtypes and values
    of the whole table's (CSV and parquet), also through table_columns and the warm-up view; a
    table the run did not keep still fails loudly, an absent one is None."""
    from aquasim_py.metrics import _AfterWarmup
    from aquasim_py.trace import TableNotKept, Trace, TraceFiles, read_table, table_columns

    for fmt in ("csv", "parquet"):
        d = tmp_path / fmt
        d.mkdir()
        tr = Trace()

        def route(n: str, d: Path = d, fmt: str = fmt) -> Path | None:
            return None if n == "noise" else d / f"{n}.{fmt}"

        tr.stream(route, fmt, chunk_rows=5)
        pk = tr.table("packets")
        for i in range(23):
            ev = ("tx", "rx", "drop")[i % 3]
            pk.append(
                (i * 0.5, ev, "collision" if ev == "drop" else None, i % 4, 0, -1, i // 3, "007", 64)
                + (1e-300 * i, -0.0 if i % 2 else math.nan, None, math.nan)
            )
            tr.table("noise").append(*row(v=i))
        done = tr.close()
        files = TraceFiles({k: p for k, (p, _) in done.items() if p is not None}, dropped=["noise"])
        whole = read_table(d / f"packets.{fmt}", "packets")
        for cols in (["time", "event"], ["uid", "reason", "node"], ["path", "tof", "kind", "nothing"]):
            want = whole[[c for c in whole.columns if c in cols]]
            pd.testing.assert_frame_equal(files.columns("packets", cols), want, check_exact=True)
            pd.testing.assert_frame_equal(table_columns(files, "packets", cols), want, check_exact=True)
            view = _AfterWarmup(files, 1.0)
            pd.testing.assert_frame_equal(table_columns(view, "packets", cols), want, check_exact=True)
        assert table_columns(files, "ranges", ["uid"]) is None
        plain = table_columns({"packets": whole}, "packets", ["uid"])
        assert plain is not None and plain.equals(whole[["uid"]])
        with pytest.raises(TableNotKept, match="noise"):
            table_columns(files, "noise", ["v"])
