"""tools/bench_acceptance.py's scaling figure: the ratio of the largest size's cost per reception
to the smallest's, from the points' medians when every point ran several rounds."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))

import bench_acceptance as ba


def _point(nodes: int, speed: float, us: list[float]) -> dict[str, object]:
    ordered = sorted(us)
    return {
        "nodes": nodes,
        "speed": speed,
        "us_per_reception": ordered[len(us) // 2],  # odd counts here: the median
        "bare_us_per_delivery": 1.0,
        "rounds_us": us,
        "rounds_bare_us": [1.0] * len(us),
    }


def test_scaling_ratio_is_of_the_medians_with_each_rounds_ratio() -> None:
    points = [
        _point(200, 0.0, [1.0, 2.0, 1.5]),
        _point(5000, 0.0, [2.0, 2.5, 3.3]),
        _point(200, 1.0, [2.0]),
        _point(5000, 1.0, [3.0]),
    ]
    static, _, moving, _ = ba.scaling_rows(points)
    assert static["value"] == 2.5 / 1.5
    assert static["unit"] == "x (of the medians of 3 rounds; each round's: 2.00, 1.25, 2.20)"
    assert moving["value"] == 1.5 and moving["unit"] == "x"  # one round: as before
