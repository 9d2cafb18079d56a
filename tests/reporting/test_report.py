"""Reports: valid PNG plots of sensible size and one report.html that embeds each of them,
for a run (ITMTL: positions, estimates, clocks, packets), an STVF run and a sweep."""

from __future__ import annotations

import base64
import re
import struct
import tomllib
from pathlib import Path

import pytest

from aquasim_py import cli

ROOT = Path(__file__).resolve().parents[2]

SWEEP = """\
[simulation]
duration_s = 20.0
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
count = 2
protocol = "beacon"
placement = { kind = "uniform" }

[sweep]
runs = 2
grid = { "channel.jitter_std_s" = [0.0, 1e-3] }
"""


def _png_size(data: bytes) -> tuple[int, int]:
    """(width, height) from a PNG's IHDR chunk; fails unless the bytes are a PNG."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
    assert data[12:16] == b"IHDR"
    w, h = struct.unpack(">II", data[16:24])
    return int(w), int(h)


def _check(directory: Path, expect: set[str]) -> None:
    html = (directory / "report.html").read_text()
    pngs = {p.name: p for p in directory.glob("*.png")}
    assert expect <= set(pngs), f"missing plots: {sorted(expect - set(pngs))}"
    embedded = re.findall(r'src="data:image/png;base64,([^"]+)"', html)
    assert len(embedded) == len(pngs)
    for name, p in pngs.items():
        data = p.read_bytes()
        w, h = _png_size(data)
        assert 400 <= w <= 2000 and 300 <= h <= 2000, (name, w, h)
        assert base64.b64encode(data).decode() in embedded, f"{name} is not embedded in report.html"
        assert f"<figcaption>{name}</figcaption>" in html


def _one_run(name: str, variant: str) -> list[str]:
    """CLI arguments for one run of a shipped scenario (its ``variant`` if it declares variants)."""
    path = ROOT / "scenarios" / f"{name}.toml"
    pick = ["--variant", variant] if "variants" in tomllib.loads(path.read_text()) else []
    return [str(path), *pick, "--quiet"]


def test_run_report_via_flag(tmp_path: Path) -> None:
    out = tmp_path / "itmtl"
    args = [*_one_run("itmtl", "itmtl"), "--out", str(out), "--report"]
    assert cli.main([*args, "--set", "simulation.duration_s=90"]) == 0
    _check(out, {"map.png", "error_vs_time.png", "sync_vs_time.png", "error_cdf.png", "packets.png"})
    html = (out / "report.html").read_text()
    assert ">localization</th>" in html and "rmse (m)" in html and "Resolved scenario" in html


def test_report_command_on_a_stvf_run_and_a_sweep(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "stvf"
    args = [*_one_run("stvf_quick", "stvf"), "--out", str(run)]
    assert cli.main([*args, "--set", "simulation.duration_s=5"]) == 0
    assert cli.main(["report", str(run)]) == 0
    _check(run, {"map.png", "error_vs_time.png", "error_cdf.png"})

    scen = tmp_path / "sw.toml"
    scen.write_text(SWEEP)
    sw = tmp_path / "sweep"
    assert cli.main(["sweep", str(scen), "--workers", "1", "--quiet", "--out", str(sw), "--report"]) == 0
    _check(sw, set())
    assert cli.main(["report", str(sw)]) == 0  # the command gives the same files again
    _check(sw, set())
    assert any(p.name.startswith("sweep_") for p in sw.glob("*.png"))
    assert "report:" in capsys.readouterr().out


def test_report_of_a_directory_that_is_no_output_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert cli.main(["report", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "neither a run" in err[0]


def test_report_into_a_users_directory_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = tmp_path / "b"
    scen = tmp_path / "sw.toml"
    scen.write_text(SWEEP.split("[sweep]")[0])
    assert cli.main([str(scen), "--quiet", "--out", str(run)]) == 0
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "map.png").write_text("my own file")
    assert cli.main(["report", str(run), "--out", str(mine)]) == 2
    assert (mine / "map.png").read_text() == "my own file"
    assert capsys.readouterr().err.strip().startswith("error: --out ")


def test_report_files_join_the_run_manifest(tmp_path: Path) -> None:
    """A later run into the same directory replaces the plots like the rest of its output."""
    import json

    scen = tmp_path / "sw.toml"
    scen.write_text(SWEEP.split("[sweep]")[0])
    run = tmp_path / "r"
    assert cli.main([str(scen), "--quiet", "--out", str(run), "--report"]) == 0
    listed = json.loads((run / ".aquasim-output.json").read_text())["files"]
    assert "report.html" in listed and "map.png" in listed
