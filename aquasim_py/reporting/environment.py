"""The environment of a range-dependent run with the rays of one link: a report plot.

``environment.png``: the vertical section through a link's two ends (at the last packet heard
on it: the sender at its send instant, the receiver at the arrival), the sound speed c(range,
depth) as colours, the sea floor, and every eigenray of the link with at most ``max_bounces``
bounces (:func:`aquasim_py.channel.arrivals.arrivals`, each walked by the exact tracer,
:func:`aquasim_py.channel.rangedep.trace_rays`), the one the modem stamped drawn bold; beside
it, the arrivals' levels against their delays.

The link: the caller's (src, dst), else the most heard of the links whose direct path is
blocked (no direct or refracted arrival), else the most heard link. The environment is rebuilt
from the run's resolved scenario, the positions are interpolated in its ``positions`` table.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from aquasim_py.reporting.figures import plt, save_figure

__all__ = ["choose_link", "link_problem", "plot_link", "report_plot"]

_CLASS_COLOURS = {
    "direct": "#1f77b4",
    "refracted": "#17becf",
    "surface": "#2ca02c",
    "bottom": "#8c564b",
    "surface-bottom": "#9467bd",
}


def choose_link(packets: pd.DataFrame) -> tuple[int, int] | None:
    """(src, dst) of the most heard link whose direct path is blocked, else of the most heard
    link; None without receptions."""
    rx = packets[packets["event"] == "rx"]
    if not len(rx):
        return None
    if "direct_tof" in rx:
        blocked = rx[rx["direct_tof"].isna()]
        if len(blocked):
            rx = blocked
    counts = rx.groupby(["src", "node"]).size().sort_values(ascending=False, kind="mergesort")
    src, dst = counts.index[0]
    return int(src), int(dst)


def link_problem(directory: Path, link: tuple[int, int]) -> str | None:
    """Why the run in ``directory`` cannot draw ``link`` (sender, receiver) in its
    environment.png, or None: a node it does not have, the same node twice, or a
    range-independent environment (no environment plot)."""
    import json

    from aquasim_py.scenario import load_dict
    from aquasim_py.scenario.ocean import range_dependent

    src, dst = link
    if src == dst:
        return f"a link joins two nodes, not node {src} with itself"
    summary = json.loads((directory / "summary.json").read_text())
    scen = summary.get("scenario")
    if not isinstance(scen, dict):
        return "summary.json has no resolved scenario"
    sc = load_dict(scen, summary.get("scenario_file"))
    n = sum(int(g.count or 0) for g in sc.nodes)
    missing = [i for i in link if not 0 <= i < n]
    if missing:
        return f"no node {missing[0]} (this run has nodes 0..{n - 1})"
    if not range_dependent(sc):
        return "a range-independent run: environment.png, where a link's rays are drawn, is made only for a range-dependent environment"
    return None


def _position(pos: pd.DataFrame, node: int, t: float) -> np.ndarray:
    g = pos[pos["node"] == node].sort_values("time")
    return np.array([np.interp(t, g["time"], g[c]) for c in "xyz"])


def plot_link(
    env: Any,
    src: np.ndarray,
    dst: np.ndarray,
    out: Path,
    *,
    max_bounces: int = 2,
    frequency_khz: float = 10.0,
    stamped_delay: float | None = None,
    title: str = "",
) -> Path:
    """Draw the section of the link src -> dst ((3,) m) with its eigenrays into ``out``."""
    from aquasim_py.channel import rangedep
    from aquasim_py.channel.arrivals import ArrivalClass, arrivals

    arr = arrivals(env, src, dst, max_bounces=max_bounces, frequency_khz=frequency_khz)
    horiz = dst[:2] - src[:2]
    R = float(np.hypot(*horiz))
    u = horiz / R if R > 0 else np.array([1.0, 0.0])
    pad = 0.05 * max(R, 100.0)
    r = np.linspace(-pad, R + pad, 241)
    x, y = src[0] + r * u[0], src[1] + r * u[1]
    floor = np.asarray(env.depth(x, y), dtype=float)
    zmax = float(np.nanmax(np.where(np.isfinite(floor), floor, np.nan), initial=max(src[2], dst[2]))) * 1.08
    zmax = max(zmax, 1.2 * max(src[2], dst[2]), 10.0)
    z = np.linspace(0.0, zmax, 161)
    c = env.speed(x[None, :], y[None, :], z[:, None])
    c = np.where(z[:, None] <= floor[None, :], c, np.nan)

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11.0, 4.6), gridspec_kw={"width_ratios": [3, 1]})
    mesh = ax.pcolormesh(r, z, c, shading="auto", cmap="viridis")
    fig.colorbar(mesh, ax=ax, label="sound speed (m/s)", pad=0.01)
    if np.isfinite(floor).any():
        ax.fill_between(r, floor, zmax, color="#c2a878", zorder=2, label="sea floor")
    drawn: set[str] = set()
    if arr.delay.size:
        paths, cnt, _sec = rangedep.trace_rays(
            env,
            np.broadcast_to(src, (arr.delay.size, 3)),
            np.broadcast_to(dst, (arr.delay.size, 3)),
            arr.launch_angle,
            max_bounces=max_bounces,
        )
        # the stamped arrival: the one nearest the stamp (the positions are interpolated from
        # samples, so the delays here differ from the run's by a little)
        near = int(np.argmin(np.abs(arr.delay - stamped_delay))) if stamped_delay is not None else -1
        for i in range(arr.delay.size):
            label = ArrivalClass(int(arr.path_class[i])).label
            stamped = i == near and abs(arr.delay[i] - float(stamped_delay or 0.0)) <= 1e-3
            ax.plot(
                paths[i, : cnt[i], 0],
                paths[i, : cnt[i], 1],
                color=_CLASS_COLOURS[label],
                lw=2.4 if stamped else 0.9,
                zorder=4 if stamped else 3,
                label=None if label in drawn else label,
            )
            drawn.add(label)
            bx.stem(
                [arr.delay[i]],
                [arr.level_db[i]],
                linefmt=_CLASS_COLOURS[label],
                markerfmt="o",
                basefmt=" ",
                bottom=float(np.min(arr.level_db)) - 5.0,
            )
        if stamped_delay is not None:
            bx.axvline(stamped_delay, color="k", ls=":", lw=0.8, label="modem stamp")
            bx.legend(fontsize=7, loc="best")
    ax.plot([0.0, R], [src[2], dst[2]], "k--", lw=0.7, zorder=3, label="straight line")
    ax.plot([0.0], [src[2]], "r^", ms=8, zorder=5, label="sender")
    ax.plot([R], [dst[2]], "rv", ms=8, zorder=5, label="receiver")
    ax.set_xlim(r[0], r[-1])
    ax.set_ylim(zmax, 0.0)
    ax.set_xlabel("range along the link (m)")
    ax.set_ylabel("depth (m)")
    ax.set_title(title or "link section and eigenrays", fontsize=10)
    ax.legend(fontsize=7, loc="upper right", ncol=2, framealpha=0.8)
    bx.set_xlabel("delay (s)")
    bx.set_ylabel("level (dB re source at 1 m)")
    bx.set_title(f"{arr.delay.size} arrivals", fontsize=10)
    return save_figure(fig, out)


def report_plot(
    summary: Mapping[str, Any], tables: Mapping[str, pd.DataFrame], out: Path, link: tuple[int, int] | None = None
) -> Path | None:
    """``out/environment.png`` for a run whose resolved scenario (``summary``) has a
    range-dependent environment; None for any other run, or without packets or positions."""
    from aquasim_py.scenario import load_dict
    from aquasim_py.scenario.build import make_ssp
    from aquasim_py.scenario.ocean import depth_profile, make_environment, range_dependent

    scen = summary.get("scenario")
    pk, pos = tables.get("packets"), tables.get("positions")
    if not isinstance(scen, dict) or pk is None or pos is None or not len(pk) or not len(pos):
        return None
    sc = load_dict(scen, summary.get("scenario_file"))
    if not range_dependent(sc):
        return None
    env = make_environment(sc, make_ssp(sc) if depth_profile(sc) else None)
    if env.range_independent:
        return None
    pair = link if link is not None else choose_link(pk)
    if pair is None:
        return None
    s_id, d_id = pair
    rx = pk[(pk["event"] == "rx") & (pk["src"] == s_id) & (pk["node"] == d_id)]
    if len(rx):
        last = rx.iloc[-1]
        t_send = float(pk[(pk["event"] == "tx") & (pk["uid"] == last["uid"])]["time"].iloc[0])
        t_arr, stamp = float(last["time"]), float(last["tof"])
        note = f"node {s_id} -> {d_id} at t = {t_send:.1f} s, stamped {last['path']}"
    else:  # never heard: the ends at the end of the run
        t_send = t_arr = float(pos["time"].max())
        stamp = None
        note = f"node {s_id} -> {d_id} at t = {t_send:.1f} s (never heard)"
    src, dst = _position(pos, s_id, t_send), _position(pos, d_id, t_arr)
    ch = sc.channel
    return plot_link(
        env,
        src,
        dst,
        out / "environment.png",
        max_bounces=ch.max_bounces,
        frequency_khz=ch.frequency_khz,
        stamped_delay=stamp,
        title=note,
    )
