"""scenarios/slope.toml (the real-site scenario of issue 34) and its flat twin: in step with each
other and with the bundled sample, and late first-arrival stamps where the direct path is blocked."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
from scipy.integrate import trapezoid  # numpy's own is numpy >= 2 only

from aquasim_py import run_scenario
from aquasim_py.channel.arrival_links import ARRIVAL_FIELDS
from aquasim_py.channel.data import shelfbreak

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"
C_NOMINAL = 1495.0


def test_flat_twin_is_the_same_network_in_the_centre_profile() -> None:
    """The twins differ only in the environment (and the channel's arrival key), and the flat
    profile, which is also every node's believed CTD cast in both, is the sample's column at the
    network's centre (x = 500 m) on its depth nodes, to 0.005 m/s (the files' two decimals)."""
    slope = tomllib.loads((SCENARIOS / "slope.toml").read_text())
    flat = tomllib.loads((SCENARIOS / "slope_flat.toml").read_text())
    for key in ("simulation", "nodes", "variants", "trace"):
        assert slope[key] == flat[key], key
    assert {k: v for k, v in slope["channel"].items() if k != "max_bounces"} == flat["channel"]
    prof = flat["environment"]["sound_speed"]
    depths = np.asarray(prof["depths_m"])
    column = shelfbreak().speed(np.full(depths.size, 500.0), np.zeros(depths.size), depths)
    np.testing.assert_allclose(prof["speeds_mps"], column, rtol=0, atol=0.005)
    np.testing.assert_array_equal(depths, shelfbreak().field.depths[: depths.size])
    params = slope["nodes"][1]["params"]
    assert params["ssp_depths_m"] == prof["depths_m"] and params["ssp_speeds_mps"] == prof["speeds_mps"]


def test_slope_run_stamps_blocked_links_late() -> None:
    """60 s of the ITMTL variant: the packets table carries the arrival columns; some
    receptions have no direct arrival (blocked by the shelf break and the downward-refracting
    summer profile) and are stamped on a reflected one; each stamped on a surface bounce
    exceeds the straight chord's travel time through the true sound-speed field (a quadrature of
    1 / c, no rays) by more than 10 m of range: late first-arrival stamps."""
    res = run_scenario(
        SCENARIOS / "slope.toml",
        variant="itmtl",
        overrides=["simulation.duration_s=60", "trace.position_interval_s=1.0"],
        progress=False,
    )
    p, pos = res.tables["packets"], res.tables["positions"]
    assert set(ARRIVAL_FIELDS) <= set(p.columns)
    rx = p[p.event == "rx"]
    blocked = rx[rx.direct_tof.isna()]
    assert len(blocked) >= 5
    assert set(blocked.path) <= {"surface", "bottom", "surface-bottom"}
    t_send = p[p.event == "tx"].set_index("uid")["time"]

    def at(node: int, t: float) -> np.ndarray:
        g = pos[pos.node == node]
        return np.array([np.interp(t, g.time, g[c]) for c in "xyz"])

    env = shelfbreak()
    u = np.linspace(0.0, 1.0, 4001)
    late = []
    for r in blocked.itertuples():
        s, d = at(r.src, t_send[r.uid]), at(r.node, r.time)
        pts = s + (d - s) * u[:, None]
        chord = trapezoid(1.0 / env.speed(pts[:, 0], pts[:, 1], pts[:, 2]), u) * np.linalg.norm(d - s)
        late.append(C_NOMINAL * (r.tof - chord))
    late = np.asarray(late)
    assert (late > 10.0).sum() >= 2
    # a surface bounce adds tens of metres on every such link (a bottom reflection may be early or
    # late against the chord: it travels in the faster slope water below the cold pool the chord
    # crosses, docs/channel.md "The slope scenario")
    surf = blocked.path.isin(["surface", "surface-bottom"]).to_numpy()
    assert surf.any() and np.all(late[surf] > 10.0)
