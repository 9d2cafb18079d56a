"""The tutorial's plug-in protocol (docs/tutorials/files/twr.py) does what its page says.

The docs build runs the tutorial itself; this keeps its claims in the default suite: the
protocol runs from its scenario file with nothing installed, the sensors' clock offsets do not
enter two-way ranges, and what is left is the sound speed the ranges assume.
"""

from __future__ import annotations

from pathlib import Path

import aquasim_py

SCENARIO = Path(__file__).resolve().parents[1] / "docs" / "tutorials" / "files" / "twr.toml"


def run(speed: float) -> dict[str, float]:
    overrides = {"simulation.duration_s": 300.0, "nodes.1.params.sound_speed_mps": speed}
    return aquasim_py.run_scenario(SCENARIO, overrides=overrides).metrics


def test_two_way_ranges_carry_the_sound_speed_not_the_clocks() -> None:
    slow, mean = run(1500.0), run(1501.2)
    # one exchange per sensor per 20 s period, sensors in their own slots: almost every poll answered
    assert slow["twr.ranges"] >= 0.9 * 6 * 300 / 20
    # the clocks' offsets (1 ms std, 1.5 m) would spread the errors over metres; assuming the
    # surface speed leaves every range short by ~0.08 % of ~1.5 km, about a metre
    assert -1.6 < slow["twr.range_error_mean_m"] < -0.6
    # the mean speed of the water between the nodes' depths leaves decimetres
    assert abs(mean["twr.range_error_mean_m"]) < 0.2
    assert mean["twr.range_rmse_m"] < 0.4
