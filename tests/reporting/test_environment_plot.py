"""The environment plot of a range-dependent run's report (aquasim_py.reporting.environment)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from aquasim_py import run_scenario
from aquasim_py.cli import main
from aquasim_py.reporting.environment import choose_link
from aquasim_py.reporting.report import write_report

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"


def test_report_draws_the_environment_of_a_range_dependent_run(tmp_path, capsys) -> None:
    """`aquasim-py report` of a slope run writes environment.png (by default the most heard link
    without a direct path; --link picks another); a range-independent run has none."""
    out = tmp_path / "slope"
    run_scenario(
        SCENARIOS / "slope.toml", variant="itmtl", overrides=["simulation.duration_s=15"], out=out, progress=False
    )
    html = write_report(out)
    assert (out / "environment.png").stat().st_size > 10_000
    assert "environment.png" in html.read_text()
    p = pd.read_csv(out / "packets.csv")
    src, dst = choose_link(p)
    heard = p[(p.event == "rx") & (p.src == src) & (p.node == dst)]
    assert len(heard) and heard.direct_tof.isna().all()  # a blocked link
    (out / "environment.png").unlink()
    assert main(["report", str(out), "--link", "0,6"]) == 0
    assert (out / "environment.png").is_file()
    flat = tmp_path / "flat"
    run_scenario(
        SCENARIOS / "slope_flat.toml", variant="itmtl", overrides=["simulation.duration_s=5"], out=flat, progress=False
    )
    write_report(flat)
    assert not (flat / "environment.png").exists()
    capsys.readouterr()
    # a link the run cannot draw: one line, exit 2, nothing written
    (out / "report.html").unlink()
    for run_dir, link, says in (
        (out, "0,99", "no node 99 (this run has nodes 0..9)"),
        (out, "3,3", "not node 3 with itself"),
        (out, "0,-1", "node ids are >= 0"),
        (flat, "0,6", "a range-independent run"),
    ):
        assert main(["report", str(run_dir), "--link", link]) == 2, link
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith("error: ") and says in err, err
        assert not (out / "report.html").exists()
