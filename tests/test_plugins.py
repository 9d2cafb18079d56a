"""Plug-ins without packaging: protocol = "./file.py:Class" or "module:Class" (issue 35 item 2)."""

from __future__ import annotations

import csv
import json
import re
import shutil
import textwrap
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

import pytest
from console_table import assert_printed

import aquasim_py
from aquasim_py import cli, plugins, registry, scenario, sweep

DOC = Path(__file__).resolve().parents[1] / "docs" / "plugins.md"


def _template(name: str) -> str:
    """The code block under ``<!-- plugin-template: NAME -->`` in docs/plugins.md."""
    text = DOC.read_text(encoding="utf-8")
    marker = f"<!-- plugin-template: {name} -->"
    assert marker in text, f"docs/plugins.md lost {marker}"
    m = re.search(r"```\w+\n(.*?)```", text[text.index(marker) :], re.S)
    assert m is not None
    return m.group(1)


@pytest.fixture
def project(tmp_path: Path) -> Path:
    """The docs' template, copied as a user would: myproto.py beside scenario.toml."""
    d = tmp_path / "exp"
    d.mkdir()
    (d / "myproto.py").write_text(_template("myproto.py"))
    (d / "scenario.toml").write_text(_template("scenario.toml"))
    return d


def test_the_docs_template_runs_through_the_cli_from_elsewhere(project, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)  # not the scenario's folder: the path is relative to the scenario
    assert cli.main([str(project / "scenario.toml"), "--out", str(tmp_path / "out")]) == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    m = summary["metrics"]
    # three listeners, beacons every 10 s for 120 s: a fix per beacon once three anchors are heard
    assert m["my_toa.fixes"] >= 3 * 9
    assert m["my_toa.fixes"] == m["localization.estimates"]
    assert m["localization.rmse_m"] < 1.0  # 0.1 m depth noise, drift between beacons
    assert summary["scenario"]["nodes"][0]["protocol"] == "./myproto.py:MyNode"  # as written: portable
    assert_printed(capsys.readouterr().out, "my_toa.median_error_m", m["my_toa.median_error_m"])


def test_run_scenario_and_the_nodes_table_name(project, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    res = aquasim_py.run_scenario(project / "scenario.toml", overrides={"simulation.duration_s": 40.0})
    assert set(res.tables["nodes"]["protocol"]) == {"my_toa"}
    assert res.metrics["my_toa.fixes"] > 0
    # the class is found again by the name its trace rows carry (metrics recomputed from files)
    assert registry.get("my_toa") is registry.get("./myproto.py:MyNode", base=project)


def test_module_form_from_the_python_path(project, monkeypatch, tmp_path):
    monkeypatch.syspath_prepend(str(project))
    monkeypatch.delitem(__import__("sys").modules, "myproto", raising=False)
    res = aquasim_py.run_scenario(
        project / "scenario.toml",
        overrides={"nodes.0.protocol": "myproto:MyNode", "nodes.1.protocol": "myproto:MyNode"},
    )
    assert res.metrics["my_toa.fixes"] > 0
    assert registry.get("myproto:MyNode").__module__ == "myproto"


def test_a_changed_file_is_read_again(project):
    spec = "./myproto.py:MyNode"
    first = registry.get(spec, base=project)
    assert registry.get(spec, base=project) is first  # unchanged: the same class
    path = project / "myproto.py"
    path.write_text(path.read_text().replace('"my_toa"', '"my_toa2"'))
    assert registry.get(spec, base=project).name == "my_toa2"


@pytest.mark.parametrize(
    ("spec", "text", "problem"),
    [
        ("./missing.py:MyNode", None, "no file {dir}/missing.py (a path is relative to the scenario file)"),
        ("./p.py:Nope", "class MyNode: pass\n", "file ./p.py has no 'Nope' (classes there: MyNode)"),
        (
            "./p.py:MyNode",
            "raise RuntimeError('half written')\n",
            "{dir}/p.py failed to import (RuntimeError: half written)",
        ),
        ("./p.py:MyNode", "class MyNode: pass\n", "MyNode is not a subclass of aquasim_py.node.Node"),
        (
            "./p.py:MyNode",
            "from aquasim_py.node import Node\nclass MyNode(Node): pass\n",
            "MyNode needs a `name` of its own (its metrics and trace rows carry it)",
        ),
        (
            "./p.py:MyNode",
            "from aquasim_protocols.beacon import BeaconNode\nclass MyNode(BeaconNode): pass\n",
            "its name 'beacon' is the registered aquasim_protocols.beacon.node.BeaconNode's; give the class another `name`",
        ),
        ("nosuchmodule_xyz:MyNode", None, "no module 'nosuchmodule_xyz' on the Python path"),
    ],
)
def test_a_bad_plugin_is_one_line_naming_the_key(project, capsys, spec, text, problem):
    if text is not None:
        (project / "p.py").write_text(text)
    scen = project / "scenario.toml"
    scen.write_text(scen.read_text().replace('protocol = "./myproto.py:MyNode"', f'protocol = "{spec}"', 1))
    assert cli.main([str(scen), "--out", str(project / "out")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {scen}: nodes[0].protocol: protocol '{spec}': ")
    assert problem.format(dir=project) in err and err.count("\n") == 1
    assert not (project / "out").exists()


def test_an_unknown_name_says_how_to_add_one(project, capsys):
    assert cli.main([str(project / "scenario.toml"), "--set", 'nodes.0.protocol="owtt"']) == 2
    err = capsys.readouterr().err
    assert "unknown protocol 'owtt' (available: beacon, " in err
    assert 'protocol = "./myproto.py:MyNode" (a file, relative to the scenario)' in err
    assert '"mymodule:MyNode" (an importable module); see docs/plugins.md' in err


SWEEP = """
[sweep]
runs = 2
grid = { "nodes.0.params.period_s" = [10.0, 15.0] }
"""


def test_a_sweep_on_two_worker_processes_gives_the_serial_rows(project, tmp_path):
    scen = project / "scenario.toml"
    scen.write_text(scen.read_text() + SWEEP)
    a, b = tmp_path / "w1", tmp_path / "w2"
    assert cli.main(["sweep", str(scen), "--workers", "1", "--out", str(a), "--quiet"]) == 0
    assert cli.main(["sweep", str(scen), "--workers", "2", "--out", str(b), "--quiet"]) == 0
    assert (a / "sweep.csv").read_bytes() == (b / "sweep.csv").read_bytes()
    with open(a / "sweep.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 4 and all(r["error"] == "" and int(r["my_toa.fixes"]) > 0 for r in rows)


def _run_elsewhere(args: tuple) -> dict:
    """A fresh interpreter (spawned: nothing inherited) with another working directory and
    without the plug-in's file, as a Dask worker on another machine."""
    import os

    cwd, base, path, job, sources = args
    os.chdir(cwd)
    return sweep.run_job(base, path, job, None, sources)


def test_a_file_plugin_travels_with_the_jobs(project, tmp_path):
    scen = project / "scenario.toml"
    scen.write_text(scen.read_text() + SWEEP)
    sc = scenario.load(scen)
    jobs = sweep.plan(sc)[:1]
    start = sweep.bases(sc, jobs)
    sources = sweep.plugin_sources(start, str(scen), jobs)
    assert sources == {str(project / "myproto.py"): (project / "myproto.py").read_text()}
    expected = sweep.run_job(start[None], str(scen), jobs[0], None, sources)
    moved = tmp_path / "moved"
    shutil.move(project, moved)  # the worker has no file at the scenario's path
    elsewhere = tmp_path / "worker"
    elsewhere.mkdir()
    with ProcessPoolExecutor(1, mp_context=get_context("spawn")) as pool:
        bare = pool.submit(_run_elsewhere, (str(elsewhere), start[None], str(scen), jobs[0], None)).result()
        row = pool.submit(_run_elsewhere, (str(elsewhere), start[None], str(scen), jobs[0], sources)).result()
    assert row["error"] is None and row == expected
    assert "no file" in bare["error"]  # without the text the worker could not have run it


def test_spec_syntax():
    assert plugins.is_spec("./a.py:B") and plugins.is_spec("pkg.mod:Cls") and plugins.is_spec("C:\\x\\a.py:B")
    assert not plugins.is_spec("beacon") and not plugins.is_spec(":B") and not plugins.is_spec("a:")
    with pytest.raises(plugins.PluginError, match="'1x' is not a class name"):
        plugins.load("./a.py:1x")


def test_a_plugin_file_shadows_no_module(tmp_path):
    (tmp_path / "json.py").write_text(
        textwrap.dedent("""
        from pydantic import BaseModel
        from aquasim_py.node import Node

        class J(Node):
            name = "json_named_file"
            class Params(BaseModel):
                pass
        """)
    )
    cls = registry.get("./json.py:J", base=tmp_path)
    assert cls.__module__.startswith("aquasim_plugin_json_") and json.dumps([1]) == "[1]"
