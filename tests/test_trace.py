"""Trace tables: typed column store, DataFrames, CSV round trip, byte-stable float output."""

from __future__ import annotations

import math
from array import array
from typing import Any

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from trace_paths import PATHS, row, using

from aquasim_py import trace
from aquasim_py.trace import SCHEMAS, Table, Trace
from aquasim_py.trace.columns import Column


def test_design_tables_exist_with_design_columns_first():
    tr = Trace()
    frames = tr.frames()
    assert list(frames["packets"].columns[:11]) == [
        "time",
        "event",
        "reason",
        "node",
        "src",
        "dst",
        "uid",
        "kind",
        "bits",
        "tof",
        "snr_db",
    ]
    assert list(frames["positions"].columns) == ["time", "node", "x", "y", "z", "vx", "vy", "vz"]
    assert list(frames["estimates"].columns) == [c for c, _ in SCHEMAS["estimates"]]
    assert list(frames["clocks"].columns) == [
        "time",
        "node",
        "protocol",
        "skew",
        "offset",
        "true_skew",
        "true_offset",
        "error",
    ]


def test_rows_with_new_and_missing_columns():
    t = Table("custom")
    t.append(*row(time=0.0, node=1, label="a"))
    t.append(*row(time=1.5, node=2, extra=3.25))
    t.append(*row(time=2.0, label="b", node=3))
    df = t.frame()
    assert list(df.columns) == ["time", "node", "label", "extra"]
    assert df.node.tolist() == [1, 2, 3] and df.node.dtype == np.int64
    assert df.label.tolist()[0] == "a" and pd.isna(df.label[1]) and df.label[2] == "b"
    assert pd.isna(df.extra[0]) and df.extra[1] == 3.25 and pd.isna(df.extra[2])


def test_columns_widen_instead_of_failing():
    t = Table("w")
    t.append(*row(v=1))
    t.append(*row(v=2.5))  # int column meets a float
    t.append(*row(v=None))
    t.append(*row(w="x"))
    t.append(*row(w=[1, 2]))  # categorical meets an unhashable object
    df = t.frame()
    assert df.v.tolist()[:2] == [1.0, 2.5] and pd.isna(df.v[2])
    assert df.w.tolist()[3] == "x" and df.w.tolist()[4] == [1, 2]


def test_extend_vectorized_rows():
    t = Table("positions", SCHEMAS["positions"])
    n = 4
    t.extend(
        time=np.full(n, 2.0),
        node=np.arange(n),
        x=np.arange(n) * 1.5,
        y=np.zeros(n),
        z=np.ones(n),
        vx=np.zeros(n),
        vy=np.zeros(n),
        vz=np.zeros(n),
    )
    t.append(*row(time=3.0, node=0, x=1.0, y=2.0, z=3.0, vx=0.0, vy=0.0, vz=0.0, flag="late"))
    df = t.frame()
    assert df.x.tolist() == [0.0, 1.5, 3.0, 4.5, 1.0] and df.node.tolist() == [0, 1, 2, 3, 0]
    assert df.flag.isna().sum() == 4 and df.flag.iloc[-1] == "late"
    with pytest.raises(ValueError):
        t.extend(time=np.zeros(2), node=np.zeros(3))


def test_packets_sorted_by_time_stably():
    tr = Trace()
    row = tr.table("packets").append
    nan = math.nan
    row((2.0, "rx", None, 1, 0, -1, 0, "a", 10, 2.0, nan, "direct", 2.0))
    row((0.0, "tx", None, 0, 0, -1, 0, "a", 10, nan, nan, None, 0.0))
    row((2.0, "rx", None, 2, 0, -1, 0, "a", 10, 2.0, nan, "direct", 2.0))
    df = tr.frames()["packets"]
    assert df.time.tolist() == [0.0, 2.0, 2.0] and df.node.tolist() == [0, 1, 2]


# awkward doubles: not the shortest decimal of their neighbours' sum, extremes, subnormals,
# integers beyond 2**53 stored as floats, negative zero, and values pandas' fast parsers (the
# C parser before 3.1 without float_precision="round_trip") read one ulp off
AWKWARD = [
    0.1 + 0.2,
    1 / 3,
    1e-300,
    -2.5e17,
    math.pi * 1e-9,
    123456789.123456789,
    5e-324,
    2.2250738585072014e-308 / 3,
    1.7976931348623157e308,
    2.0**53 + 2,
    1e22,
    -0.0,
    math.inf,
    6.40422650443282e-273,
    3.615950549094847e-70,
]


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return np.array_equal(np.asarray(a, np.float64).view(np.int64), np.asarray(b, np.float64).view(np.int64))


def test_csv_round_trip_is_exact_and_byte_stable(tmp_path):
    rng = np.random.default_rng(0)
    # random doubles over the whole exponent range: ~30% of these read back wrong without an
    # exact parser (measured with pandas 3.0.6 and with 2.1's default parser)
    rand = (rng.standard_normal(3000) * 10.0 ** rng.integers(-300, 300, 3000)).tolist()
    vals = AWKWARD + rand
    tr = Trace()
    for i, v in enumerate(vals):
        tr.table("clocks").append(
            *row(
                time=float(i),
                node=i,
                protocol="p" if i % 3 else "NA",
                skew=v,
                offset=-v,
                true_skew=math.nan if i % 5 == 0 else 0.0,
                true_offset=v * 3,
                error=v / 7,
            )
        )
    tr.table("events").append(*row(time=1.0, node=0, what='x,y "quoted"', ok=True))
    tr.table("events").append(*row(time=2.0, node=2**62, what="007", ok=False))
    # categories that look like numbers or NA markers, and an all-missing category column
    tr.table("packets").append(
        *row(
            time=0.5,
            event="tx",
            reason=None,
            node=1,
            src=1,
            dst=2,
            uid=7,
            kind="1.50",
            bits=256,
            tof=math.nan,
            snr_db=-0.0,
            path="null",
            local_time=0.5000000000000001,
        )
    )
    tr.write(tmp_path / "a")
    tr.write(tmp_path / "b")
    names = sorted(p.name for p in (tmp_path / "a").iterdir())
    assert {"clocks.csv", "events.csv", "packets.csv", "positions.csv", "estimates.csv"} <= set(names)
    for name in names:
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    back = trace.load(tmp_path / "a")
    # write -> load -> write: the same bytes, for every table (empty ones included)
    trace.write_frames(back, tmp_path / "c")
    for name in names:
        assert (tmp_path / "c" / name).read_bytes() == (tmp_path / "a" / name).read_bytes(), name
    # loaded floats equal the originals bit for bit (not approximately)
    clocks = back["clocks"]
    assert _same_bits(clocks["skew"], vals)
    assert _same_bits(clocks["offset"], [-v for v in vals])
    assert _same_bits(clocks["error"], [v / 7 for v in vals])
    assert _same_bits(clocks["true_skew"], [math.nan if i % 5 == 0 else 0.0 for i in range(len(vals))])
    # dtypes survive: schema tables exactly as Trace.frames() makes them, empty tables included
    orig = tr.frames()
    for name in ("clocks", "packets", "positions", "estimates"):
        assert back[name].dtypes.to_dict() == orig[name].dtypes.to_dict(), name
        pd.testing.assert_frame_equal(back[name], orig[name])
    assert back["clocks"]["protocol"].tolist()[:3] == ["NA", "p", "p"]
    assert back["packets"]["reason"].tolist() == [None]
    assert back["packets"][["kind", "path"]].iloc[0].tolist() == ["1.50", "null"]
    ev = back["events"]
    assert ev["what"].tolist() == ['x,y "quoted"', "007"]
    assert ev["node"].dtype == np.int64 and ev["node"].tolist() == [0, 2**62]
    assert ev["ok"].dtype == bool and ev["ok"].tolist() == [True, False]
    assert b"\r" not in (tmp_path / "a" / "clocks.csv").read_bytes()


def test_write_rejects_unknown_format_and_load_missing_dir(tmp_path):
    with pytest.raises(ValueError, match="format"):
        Trace().write(tmp_path, fmt="xlsx")
    with pytest.raises(FileNotFoundError):
        trace.load(tmp_path / "nope")


def test_parquet_round_trip(tmp_path):
    pytest.importorskip("pyarrow")
    tr = Trace()
    tr.table("clocks").append(
        *row(time=1.0, node=0, protocol="p", skew=1e-5, offset=0.1, true_skew=0.0, true_offset=0.0, error=0.1)
    )
    tr.write(tmp_path, fmt="parquet")
    back = trace.load(tmp_path)
    assert back["clocks"]["skew"].tolist() == [1e-5]


def test_batched_fast_rows_widen_without_duplicates():
    t = Table("fast", (("a", "i"), ("b", "f")))
    rows = [(i, float(i)) for i in range(5)] + [(2.5, 1.0)] + [(i, 0.0) for i in range(3)]
    for r in rows:
        t.append(r)
    t.append(*row(a=7, b=7.0, c="late"))  # a generic row after buffered ones keeps the order
    df = t.frame()
    assert df["a"].tolist() == [0, 1, 2, 3, 4, 2.5, 0, 1, 2, 7]
    assert df["b"].tolist()[-1] == 7.0 and df["c"].isna().sum() == 9 and t.n == 10


# values a row may hold: exact floats and ints (the C path's), and what it hands back to the
# Python reference: ints beyond int64 and beyond float's range, bools, None, numpy scalars,
# a str subclass, strings
class _Text(str):
    pass


_cell = st.one_of(
    st.floats(width=64),
    st.integers(-(2**63), 2**63 - 1),
    st.integers(-3, 3),
    st.sampled_from([2**63, -(2**63) - 1, 2**1100, True, False, None, np.float64(0.5), np.int64(7), _Text("t")]),
    st.sampled_from(["", "a", "b,c", 'q"', "é"]),
)


def _state(col: Column) -> tuple[Any, ...]:
    """Everything a column holds: kind, values (by type and repr: NaN, -0.0 and 1 vs 1.0 vs
    True told apart; arrays by their bytes), categories in code order, floated."""
    data = col.data
    held = (data.typecode, data.tobytes()) if isinstance(data, array) else [(type(v), repr(v)) for v in data]
    return col.kind, held, [(type(k), repr(k), c) for k, c in col.cats.items()], col.floated


@pytest.mark.skipif("c" not in PATHS, reason="aquasim_py._fastcsv not built")
@settings(max_examples=150)
@given(
    kinds=st.lists(st.sampled_from("fico"), min_size=1, max_size=4),
    before=st.lists(_cell, max_size=3),
    rows=st.lists(st.lists(_cell, min_size=4, max_size=4), min_size=1, max_size=12),
)
def test_batches_of_rows_fill_columns_as_the_python_path_does(kinds, before, rows):
    """Table._push_batch in C against zip(*rows) + push_many: the same kinds, values,
    categories (coded in order of first appearance) and floated flags, whatever the batch
    holds and whatever the columns held before (pushed one by one, as a widened column)."""
    batch = [tuple(r[: len(kinds)]) for r in rows]
    states = {}
    for path in PATHS:
        cols = [Column(k) for k in kinds]
        for col in cols:
            for v in before:
                col.push(v)
        with using(path):
            Table._push_batch(cols, batch)
            Table._push_batch(cols, batch[::-1])  # a second batch meets the categories known
        states[path] = [_state(c) for c in cols]
    assert states["c"] == states["python"]
