"""Streaming traces (issue 20 item 6): tables written in chunks as the run goes, byte for byte
what the in-memory path writes; tables nobody reads not kept; memory flat with run length."""

from __future__ import annotations

import gc
import json
import math
import subprocess
import sys
import textwrap
import tracemalloc
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from trace_paths import PATHS, row, using

from aquasim_py import metrics, run_scenario, trace
from aquasim_py.trace import TableNotKept, Trace, TraceFiles, write_frames
from aquasim_py.trace.read import _read_csv

# --------------------------------------------------------------------------- the sinks
# one operation on a trace: (table, row) appended through Trace.append; values of every kind
# the column store handles, so that columns appear late and widen (int -> float -> object)
_value = st.one_of(
    st.none(),
    st.integers(-(2**40), 2**40),
    st.floats(allow_nan=True, allow_infinity=False, width=64),
    st.text(alphabet='ab,"\n x0.', max_size=4),
    st.booleans(),
)
_row = st.dictionaries(st.sampled_from(["a", "b", "c", "d"]), _value, min_size=1, max_size=3)
_ops = st.lists(st.tuples(st.sampled_from(["t1", "t2", "estimates"]), _row), max_size=60)


def _replay(tr: Trace, ops: list[tuple[str, dict[str, Any]]]) -> None:
    for i, (name, values) in enumerate(ops):
        if name == "estimates":  # a schema table: fixed columns first, extra ones after
            tr.table(name).append(*row(time=float(i), node=i % 3, protocol="p", **values))
        else:
            tr.table(name).append(*row(**values))


def _streamed(tmp: Path, ops: list[tuple[str, dict[str, Any]]], chunk: int, fmt: str = "csv") -> dict[str, Path]:
    tr = Trace()
    tr.stream(lambda n: tmp / f"{n}.{fmt}", fmt, chunk_rows=chunk)
    _replay(tr, ops)
    return {k: p for k, (p, _) in tr.close().items() if p is not None}


@settings(max_examples=30)
@given(ops=_ops, chunk=st.integers(1, 7))
# an int column that turns float (a missing value) and then object (None) in a later chunk:
# the whole table's ints became floats on the way ("0.0"), with and without a column added
@example(ops=[("t2", {"c": 0}), ("t2", {"c": 0}), ("t2", {"a": None}), ("t2", {"a": None, "c": None})], chunk=2)
@example(
    ops=[("t2", {"c": 0, "a": 1}), ("t2", {"c": 0, "a": 1}), ("t2", {"a": 1}), ("t2", {"c": None, "a": 1})], chunk=2
)
def test_streamed_csv_is_byte_identical_to_writing_the_whole_table(tmp_path_factory, ops, chunk):
    """Chunks of 1..7 rows, columns that appear after rows were written and ints that turn
    float mid-table: the file is the bytes write_frames gives for the whole in-memory table
    (the Python path's), on every path."""
    ref_dir = tmp_path_factory.mktemp("ref")
    ref = Trace()
    with using("python"):
        _replay(ref, ops)
        write_frames(ref.frames(), ref_dir)
    for p in PATHS:
        with using(p):
            files = _streamed(tmp_path_factory.mktemp(p), ops, chunk)
        assert sorted(files) == sorted(ref.tables)
        for name, path in files.items():
            assert path.read_bytes() == (ref_dir / f"{name}.csv").read_bytes(), (p, name)


def test_streamed_parquet_reads_back_as_the_whole_table_does(tmp_path):
    pytest.importorskip("pyarrow")
    ops: list[tuple[str, dict[str, Any]]] = []
    for i in range(200):  # a category all missing at first, an int column that turns float, a late column
        row: dict[str, Any] = {"a": i, "s": None if i < 50 else f"k{i % 3}"}
        if i == 120:
            row["a"] = 0.5
        if i >= 150:
            row["late"] = i * 0.25
        ops.append(("t1", row))
    ref = Trace()
    _replay(ref, ops)
    write_frames(ref.frames(), tmp_path / "ref", "parquet")
    files = _streamed(tmp_path, ops, chunk=16, fmt="parquet")
    for name, path in files.items():
        pd.testing.assert_frame_equal(pd.read_parquet(path), pd.read_parquet(tmp_path / "ref" / f"{name}.parquet"))


def test_time_ordered_table_streams_in_the_order_frame_sorts(tmp_path):
    """packets rows arrive out of time order (a reception is written when its last bit
    arrives): with the watermark promise kept, the file is the stably time-sorted table."""
    rng = np.random.default_rng(3)
    now = [0.0]
    lag = 2.0

    def fill(tr: Trace) -> None:
        pk = tr.table("packets")
        for uid in range(3000):
            now[0] += float(rng.exponential(0.05))
            # times in [now - lag, now + 5]: late receptions and drops decided ahead
            t = now[0] + float(rng.uniform(-lag, 5.0))
            t = round(t, 1)  # many equal times: the sort must be stable
            pk.append((t, "rx", None, 1, 2, -1, uid, "k", 8, 0.1, 3.0, "d", t))

    ref = Trace()
    fill(ref)
    rng = np.random.default_rng(3)
    now[0] = 0.0
    tr = Trace()
    tr.table("packets").order_by_time(lambda: now[0] - lag)
    tr.stream(lambda n: tmp_path / f"{n}.csv", chunk_rows=64)
    fill(tr)
    tr.close()
    write_frames({"packets": ref.frames()["packets"]}, tmp_path / "ref")
    assert (tmp_path / "packets.csv").read_bytes() == (tmp_path / "ref" / "packets.csv").read_bytes()


def test_a_row_breaking_the_order_promise_is_an_error_not_a_misordered_file(tmp_path):
    tr = Trace()
    pk = tr.table("packets")
    pk.order_by_time(lambda: 100.0)
    tr.stream(lambda n: tmp_path / f"{n}.csv", chunk_rows=1)
    pk.append(*row(time=150.0, event="tx"))  # streamed: the file now holds rows before t = 100
    with pytest.raises(RuntimeError, match="order_by_time"):
        pk.append(*row(time=50.0, event="rx"))  # earlier than the promised 100 s


def test_dropped_table_keeps_nothing_and_says_so(tmp_path):
    tr = Trace()
    tr.stream(lambda n: None if n == "noise" else tmp_path / f"{n}.csv", chunk_rows=10)
    for i in range(1000):
        tr.table("noise").append(*row(v=i))
    assert tr.tables["noise"].frame().empty  # no rows held
    done = tr.close()
    assert done["noise"] == (None, 1000)
    assert not (tmp_path / "noise.csv").exists()
    files = TraceFiles({k: p for k, (p, _) in done.items() if p}, dropped=["noise"])
    assert "noise" not in files
    with pytest.raises(TableNotKept, match="noise"):
        files.get("noise")  # a metric reading it fails loudly, never a silent None


# values of a categorical column: missing, empty, csv's specials, texts read as missing elsewhere
_cat = st.one_of(st.none(), st.sampled_from(["", "tx", "rx", "drop", "NA", "null", "a,b", 'q"', "x\ny"]))


@settings(max_examples=30)
@given(rows=st.lists(st.tuples(_cat, _cat), max_size=80), chunk=st.integers(1, 9))
def test_a_tally_counts_the_rows_handed_to_the_file(tmp_path_factory, rows, chunk):
    """Table.tally counts each (event, reason) of the rows as chunks go to the file: the
    counts of the whole table kept in memory, and the packet counts of the file read back."""
    tmp = tmp_path_factory.mktemp("tally")
    ref, tr = Trace(), Trace()
    tr.table("packets").tally(("event", "reason"))
    tr.stream(lambda n: tmp / f"{n}.csv", chunk_rows=chunk)
    for t in (ref, tr):
        for i, (event, reason) in enumerate(rows):
            t.table("packets").append(*row(time=float(i), event=event, reason=reason))
    tr.close()
    tally = tr.tables["packets"].tallies[("event", "reason")]
    whole = ref.frames()["packets"]
    expected = Counter(zip(whole["event"], whole["reason"])) if rows else Counter()
    assert tally == dict(expected)
    back = trace.read_table(tmp / "packets.csv", "packets")
    assert metrics.packet_counts(tally) == metrics.packet_counts(back)


def test_a_tally_gives_up_on_a_column_that_is_not_categorical_and_the_counts_read_the_file(tmp_path):
    tr = Trace()
    tr.table("packets").tally(("event", "reason"))
    tr.stream(lambda n: tmp_path / f"{n}.csv", chunk_rows=2)
    for i, event in enumerate(["tx", "rx", "drop", 7, "rx"]):  # 7: the column becomes "o"
        tr.table("packets").append(*row(time=float(i), event=event, reason="collision" if event == "drop" else None))
    done = tr.close()
    assert tr.tables["packets"].tallies[("event", "reason")] is None
    files = TraceFiles({k: p for k, (p, _) in done.items() if p}, tallies={"packets": tr.tables["packets"].tallies})
    assert files.tally("packets", ("event", "reason")) is None
    assert metrics.summarize(files, [])["packets.received"] == 2  # counted from the file


# a packets row as a writer might append it: event texts that read back as written and some
# that do not (empty, spaces, quotes, "NA"), ints that turn float or missing, any float
_event = st.one_of(st.sampled_from(["tx", "rx", "drop", "NA", "007", "1.50", "", " a", 'q"', "a,b"]), st.none())
_kept_row = st.tuples(
    _event,
    st.one_of(st.integers(-(2**40), 2**40), st.sampled_from([None, 2.5])),
    st.integers(0, 5),
    st.one_of(st.floats(width=64), st.floats(0.0, 100.0)),
)


@settings(max_examples=40)
@given(rows=st.lists(_kept_row, max_size=40), chunk=st.integers(1, 9))
@example(rows=[("tx", 1, 0, 0.5), ("rx", 1, 2, -0.0), ("drop", 2, 3, math.nan), (None, 3, 1, math.inf)], chunk=2)
def test_columns_kept_as_written_are_what_the_file_reads_back(tmp_path_factory, rows, chunk):
    """Table.keep: the columns kept as chunks go to the file are exactly (dtypes, values, NaN
    and -0.0, order) what reading those columns back from the file gives; TraceFiles.columns
    hands them out instead of parsing, and a keep given up leaves the file's path."""
    tmp = tmp_path_factory.mktemp("kept")
    tr = Trace()
    tr.table("packets").keep(("event", "uid", "node", "time"))
    tr.stream(lambda n: tmp / f"{n}.csv", chunk_rows=chunk)
    for event, uid, node, t in rows:
        tr.table("packets").append(*row(time=t, event=event, uid=uid, node=node))
    table = tr.tables["packets"]
    done = tr.close()
    kept = table.kept()
    plain = {"tx", "rx", "drop", "NA", "007", "1.50", None}
    if rows and all(r[0] in plain and isinstance(r[1], int) for r in rows):
        assert kept is not None  # nothing here that would not read back: kept, not given up
    files = TraceFiles(
        {k: p for k, (p, _) in done.items() if p},
        kept={} if kept is None else {"packets": (kept, tuple(table.columns))},
    )
    for cols in (["event", "uid", "node", "time"], ["time", "node"], ["uid", "reason"], ["event"]):
        back = _read_csv(tmp / "packets.csv", "packets", cols)
        got = files.columns("packets", cols)
        pd.testing.assert_frame_equal(got, back, check_exact=True)
        assert got.dtypes.tolist() == back.dtypes.tolist()
        for c in got.columns:  # floats bit for bit (-0.0 is not 0.0), every NaN alike
            if got[c].dtype == np.float64:
                assert np.array_equal(_bits(got[c]), _bits(back[c])), c


def test_columns_outside_the_schema_are_not_kept(tmp_path):
    """A column the table's schema does not type reads back typed by its text ("007" as 7), so
    Table.keep gives it up and TraceFiles parses the file."""
    tr = Trace()
    tr.table("samples").keep(("label",))
    tr.stream(lambda n: tmp_path / f"{n}.csv", chunk_rows=2)
    for i in range(5):
        tr.table("samples").append(*row(time=float(i), label="007"))
    table = tr.tables["samples"]
    done = tr.close()
    assert table.kept() is None
    files = TraceFiles({k: p for k, (p, _) in done.items() if p})
    assert files.columns("samples", ["label"])["label"].tolist() == [7] * 5


def _bits(x: pd.Series) -> np.ndarray:
    a = x.to_numpy(dtype=np.float64)
    return np.where(np.isnan(a), np.nan, a).view(np.int64)


def _peak_streaming(rows: int, tmp: Path) -> int:
    tmp.mkdir()
    tr = Trace()
    tr.stream(lambda n: tmp / f"{n}.csv", chunk_rows=256)
    gc.collect()
    tracemalloc.start()
    for i in range(rows):
        tr.table("samples").append(*row(time=i * 0.01, node=i % 7, value=float(i) / 7.0))
    tr.close()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak


def test_streaming_memory_does_not_grow_with_the_number_of_rows(tmp_path):
    """Peak Python memory while streaming 20x the rows grows by < 10 % (kept in memory, the
    20x table alone would take 20x its columns)."""
    _peak_streaming(300, tmp_path / "warm")  # lazy imports of the CSV writer, not counted
    small = _peak_streaming(1_500, tmp_path / "a")
    large = _peak_streaming(30_000, tmp_path / "b")
    assert large < 1.10 * small, (small, large)


# --------------------------------------------------------------------------- runs
BEACON = textwrap.dedent(
    """
    [simulation]
    duration_s = 60.0
    seed = 3
    [environment]
    volume = { lo = [0.0, 0.0, 0.0], hi = [1000.0, 1000.0, 100.0] }
    sound_speed = { model = "constant", speed_mps = 1500.0 }
    [channel]
    max_range_m = 3000.0
    bitrate_bps = 1000.0
    [[nodes]]
    name = "anchors"
    role = "anchor"
    protocol = "beacon"
    placement = { kind = "explicit", positions = [[0.0, 0.0, 10.0], [1000.0, 0.0, 10.0], [0.0, 1000.0, 10.0]] }
    params = { period_s = 5.0 }
    [[nodes]]
    name = "sensors"
    role = "ordinary"
    count = 3
    protocol = "beacon"
    placement = { kind = "uniform", lo = [100.0, 100.0, 20.0], hi = [900.0, 900.0, 80.0] }
    mobility = { model = "random_walk", speed_min = 0.0, speed_max = 0.5, leg_duration = 30.0 }
    [trace]
    position_interval_s = 1.0
    """
)


def _scenario(tmp: Path, extra: str = "") -> Path:
    p = tmp / "beacon.toml"
    p.write_text(BEACON + extra)
    return p


def test_run_streams_in_small_chunks_to_the_bytes_of_the_in_memory_run(tmp_path, monkeypatch):
    """A whole run streamed in 50-row chunks writes exactly the files of the same run kept in
    memory and written at the end (the path of every earlier version), on every path."""
    from aquasim_py import scenario

    path = _scenario(tmp_path)
    with using("python"):
        sim = scenario.build(scenario.load(path))
        sim.run(60.0)
        write_frames(sim.trace.frames(), tmp_path / "memory")
    monkeypatch.setattr(trace, "CHUNK_ROWS", 50)
    for p in PATHS:
        with using(p):
            run_scenario(path, out=tmp_path / p, progress=False)
        for f in sorted((tmp_path / "memory").iterdir()):
            assert (tmp_path / p / f.name).read_bytes() == f.read_bytes(), (p, f.name)


def test_tables_not_requested_are_kept_only_when_a_metric_reads_them(tmp_path):
    path = _scenario(tmp_path, '    tables = ["estimates"]\n')
    res = run_scenario(path, out=tmp_path / "out", progress=False)
    written = {p.name for p in (tmp_path / "out").iterdir() if p.suffix == ".csv"}
    assert {"estimates.csv", "beacon_range_errors.csv"} <= written
    assert "ranges.csv" not in written and "packets.csv" not in written
    # beacon's metrics read ranges, packets and positions: kept aside, so its metrics exist
    assert res.metrics["beacon.ranges"] == res.tables.rows("ranges") > 0
    assert res.metrics["packets.sent"] > 0
    # the same metrics from the tables as an analyst would load them
    again = metrics.summarize(dict(res.tables), res.scenario.protocols())
    assert again == res.metrics


def test_scratch_files_go_with_the_result(tmp_path):
    path = _scenario(tmp_path, '    tables = ["estimates"]\n')
    res = run_scenario(path, progress=False)  # no output directory: everything is scratch
    scratch = res.tables.path("packets").parent
    assert scratch.is_dir() and scratch != tmp_path
    assert isinstance(res.tables, TraceFiles)
    del res
    gc.collect()
    assert not scratch.exists()


def test_a_protocol_that_declares_what_it_reads_lets_the_rest_go(tmp_path):
    """multilateration_all_refs reads estimates and nodes: with positions not requested, no
    positions file exists anywhere and asking for it says why."""
    p = tmp_path / "s.toml"
    text = (Path(__file__).resolve().parents[1] / "scenarios" / "stvf_quick.toml").read_text()
    text = text.replace('tables = ["nodes", "estimates", "positions"]', 'tables = ["nodes"]')
    p.write_text(text)
    short = {"simulation.duration_s": 3.0, "metrics.warmup_s": 0.0}
    short |= {f"nodes.{g}.params.training_s": 1.0 for g in (0, 1)}
    res = run_scenario(p, variant="multilateration_all_refs", overrides=short, progress=False)
    assert "positions" not in res.tables and "estimates" in res.tables
    with pytest.raises(TableNotKept):
        res.tables["positions"]


# --------------------------------------------------------------------------- acceptance
MEMORY_SCENARIO = textwrap.dedent(
    """
    # 7 nodes: 3 anchors out of each other's range (so no inbox fills up unread), 4 static
    # unknowns near the centroid; ground-truth positions sampled at 50 Hz make the trace long
    [simulation]
    duration_s = 100.0
    seed = 1
    [environment]
    volume = { lo = [-300.0, -300.0, 0.0], hi = [300.0, 300.0, 40.0] }
    sound_speed = { model = "constant", speed_mps = 1500.0 }
    [channel]
    max_range_m = 260.0
    bitrate_bps = 10000.0
    collision = "none"
    [[nodes]]
    name = "beacons"
    role = "anchor"
    protocol = "multilateration_all_refs"
    placement = { kind = "explicit", positions = [[0.0, 231.0, 20.0], [200.0, -115.5, 20.0], [-200.0, -115.5, 20.0]] }
    params = { range_m = 260.0, period_s = 10.0, listen_s = 9.0, send_window_s = 5.0 }
    [[nodes]]
    name = "unknown"
    role = "ordinary"
    count = 4
    protocol = "multilateration_all_refs"
    placement = { kind = "uniform", lo = [-15.0, -15.0, 15.0], hi = [15.0, 15.0, 25.0] }
    params = { range_m = 260.0, period_s = 10.0, listen_s = 9.0, send_window_s = 5.0 }
    [trace]
    position_interval_s = 0.02
    """
)

# VmHWM, not ru_maxrss: Linux updates the latter lazily (measured 207 MB against a VmHWM of 318 MB)
_MEASURE = """
import json, sys
import aquasim_py
res = aquasim_py.run_scenario(sys.argv[1], overrides={"simulation.duration_s": float(sys.argv[2])},
                              out=sys.argv[3], progress=False)
status = dict(line.split(":", 1) for line in open("/proc/self/status"))
print(json.dumps({"peak_kib": int(status["VmHWM"].split()[0]), "rows": res.tables.rows("positions")}))
"""


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads VmHWM from /proc (Linux)")
def test_memory_of_a_7_node_run_at_20x_the_duration_grows_by_less_than_10_percent(tmp_path):
    """Issue 20's acceptance: peak RSS of a fresh process running the scenario for D and for
    20 D (D = 100 s: 17 500 position rows, past one chunk; 20 D: 350 000). Kept in memory,
    the 20 D trace alone adds about 50 MB to a ~190 MB process."""
    path = tmp_path / "mem.toml"
    path.write_text(MEMORY_SCENARIO)
    peaks = {}
    for d in (100.0, 2000.0):
        out = subprocess.run(
            [sys.executable, "-c", _MEASURE, str(path), str(d), str(tmp_path / f"out{d:g}")],
            capture_output=True,
            text=True,
            check=True,
        )
        peaks[d] = json.loads(out.stdout.strip().splitlines()[-1])
    assert peaks[2000.0]["rows"] == pytest.approx(20 * peaks[100.0]["rows"], rel=0.01)
    assert peaks[2000.0]["peak_kib"] < 1.10 * peaks[100.0]["peak_kib"], peaks
