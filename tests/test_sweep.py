"""Sweeps: job order, seeds, identical rows whatever the number of workers."""

from __future__ import annotations

import csv
import json
import math
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from aquasim_py import cli, scenario, sweep

SCENARIO = """\
[simulation]
duration_s = 40.0
seed = 21

[environment]
volume = { lo = [0.0, 0.0, 0.0], hi = [800.0, 800.0, 60.0] }

[[nodes]]
role = "anchor"
protocol = "beacon"
placement = { kind = "explicit", positions = [[0.0, 0.0, 5.0], [800.0, 800.0, 5.0]] }
params = { period_s = 4.0 }

[[nodes]]
role = "ordinary"
count = 3
protocol = "beacon"
placement = { kind = "uniform" }
clock = { skew_std_ppm = 30.0 }

[sweep]
runs = 3
grid = { "channel.jitter_std_s" = [0.0, 1e-3], "nodes.1.count" = [2, 4] }
"""


@pytest.fixture
def scen(tmp_path: Path) -> Path:
    p = tmp_path / "sw.toml"
    p.write_text(SCENARIO)
    return p


def test_run_seed_is_deterministic_and_distinct():
    seeds = [sweep.run_seed(21, r) for r in range(100)]
    assert seeds == [sweep.run_seed(21, r) for r in range(100)]
    assert len(set(seeds)) == 100
    assert all(0 <= s < 2**63 for s in seeds)
    assert sweep.run_seed(22, 0) != sweep.run_seed(21, 0)


def test_plan_order(scen):
    jobs = sweep.plan(scenario.load(scen))
    assert [j.index for j in jobs] == list(range(12))
    # grid keys in file order, later keys faster, runs fastest
    points = [tuple(v for _, v in j.point) for j in jobs]
    assert points == [(a, b) for a in (0.0, 1e-3) for b in (2, 4) for _ in range(3)]
    assert [j.run for j in jobs] == [0, 1, 2] * 4
    # common random numbers: run r has the same seed at every grid point
    assert {j.seed for j in jobs if j.run == 1} == {sweep.run_seed(21, 1)}


def test_rows_depend_on_swept_values(scen):
    sc = scenario.load(scen)
    jobs = [j for j in sweep.plan(sc) if j.run == 0]
    rows = sweep.run_jobs(sc, jobs, workers=1)
    assert [r["nodes.1.count"] for r in rows] == [2, 4, 2, 4]
    # 2 anchors, 4 s period, 40 s: 10 beacons each -> 20 sent whatever the listeners
    assert all(r["packets.sent"] == 20 for r in rows)
    # more listeners, more ranges (same seed, same anchors)
    assert rows[1]["beacon.ranges"] > rows[0]["beacon.ranges"]
    # a run row equals a direct single run with the same seed and values
    direct = scenario.load_dict(
        sc.to_dict(),
        scen,
        overrides=[(["nodes", 1, "count"], 4), (["channel", "jitter_std_s"], 0.0)],
        seed=jobs[1].seed,
    )
    sim = scenario.build(direct)
    sim.run(direct.simulation.duration_s)
    from aquasim_py import metrics

    m = metrics.summarize(sim.trace.frames(), direct.protocols())
    for k, v in m.items():
        assert rows[1][k] == v or (math.isnan(v) and math.isnan(rows[1][k])), k


def test_two_workers_give_the_same_csv_as_one(scen, tmp_path, capsys):
    a, b = tmp_path / "w1", tmp_path / "w2"
    short = ["--set", "simulation.duration_s=10"]  # the rows' order and bytes, not the runs' length, are tested
    assert cli.main(["sweep", str(scen), "--workers", "1", "--out", str(a), "--quiet", *short]) == 0
    assert cli.main(["sweep", str(scen), "--workers", "2", "--out", str(b), "--quiet", *short]) == 0
    assert (a / "sweep.csv").read_bytes() == (b / "sweep.csv").read_bytes()
    with open(a / "sweep.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 12
    head = list(rows[0])
    assert head[:4] == ["channel.jitter_std_s", "nodes.1.count", "run", "seed"]
    assert "beacon.range_rmse_m" in head and "packets.sent" in head
    info = json.loads((b / "sweep.json").read_text())
    assert info["runs"] == 12 and info["workers"] == 2 and info["scenario"]["sweep"]["runs"] == 3


def test_sweep_prints_summary(scen, tmp_path, capsys):
    rc = cli.main(["sweep", str(scen), "--workers", "1", "--out", str(tmp_path / "o"), "--set", "sweep.runs=1"])
    out, err = capsys.readouterr()
    assert rc == 0 and err == ""
    assert "4 runs in" in out and "beacon.range_rmse (m)" in out and "n = 1 run per grid point" in out


def test_swept_explicit_placement_sets_its_own_count(scen):
    # the anchors' count (2) is implied by their explicit placement; a swept placement with
    # another number of positions implies its own (the ITMTL Fig. 10 sweep over references)
    three = {"kind": "explicit", "positions": [[0.0, 0.0, 5.0], [800.0, 800.0, 5.0], [800.0, 0.0, 5.0]]}
    sc = scenario.load(scen, overrides=[f'sweep.grid={{"nodes.0.placement"=[{_toml(three)}]}}'])
    job = sweep.plan(sc)[0]
    built = sweep._job_scenario(sweep.bases(sc, [job])[None], str(scen), job)
    assert built.nodes[0].count == 3
    # a count swept with it still has to agree
    sc = scenario.load(scen, overrides=[f'sweep.grid={{"nodes.0.placement"=[{_toml(three)}], "nodes.0.count"=[2]}}'])
    job = sweep.plan(sc)[0]
    with pytest.raises(scenario.ScenarioError, match="count"):
        sweep._job_scenario(sweep.bases(sc, [job])[None], str(scen), job)


def _toml(placement: dict) -> str:
    pos = ", ".join("[" + ", ".join(str(c) for c in p) + "]" for p in placement["positions"])
    return f'{{kind="explicit", positions=[{pos}]}}'


def test_sweep_without_sweep_table(tmp_path, capsys):
    p = tmp_path / "nosweep.toml"
    p.write_text(SCENARIO[: SCENARIO.index("[sweep]")])
    rc = cli.main(["sweep", str(p), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and err.strip() == f"error: {p}: sweep: no [sweep] table: add one with runs and grid to run a sweep"
    assert not (tmp_path / "o").exists()


def test_sweep_grid_value_rejected_by_physics_fails_before_running(scen, tmp_path, capsys):
    rc = cli.main(
        [
            "sweep",
            str(scen),
            "--out",
            str(tmp_path / "o"),
            "--set",
            'sweep.grid={"nodes.1.mobility"=[{model="random_walk", speed_min=3.0, speed_max=1.0}]}',
        ]
    )
    err = capsys.readouterr().err
    assert rc == 2 and len(err.splitlines()) == 1 and "nodes[1].mobility" in err
    assert not (tmp_path / "o").exists()


def test_scheduler_without_dask_is_a_clear_error(scen, tmp_path, capsys, monkeypatch):
    import builtins

    real_import = builtins.__import__

    def no_dask(name, *a, **kw):
        if name.startswith("dask"):
            raise ImportError("No module named 'dask'")
        return real_import(name, *a, **kw)

    monkeypatch.setattr(builtins, "__import__", no_dask)
    rc = cli.main(["sweep", str(scen), "--scheduler", "tcp://127.0.0.1:1", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and err.strip() == "error: --scheduler needs dask.distributed: pip install 'aquasim-py[dask]'"


def test_dask_rows_equal_local_rows(scen):
    distributed = pytest.importorskip("dask.distributed")
    sc = scenario.load(scen, overrides=["sweep.runs=1"])
    jobs = sweep.plan(sc)
    local = sweep.run_jobs(sc, jobs, workers=1)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False) as cluster:
        journal: list[dict] = []
        remote = sweep.run_jobs(sc, jobs, scheduler=cluster.scheduler_address, on_row=journal.append)
    assert json.dumps(local) == json.dumps(remote)
    # the Dask path feeds the same row journal, one row per run as it finishes
    assert sorted(r["key"] for r in journal) == sorted(j.key for j in jobs)


def test_csv_cells_round_trip_floats(tmp_path):
    rows = [{"a": 0.1 + 0.2, "run": 0, "seed": 1, "m": float("nan"), "v": [1, 2]}]
    job = sweep.Job(0, (("a", 0.3),), 0, 1)
    cols = sweep.columns(rows, [job])
    assert cols == ["a", "run", "seed", "m", "v"]
    sweep.rows_to_csv(rows, cols, tmp_path / "x.csv")
    with open(tmp_path / "x.csv") as fh:
        back = next(iter(csv.DictReader(fh)))
    assert float(back["a"]) == 0.1 + 0.2 and np.isnan(float(back["m"])) and json.loads(back["v"]) == [1, 2]


# --------------------------------------------------------------------------- surviving sweeps
KILL_SCENARIO = """\
[simulation]
duration_s = 200.0
seed = 5

[environment]
volume = { lo = [0.0, 0.0, 0.0], hi = [800.0, 800.0, 60.0] }

[[nodes]]
role = "anchor"
protocol = "beacon"
placement = { kind = "explicit", positions = [[0.0, 0.0, 5.0], [800.0, 800.0, 5.0]] }
params = { period_s = 4.0 }

[[nodes]]
role = "ordinary"
count = 3
protocol = "beacon"
placement = { kind = "uniform" }

[sweep]
runs = 4
grid = { "nodes.1.count" = [2, 4] }
"""


@pytest.fixture(scope="module")
def kill_reference(tmp_path_factory) -> tuple[Path, bytes]:
    """The kill scenario and the sweep.csv of its uninterrupted sweep (8 runs)."""
    d = tmp_path_factory.mktemp("kill")
    p = d / "k.toml"
    p.write_text(KILL_SCENARIO)
    assert cli.main(["sweep", str(p), "--workers", "1", "--out", str(d / "ref"), "--quiet"]) == 0
    return p, (d / "ref" / "sweep.csv").read_bytes()


def _journal_lines(path: Path) -> list[bytes]:
    try:
        return [x for x in path.read_bytes().split(b"\n") if x]
    except FileNotFoundError:
        return []


@pytest.mark.parametrize(("sig", "workers"), [(signal.SIGINT, "1"), (signal.SIGKILL, "2")])
def test_killed_sweep_resumes_to_the_uninterrupted_rows(kill_reference, tmp_path, sig, workers, capsys):
    scen, reference = kill_reference
    k = 2
    # the signal races the sweep's last runs: a sweep that finished first is started again
    # (three tries), so that what is tested is the resume, not the machine's speed
    for attempt in range(3):
        out = tmp_path / f"o{attempt}"
        cmd = [sys.executable, "-m", "aquasim_py.cli", "sweep", str(scen), "--workers", workers, "--out", str(out)]
        errfile = tmp_path / "stderr.txt"
        with open(errfile, "wb") as fh:
            proc = subprocess.Popen([*cmd, "--quiet"], stdout=subprocess.DEVNULL, stderr=fh)
        deadline = time.monotonic() + 120.0
        while len(_journal_lines(out / sweep.JOURNAL)) < k:
            if proc.poll() is not None:
                break
            assert time.monotonic() < deadline, "no rows written in 120 s"
            time.sleep(0.005)
        if proc.poll() is None:
            proc.send_signal(sig)
        proc.wait(timeout=120)
        if proc.returncode != 0:
            break
    err = errfile.read_bytes()
    assert proc.returncode != 0, "the sweep finished before the signal three times: make its runs longer"
    written = _journal_lines(out / sweep.JOURNAL)
    assert k <= len(written) < 8
    if sig == signal.SIGINT:
        assert proc.returncode == 130
        assert err.decode().strip() == (
            f"error: interrupted by SIGINT: {len(written)} of 8 runs saved in {out}; finish with --resume"
        )
        # the rows so far, already in plan order
        assert reference.startswith((out / "sweep.csv").read_bytes().split(b"\n", 1)[0])
    else:
        assert proc.returncode == -signal.SIGKILL
        # as if killed in the middle of writing a row: an unfinished last line
        with open(out / sweep.JOURNAL, "ab") as fh:
            fh.write(written[-1][: len(written[-1]) // 2])
    before = {json.loads(x)["key"] for x in written}
    capsys.readouterr()
    assert cli.main(["sweep", str(scen), "--workers", workers, "--out", str(out), "--resume"]) == 0
    said = capsys.readouterr().out
    dropped = " (dropped 1 partially written row)" if sig == signal.SIGKILL else ""
    assert f"resuming {out}: {len(written)} of 8 runs already done{dropped}" in said
    assert (out / "sweep.csv").read_bytes() == reference
    keys = [json.loads(x)["key"] for x in _journal_lines(out / sweep.JOURNAL)]
    assert len(keys) == len(set(keys)) == 8  # each run once: the saved ones were not run again
    assert set(keys) > before


def test_run_keys_are_stable_and_distinct(scen):
    sc = scenario.load(scen)
    keys = [j.key for j in sweep.plan(sc)]
    assert keys == [j.key for j in sweep.plan(scenario.load(scen))]
    assert len(set(keys)) == len(keys) and all(len(k) == 16 and int(k, 16) >= 0 for k in keys)
    # the key follows the resolved scenario: a changed value changes every key...
    other = [j.key for j in sweep.plan(scenario.load(scen, overrides=["simulation.duration_s=41"]))]
    assert not set(other) & set(keys)
    # ...but not more runs (the first runs keep theirs) nor where the results go
    more = sweep.plan(scenario.load(scen, overrides=["sweep.runs=4", "output.directory='elsewhere'"]))
    assert [j.key for j in more if j.run < 3] == keys


def test_journal_drops_broken_lines(tmp_path):
    path = tmp_path / sweep.JOURNAL
    with sweep.Journal(path) as j:
        j.append({"key": "a", "x": 0.1 + 0.2, "m": float("nan")})
        j.append({"key": "b", "x": 1})
    with open(path, "ab") as fh:
        fh.write(b'{"key": "c", "x"')  # killed mid-write
    rows, dropped = sweep.read_journal(path)
    assert [r["key"] for r in rows] == ["a", "b"] and dropped == 1
    assert rows[0]["x"] == 0.1 + 0.2 and math.isnan(rows[0]["m"])
    sweep.read_journal(path, repair=True)
    with sweep.Journal(path) as j:
        j.append({"key": "c", "x": 2})
    rows, dropped = sweep.read_journal(path)
    assert [r["key"] for r in rows] == ["a", "b", "c"] and dropped == 0


class _Boom(RuntimeError):
    pass


def _boom_protocol() -> str:
    """A beacon that raises inside the simulation when its ``boom`` parameter is set."""
    from aquasim_protocols.beacon.node import BeaconNode
    from aquasim_py import registry

    name = "test_sweep_boom"
    try:
        registry.get(name)
    except Exception:

        class BoomNode(BeaconNode):
            name = "test_sweep_boom"

            class Params(BeaconNode.Params):
                boom: bool = False

            def run(self):
                if self.params.boom:
                    yield self.env.timeout(1.0)
                    raise _Boom("protocol\nbug")
                yield from super().run()

        registry.register(BoomNode)
    return name


def test_failed_run_is_recorded_and_the_others_go_on(tmp_path, capsys):
    name = _boom_protocol()
    p = tmp_path / "boom.toml"
    text = SCENARIO.replace('count = 3\nprotocol = "beacon"', f'count = 3\nprotocol = "{name}"')
    text = text.replace(
        'grid = { "channel.jitter_std_s" = [0.0, 1e-3], "nodes.1.count" = [2, 4] }',
        'grid = { "nodes.1.params.boom" = [false, true] }',
    )
    p.write_text(text.replace("runs = 3", "runs = 2"))
    out = tmp_path / "o"
    rc = cli.main(["sweep", str(p), "--workers", "1", "--out", str(out), "--quiet", "--keep-traces"])
    stdout, err = capsys.readouterr()
    assert rc == 1
    assert err.strip() == f"error: 2 of 4 runs failed (see the error column of {out / 'sweep.csv'})"
    assert stdout.strip() == f"4 runs in {stdout.split(' in ')[1].split(' s ')[0]} s -> {out / 'sweep.csv'}"
    with open(out / "sweep.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["nodes.1.params.boom"] for r in rows] == ["False", "False", "True", "True"]
    assert [r["error"] for r in rows] == ["", "", "_Boom: protocol bug", "_Boom: protocol bug"]
    assert all(r["packets.sent"] == "" for r in rows[2:]) and all(int(r["packets.sent"]) > 0 for r in rows[:2])
    # the successful runs' traces are kept, complete, under runs/<key>/
    kept = sorted(d.name for d in (out / "runs").iterdir())
    assert kept == sorted(r["key"] for r in rows[:2])
    assert (out / "runs" / kept[0] / "summary.json").exists()
    # summary.csv: the successful runs only
    import pandas as pd

    s = pd.read_csv(out / "summary.csv")
    sent = s[s["metric"] == "packets.sent"]
    assert list(sent["nodes.1.params.boom"]) == [False] and list(sent["n"]) == [2]


def test_summary_csv_is_summarize_runs_of_sweep_csv(scen, tmp_path):
    import pandas as pd

    from aquasim_py.metrics import summarize_runs

    out = tmp_path / "o"
    assert cli.main(["sweep", str(scen), "--workers", "1", "--out", str(out), "--quiet", "--set", "sweep.runs=2"]) == 0
    runs = pd.read_csv(out / "sweep.csv")
    s = pd.read_csv(out / "summary.csv")
    assert list(s.columns) == [
        "channel.jitter_std_s",
        "nodes.1.count",
        "metric",
        "n",
        "mean",
        "std",
        "ci95_low",
        "ci95_high",
        "center_stat",
        "center",
        "center_ci95_low",
        "center_ci95_high",
    ]
    rmse = s[(s["metric"] == "beacon.range_rmse_m") & (s["nodes.1.count"] == 4) & (s["channel.jitter_std_s"] == 1e-3)]
    vals = runs[(runs["nodes.1.count"] == 4) & (runs["channel.jitter_std_s"] == 1e-3)]["beacon.range_rmse_m"]
    assert int(rmse["n"].iloc[0]) == 2 and rmse["mean"].iloc[0] == pytest.approx(vals.mean(), rel=1e-12)
    # beside the mean, the centre the reports draw: an error's geometric mean, named
    assert rmse["center_stat"].iloc[0] == "geometric mean"
    assert rmse["center"].iloc[0] == pytest.approx(np.exp(np.log(vals).mean()), rel=1e-12)
    assert 0 < rmse["center_ci95_low"].iloc[0] <= rmse["center"].iloc[0] <= rmse["center_ci95_high"].iloc[0]
    assert len(s) == len(
        summarize_runs(
            runs,
            by=["channel.jitter_std_s", "nodes.1.count"],
            metrics=[c for c in runs.columns if c.startswith(("beacon.", "packets."))],
        )
    )
    pq = pytest.importorskip("pyarrow.parquet")
    assert pq.read_table(out / "sweep.parquet").num_rows == 8


def test_help_names_the_sweep_directory(capsys):
    assert cli.main(["sweep", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "out/<scenario file stem>-sweep" in text and "--resume" in text and "--keep-traces" in text


def _interrupt_after(monkeypatch, n: int) -> None:
    """The sweep is interrupted (as by Ctrl-C) right after its n-th row is journalled."""
    append = sweep.Journal.append
    count = 0

    def append_then_stop(self, row):
        nonlocal count
        append(self, row)
        count += 1
        if count == n:
            raise KeyboardInterrupt

    monkeypatch.setattr(sweep.Journal, "append", append_then_stop)


@pytest.mark.parametrize("killed", [False, True])
def test_an_interrupted_sweep_is_refused_without_resume_and_kept(scen, tmp_path, monkeypatch, capsys, killed):
    out = tmp_path / "o"
    argv = ["sweep", str(scen), "--workers", "1", "--out", str(out), "--quiet", "--set", "sweep.runs=1"]
    argv += ["--set", "simulation.duration_s=10"]  # what is kept and refused, not the runs' length, is tested
    with monkeypatch.context() as m:
        _interrupt_after(m, 3)
        assert cli.main(argv) == 130
    if killed:  # a SIGKILL writes no sweep.json
        (out / "sweep.json").unlink()
    saved = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    capsys.readouterr()
    assert cli.main(argv) == 2
    _, err = capsys.readouterr()
    assert err == (
        f"error: {out} holds an interrupted sweep (3 finished runs saved in rows.jsonl): finish it with --resume, "
        "or start again with --overwrite (discards them)\n"
    )
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == saved  # nothing touched
    # --resume runs only the missing run; the journal keeps the 3 saved rows first
    assert cli.main([*argv, "--resume"]) == 0
    keys = [json.loads(x)["key"] for x in _journal_lines(out / sweep.JOURNAL)]
    assert len(keys) == 4 and b"\n".join(_journal_lines(out / sweep.JOURNAL)).startswith(saved["rows.jsonl"].strip())
    # a complete sweep there is no longer in the way; --overwrite discards an interrupted one
    assert sweep.saved_runs(out) == 0
    assert cli.main(argv) == 0
    with monkeypatch.context() as m:
        _interrupt_after(m, 1)
        assert cli.main(argv) == 130
    assert sweep.saved_runs(out) == 1
    assert cli.main([*argv, "--overwrite"]) == 0
    assert len(_journal_lines(out / sweep.JOURNAL)) == 4
