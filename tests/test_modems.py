"""``aquasim-py modems``, the presets as data, and the scenario keys of the physical layer,
presets and energy: a preset fills the keys the file does not give, a run counts energy, and
bad input gets one line naming the key (exit 2, nothing written)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from test_cli import SCENARIO, assert_user_error, run

from aquasim_py import scenario
from aquasim_py.channel.modem_presets import FIELDS, PRESETS, REFERENCES


@pytest.fixture
def scen(tmp_path: Path) -> Path:
    p = tmp_path / "scen.toml"
    p.write_text(SCENARIO)
    return p


def test_modems_lists_every_preset_with_figures_and_sources(capsys) -> None:
    rc, out, err = run(capsys, "modems")
    assert rc == 0 and err == ""
    for name, p in PRESETS.items():
        assert f"{name}: {p.title}" in out
    for key in FIELDS:  # every figure, each with its source in brackets
        assert out.count(f"  {key} ") >= len([p for p in PRESETS.values() if key in p.sources])
    assert "references:" in out and "[evologics-1834]" in out
    rc, out, _ = run(capsys, "modems", "subnero_m25m", "--json")
    doc = json.loads(out)
    assert rc == 0 and [p["name"] for p in doc["presets"]] == ["subnero_m25m"]
    figs = doc["presets"][0]["figures"]
    assert figs["source_level_db"] == {"value": 185.0, "unit": "dB re 1 uPa @ 1 m", "source": "subnero-silver"}
    assert set(doc["references"]) <= set(REFERENCES)


def test_modems_unknown_name_is_one_line(capsys) -> None:
    rc, out, err = run(capsys, "modems", "whoi")
    assert rc == 2 and out == "" and len(err.splitlines()) == 1 and "unknown modem 'whoi'" in err


def test_every_preset_figure_has_a_source() -> None:
    for p in PRESETS.values():
        for key in FIELDS:
            if key == "modulation_order" and p.modulation != "mfsk":
                continue
            src = p.sources[key]
            assert src.partition(": ")[0] in REFERENCES or src.startswith("assumed: "), (p.name, key)


def test_a_preset_fills_the_keys_the_file_does_not_give(scen: Path) -> None:
    sc = scenario.load(scen, overrides=['channel.modem="evologics_s2cr_18_34"', "channel.bitrate_bps=9000"])
    ch = sc.to_dict()["channel"]
    p = PRESETS["evologics_s2cr_18_34"]
    assert ch["bitrate_bps"] == 9000.0  # given: kept
    assert ch["frequency_khz"] == p.frequency_khz and ch["tx_power_w"] == p.tx_power_w
    assert ch["max_range_m"] == 3000.0  # not a preset key
    # the resolved scenario loads back to itself
    assert scenario.load_dict(sc.to_dict(), scen).to_dict() == sc.to_dict()


def test_a_scenario_without_the_new_keys_resolves_as_before(scen: Path) -> None:
    ch = scenario.load(scen).to_dict()["channel"]
    assert not {"modem", "reception", "tx_power_w", "overhead_s", "lock"} & set(ch)
    assert all("battery" not in g for g in scenario.load(scen).to_dict()["nodes"])


def test_a_run_with_a_preset_and_batteries_counts_energy(scen: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "out"
    rc, _, err = run(
        capsys,
        scen,
        "--out",
        out,
        "--quiet",
        "--set",
        'channel.modem="whoi_mm2_psk"',
        "--set",
        'channel.reception="sinr"',
        "--set",
        "nodes.1.battery={capacity_j=100.0}",
    )
    assert rc == 0, err
    m = json.loads((out / "summary.json").read_text())["metrics"]
    assert m["energy.total_j"] > 0.0 and m["energy.per_node_j"] > 0.0
    energy = (out / "energy.csv").read_text().splitlines()
    assert energy[0].startswith("time,node,energy_j") and len(energy) == 1 + 7


@pytest.mark.parametrize(
    "overrides, key, problem",
    [
        (['channel.modem="nope"'], "channel.modem", r"unknown modem 'nope'"),
        (["channel.tx_power_w=-2.0"], "channel.tx_power_w", r"must be >= 0"),
        (["nodes.0.battery={}"], "nodes[0].battery.capacity_j", r"required key missing"),
        (["nodes.0.battery={capacity_j=-5.0}"], "nodes[0].battery.capacity_j", r"must be > 0"),
        (["nodes.0.battery={capacity_j=50.0}"], "nodes[0].battery", r"needs the modem's power"),
        (["channel.idle_power_w=0.1"], "channel.tx_power_w", r"give all four"),
        (['channel.reception="maybe"'], "channel.reception", r"must be one of"),
        (['channel.modulation="table"'], "channel.per_table", r"needs per_table"),
        (['channel.modulation="mfsk"', "channel.modulation_order=6"], "channel.modulation_order", r"power of 2"),
    ],
)
def test_bad_phy_and_energy_input_is_one_line(
    scen: Path, tmp_path: Path, capsys, overrides: list[str], key: str, problem: str
) -> None:
    out = tmp_path / "out"
    sets = [a for o in overrides for a in ("--set", o)]
    rc, _, err = run(capsys, scen, "--out", out, "--quiet", *sets)
    assert_user_error(rc, err, str(scen), key, problem, out)
