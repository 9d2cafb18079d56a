"""Output safety and signals: the tool deletes or replaces only what it wrote itself, table
names stay inside the output directory, SIGTERM is handled like SIGINT, sweep workers die with
their parent, stale staging directories are cleaned (issue 20, items 1 and 2)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import pytest

from aquasim_py import cli
from aquasim_py.kernel import Simulation
from aquasim_py.node import Node
from aquasim_py.outdir import MANIFEST, STAGING_MARKER, clean_stale, staged_output
from aquasim_py.trace import Trace, write_frames

SCENARIO = """\
[simulation]
duration_s = {duration}
seed = 3

[environment]
volume = {{ lo = [0.0, 0.0, 0.0], hi = [1000.0, 1000.0, 100.0] }}
sound_speed = {{ model = "constant", speed_mps = 1500.0 }}

[channel]
max_range_m = 3000.0

[[nodes]]
name = "anchors"
role = "anchor"
protocol = "beacon"
placement = {{ kind = "explicit", positions = [[0.0, 0.0, 10.0], [1000.0, 0.0, 10.0], [0.0, 1000.0, 10.0]] }}
params = {{ period_s = 5.0 }}

[[nodes]]
name = "sensors"
role = "ordinary"
count = 3
protocol = "beacon"
placement = {{ kind = "uniform", lo = [100.0, 100.0, 20.0], hi = [900.0, 900.0, 90.0] }}
"""
SWEEP = """
[sweep]
runs = 1
grid = { "channel.jitter_std_s" = [0.0, 1e-4] }
"""
REFUSED = "not empty and not an aquasim-py output directory (use --overwrite to write into it)"


#: long enough to be still running when a signal arrives, within the input bounds (positions rows)
LONG = 2e5


def scenario(where: Path, duration: float = 20.0, extra: str = "", name: str = "scen.toml") -> Path:
    p = where / name
    p.write_text(SCENARIO.format(duration=duration) + extra)
    return p


def run(capsys: pytest.CaptureFixture[str], *argv: object) -> tuple[int, str]:
    rc = cli.main([str(a) for a in argv])
    return rc, capsys.readouterr().err


def listing(d: Path) -> list[str]:
    return sorted(p.name for p in d.iterdir())


# --------------------------------------------------------------------------- item 1: outputs
def test_users_directory_refused_then_kept_with_overwrite(tmp_path, capsys):
    sc = scenario(tmp_path)
    out = tmp_path / "results"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    rc, err = run(capsys, sc, "--out", out, "--quiet")
    assert rc == 2 and err.splitlines() == [f"error: --out {out}: {REFUSED}"]
    assert listing(out) == ["notes.txt"] and listing(tmp_path) == ["results", "scen.toml"]

    rc, err = run(capsys, sc, "--out", out, "--quiet", "--overwrite")
    assert rc == 0, err
    assert (out / "notes.txt").read_text() == "mine" and (out / "summary.json").is_file()
    written = json.loads((out / MANIFEST).read_text())["files"]
    assert "notes.txt" not in written and "summary.json" in written
    assert listing(tmp_path) == ["results", "scen.toml"]  # no staging left beside or inside
    assert not [p for p in out.iterdir() if ".tmp-" in p.name]


def test_own_output_rewritten_only_own_files(tmp_path, capsys):
    sc = scenario(tmp_path)
    out = tmp_path / "res"
    assert run(capsys, sc, "--out", out, "--quiet")[0] == 0
    assert "positions.csv" in listing(out)
    (out / "analysis.ipynb").write_text("user's")  # added to an output directory later
    # its own directory needs no --overwrite; tables no longer written disappear, the user's stays
    rc, err = run(capsys, sc, "--out", out, "--quiet", "--set", 'trace.tables=["packets"]')
    assert rc == 0, err
    assert listing(out) == [MANIFEST, "analysis.ipynb", "beacon_range_errors.csv", "packets.csv", "summary.json"]


def test_out_dot_in_a_temporary_cwd(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    sc = scenario(tmp_path)
    rc, err = run(capsys, "scen.toml", "--out", ".", "--quiet")
    assert rc == 2 and err.splitlines() == [f"error: --out .: {REFUSED}"]
    assert listing(tmp_path) == ["scen.toml"]
    rc, err = run(capsys, "scen.toml", "--out", str(tmp_path), "--quiet", "--overwrite")
    assert rc == 0, err
    assert sc.read_text().startswith("[simulation]") and (tmp_path / "summary.json").is_file()
    assert not [p for p in tmp_path.iterdir() if ".tmp-" in p.name]
    assert tmp_path.is_dir() and Path.cwd() == tmp_path  # the working directory itself survives


def test_scenario_output_directory_cannot_delete_a_victim(tmp_path, capsys, monkeypatch):
    work, victim = tmp_path / "work", tmp_path / "victim"
    work.mkdir()
    victim.mkdir()
    (victim / "thesis.tex").write_text("years of work")
    sc = scenario(work, extra='\n[output]\ndirectory = "../victim"\n')
    monkeypatch.chdir(work)
    rc, err = run(capsys, sc, "--quiet")
    assert rc == 2
    assert err.splitlines() == [f"error: {sc}: output.directory: ../victim: {REFUSED}"]
    assert listing(victim) == ["thesis.tex"] and listing(tmp_path) == ["victim", "work"]


def test_variant_run_under_an_all_variants_directory_and_sweep_refusal(tmp_path, capsys):
    """A directory holding only aquasim-py outputs (e.g. one written by --variant) counts as
    the tool's; a sweep's output directory follows the same rules."""
    sc = scenario(tmp_path, extra=SWEEP)
    out = tmp_path / "o"
    assert run(capsys, sc, "--out", out / "one", "--quiet")[0] == 0
    assert run(capsys, sc, "--out", out, "--quiet")[0] == 0  # only our output inside: allowed
    assert (out / "one" / "summary.json").is_file() and (out / "summary.json").is_file()
    user = tmp_path / "mine"
    user.mkdir()
    (user / "keep.txt").write_text("x")
    rc, err = run(capsys, "sweep", sc, "--out", user, "--quiet", "--workers", "1")
    assert rc == 2 and err.splitlines() == [f"error: --out {user}: {REFUSED}"]
    assert listing(user) == ["keep.txt"]


VARIANTS = """
[variants.a]
[variants.b]
"nodes.0.params.period_s" = 6.0
"""


def test_variant_directories_are_outputs_of_their_own(tmp_path, capsys):
    sc = scenario(tmp_path, duration=5.0, extra=VARIANTS)
    out = tmp_path / "all"
    assert run(capsys, sc, "--out", out, "--quiet")[0] == 0
    (out / "a" / "plot.png").write_text("user's")
    # DIR/NAME of an all-variants run is an output directory: --variant may rewrite it
    rc, err = run(capsys, sc, "--variant", "a", "--out", out / "a", "--quiet")
    assert rc == 0, err
    assert (out / "a" / "plot.png").read_text() == "user's"
    # and the all-variants run again: the user's file inside survives
    assert run(capsys, sc, "--out", out, "--quiet")[0] == 0
    assert (out / "a" / "plot.png").read_text() == "user's" and (out / "b" / "summary.json").is_file()
    assert not [p for p in out.rglob("*") if ".tmp-" in p.name]


def test_python_api_follows_the_same_rules(tmp_path):
    import aquasim_py
    from aquasim_py.scenario import ScenarioError

    sc = scenario(tmp_path, duration=5.0)
    out = tmp_path / "api"
    out.mkdir()
    (out / "x.txt").write_text("x")
    res = aquasim_py.run_scenario(sc, progress=False)
    with pytest.raises(ScenarioError, match="overwrite=True"):
        res.write(out)
    res.write(out, overwrite=True)
    assert (out / "x.txt").read_text() == "x" and (out / "summary.json").is_file()


def test_tampered_manifest_deletes_nothing_outside(tmp_path):
    out, outside, ext = tmp_path / "o", tmp_path / "precious.txt", tmp_path / "ext"
    out.mkdir()
    ext.mkdir()
    outside.write_text("keep")
    (ext / "also.txt").write_text("keep")
    (out / "link").symlink_to(ext)
    files = ["../precious.txt", "/etc/passwd", "link/also.txt", "a.csv"]
    (out / MANIFEST).write_text(json.dumps({"files": files}))
    (out / "a.csv").write_text("old")
    with staged_output(out, None, "out") as tmp:
        (tmp / "b.csv").write_text("new")
    assert outside.read_text() == "keep" and (ext / "also.txt").read_text() == "keep"
    assert listing(out) == [MANIFEST, "b.csv", "link"]


@pytest.mark.parametrize("bad", ["../x", "a/b", "..", ".hidden", "-x", "", "a\\b", "x\x00"])
def test_bad_table_names_refused_at_log_time(bad):
    with pytest.raises(ValueError, match="invalid trace table name"):
        Trace().table(bad).append((1,), ("a",))
    with pytest.raises(ValueError, match="invalid trace table name"):
        write_frames({bad: __import__("pandas").DataFrame({"a": [1]})}, "/nonexistent-never-made")


def test_protocol_logging_outside_the_output_directory_is_refused(tmp_path):
    class Escaper(Node):
        name = "escaper"

        def run(self):
            yield self.sleep(1.0)
            self.log("../x", value=1.0)

    sim = Simulation(0)
    sim.add_group(Escaper, 1, positions=[[0.0, 0.0, 10.0]])
    with pytest.raises(ValueError, match=r"invalid trace table name '\.\./x'"):
        sim.run(5.0)
    Trace().table("my_table.v2-a").append((1,), ("a",))  # the allowed alphabet


# --------------------------------------------------------------------------- item 2: signals
def _command() -> list[str]:
    exe = Path(sys.executable).parent / "aquasim-py"
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "aquasim_py.cli"]


def _wait_for(pred, timeout: float = 60.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.05)
    return False


def _staging(where: Path) -> list[Path]:
    return [p for p in where.iterdir() if ".tmp-" in p.name] if where.is_dir() else []


def _marked(where: Path) -> bool:
    """Whether a staging folder in ``where`` carries its owner's marker."""
    return any((p / STAGING_MARKER).is_file() for p in _staging(where))


def _children(pid: int) -> list[int]:
    """Live (not zombie) processes whose parent is ``pid`` (Linux /proc)."""
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if stat[0] != "Z" and int(stat[1]) == pid:
                out.append(int(d.name))
    return out


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return False
    return stat[0] != "Z"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="signals and /proc as on Linux")
def test_sigterm_to_a_run(tmp_path):
    sc = scenario(tmp_path, duration=LONG)  # long: still running when the signal arrives
    out = tmp_path / "res"
    tmpdir = tmp_path / "tmpdir"  # where the run's trace scratch folder goes
    tmpdir.mkdir()
    env = {**os.environ, "TMPDIR": str(tmpdir)}
    cmd = [*_command(), str(sc), "--out", str(out), "--quiet"]
    p = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True, env=env)
    try:
        assert _wait_for(lambda: bool(_staging(tmp_path))), "the run never started staging"
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=60)
    finally:
        p.kill()
    assert p.returncode == 143
    assert err.splitlines() == ["error: interrupted by SIGTERM (no output written)"]
    assert listing(tmp_path) == ["scen.toml", "tmpdir"]
    assert listing(tmpdir) == []


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="signals as on Linux")
@pytest.mark.parametrize("prefix", [".aquasim-trace.tmp-", ".res.tmp-"], ids=["trace scratch", "output staging"])
def test_sigterm_just_after_a_folder_is_made_leaves_none(tmp_path, monkeypatch, capsys, prefix):
    """A SIGTERM arriving the instant the run's trace scratch folder or its output's staging
    folder exists (here: sent from inside its mkdir) finds the folder already recorded by what
    removes it: none is left (before, one arriving between its making and that record left
    it, as loaded machines showed in test_sigterm_to_a_run, once for each folder)."""
    from aquasim_py.outdir import SCRATCH_PREFIX

    assert prefix == SCRATCH_PREFIX or prefix.startswith(".res")
    sc = scenario(tmp_path)
    tmpdir = tmp_path / "tmpdir"
    tmpdir.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmpdir))
    mkdir = os.mkdir  # what Path.mkdir and tempfile.mkdtemp both call

    def made_then_signalled(path: Any, *args: Any, **kwargs: Any) -> None:
        mkdir(path, *args, **kwargs)
        if os.path.basename(path).startswith(prefix):
            os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(os, "mkdir", made_then_signalled)
    assert cli.main([str(sc), "--out", str(tmp_path / "res"), "--quiet"]) == 143
    assert capsys.readouterr().err.splitlines() == ["error: interrupted by SIGTERM (no output written)"]
    assert listing(tmpdir) == []
    assert listing(tmp_path) == ["scen.toml", "tmpdir"]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="signals as on Linux")
def test_a_sigterm_whose_exception_is_swallowed_still_writes_nothing(tmp_path, monkeypatch, capsys):
    """The handler's exception can be lost on its way out: raised while a finalizer (``__del__``,
    a weakref callback) runs, it is only printed ("Exception ignored in ..."), and the handler
    already ignores further signals, so the run goes on to its end (a test_sigterm_to_a_run once
    ended with exit 0 and its outputs in place). The interruption still counts: exit 143, no
    output, no staging folder."""
    from aquasim_py import runner

    sc = scenario(tmp_path)
    real = runner._run

    class SignalledInAFinalizer:
        def __del__(self) -> None:
            os.kill(os.getpid(), signal.SIGTERM)  # the handler runs in here: its raise is lost
            sum(range(10))  # a few bytecodes, where a pending signal's handler runs at the latest

    def run(sim: Any, sc: Any, progress: Any) -> float:
        SignalledInAFinalizer()  # made and finalized at once
        return real(sim, sc, progress)

    monkeypatch.setattr(runner, "_run", run)
    lost: list[Any] = []  # what Python reports of an exception it cannot raise
    monkeypatch.setattr(sys, "unraisablehook", lost.append)
    assert cli.main([str(sc), "--out", str(tmp_path / "res"), "--quiet"]) == 143
    assert [type(u.exc_value).__name__ for u in lost] == ["Interrupted"]  # indeed swallowed
    assert capsys.readouterr().err.splitlines() == ["error: interrupted by SIGTERM (no output written)"]
    assert listing(tmp_path) == ["scen.toml"]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="signals and /proc as on Linux")
def test_sigkill_of_a_sweep_parent_leaves_no_worker_and_no_stale_folder(tmp_path):
    sc = scenario(tmp_path, duration=LONG, extra=SWEEP)
    out = tmp_path / "sw"
    cmd = [*_command(), "sweep", str(sc), "--out", str(out), "--quiet", "--workers", "2"]
    p = subprocess.Popen(cmd, stderr=subprocess.DEVNULL)
    workers: list[int] = []
    try:
        assert _wait_for(lambda: len(_children(p.pid)) >= 2), "the sweep never started its workers"
        workers = _children(p.pid)
        p.kill()
        p.wait(timeout=10)
        assert _wait_for(lambda: not any(_alive(w) for w in workers), timeout=5.0), "orphan workers"
    finally:
        for w in workers:
            if _alive(w):
                os.kill(w, signal.SIGKILL)
    # a sweep writes into its directory as runs finish (resumable): what SIGKILL leaves is
    # the tool's own directory, which the next sweep there takes over without --overwrite
    assert (out / ".aquasim-output.json").is_file()
    (tmp_path / ".unrelated.tmp-zzz").mkdir()  # no marker: not ours, never touched
    quick = [str(sc), "--out", str(out), "--quiet", "--set", "simulation.duration_s=5", "--workers", "1"]
    assert cli.main(["sweep", *quick]) == 0
    assert sorted(p.name for p in _staging(tmp_path)) == [".unrelated.tmp-zzz"]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="signals and /proc as on Linux")
def test_sigkill_of_a_run_leaves_nothing_after_the_next_run(tmp_path, monkeypatch):
    """A SIGKILLed run cannot clean up: its staging folder and its trace scratch folder (in
    TMPDIR) stay behind, and the next run removes both."""
    tmpdir = tmp_path / "tmpdir"
    tmpdir.mkdir()
    sc = scenario(tmp_path, duration=LONG)
    out = tmp_path / "res"
    env = {**os.environ, "TMPDIR": str(tmpdir)}
    p = subprocess.Popen([*_command(), str(sc), "--out", str(out), "--quiet"], env=env, stderr=subprocess.DEVNULL)
    try:
        # marked, not only made: a kill between the two leaves an unmarked folder that the next
        # run keeps for a minute (outdir.scratch_dir), which a slow start on a loaded machine hits
        assert _wait_for(lambda: _marked(tmp_path) and _marked(tmpdir)), "the run never started"
    finally:
        p.kill()
        p.wait(timeout=10)
    assert len(_staging(tmp_path)) == 1 and len(_staging(tmpdir)) == 1  # what the kill left
    monkeypatch.setattr(tempfile, "tempdir", str(tmpdir))
    assert run_quick(sc, out) == 0
    assert _staging(tmp_path) == [] and _staging(tmpdir) == []
    assert (out / "estimates.csv").is_file()


def run_quick(sc: Path, out: Path) -> int:
    return cli.main([str(sc), "--out", str(out), "--quiet", "--set", "simulation.duration_s=5"])


@pytest.mark.slow  # ~3 process start-ups; the handler and the worker clean-up are also covered above
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="signals and /proc as on Linux")
def test_sigterm_to_a_sweep(tmp_path):
    sc = scenario(tmp_path, duration=LONG, extra=SWEEP)
    cmd = [*_command(), "sweep", str(sc), "--out", str(tmp_path / "sw"), "--quiet", "--workers", "2"]
    p = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True)
    workers: list[int] = []
    try:
        assert _wait_for(lambda: len(_children(p.pid)) >= 2), "the sweep never started its workers"
        workers = _children(p.pid)
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=60)
    finally:
        p.kill()
    assert p.returncode == 143
    out = tmp_path / "sw"
    assert err.splitlines() == [f"error: interrupted by SIGTERM: 0 of 2 runs saved in {out}; finish with --resume"]
    assert _wait_for(lambda: not any(_alive(w) for w in workers), timeout=5.0)
    # a resumable sweep directory, without a row; nothing else written
    assert listing(tmp_path) == ["scen.toml", "sw"]
    assert not (out / "sweep.csv").exists() or len((out / "sweep.csv").read_text().splitlines()) <= 1


def test_scratch_dir_removes_only_what_a_killed_run_left(tmp_path, monkeypatch):
    """A run killed between making its trace scratch folder and marking it leaves it empty:
    the next one removes such a folder once it is a minute old, and nothing else."""
    from aquasim_py.outdir import SCRATCH_PREFIX, scratch_dir

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    old, fresh, full = (tmp_path / f"{SCRATCH_PREFIX}{n}" for n in ("old", "fresh", "full"))
    for d in (old, fresh, full):
        d.mkdir()
    (full / "x.csv").write_text("someone's")
    for d in (old, full):
        os.utime(d, (time.time() - 120, time.time() - 120))
    mine = scratch_dir()
    assert (mine / STAGING_MARKER).is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([fresh.name, full.name, mine.name])


def test_clean_stale_keeps_live_and_foreign(tmp_path):
    live = tmp_path / ".a.tmp-live"
    live.mkdir()
    (live / STAGING_MARKER).write_text(json.dumps({"pid": os.getpid(), "host": os.uname().nodename}))
    foreign = tmp_path / ".b.tmp-x"
    foreign.mkdir()
    (foreign / "data").write_text("x")
    assert clean_stale(tmp_path) == []
    assert listing(tmp_path) == [".a.tmp-live", ".b.tmp-x"]


@pytest.mark.parametrize(("sig", "rc"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_signal_in_process_exit_status_and_no_leftovers(tmp_path, capsys, monkeypatch, sig, rc):
    from aquasim_py import kernel

    def interrupted(self, until, progress=None):
        os.kill(os.getpid(), sig)
        time.sleep(5.0)  # the handler raises here
        raise AssertionError("signal not handled")

    monkeypatch.setattr(kernel.Simulation, "run", interrupted)
    sc = scenario(tmp_path)
    out = tmp_path / "new" / "res"
    got, err = run(capsys, sc, "--out", out, "--quiet")
    assert got == rc
    assert err.splitlines() == [f"error: interrupted by {sig.name} (no output written)"]
    assert listing(tmp_path) == ["scen.toml"]
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL  # the handlers are put back


def test_the_temporary_directory_is_found_before_signals_are_handled(tmp_path, monkeypatch):
    """tempfile finds TMPDIR on first use by writing and removing a probe file with a bare
    8-letter name; a SIGTERM handled in between left that file behind (test_sigterm_to_a_run,
    once in CI). The CLI finds it before its handlers are installed."""
    from aquasim_py.cli import _interruptible

    monkeypatch.setattr(tempfile, "tempdir", None)
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    seen = []
    real = signal.signal

    def installing(signum: int, handler: Any) -> Any:
        seen.append(tempfile.tempdir)
        return real(signum, handler)

    monkeypatch.setattr(signal, "signal", installing)
    with _interruptible():
        pass
    assert seen and all(d == str(tmp_path) for d in seen)
