"""Reports: PNG plots and one self-contained ``report.html`` from a run's, a variants run's or
a sweep's output.

Everything is drawn from what the run wrote (trace tables, ``summary.json``, ``variants.csv``,
``sweep.csv``), so the same call serves ``aquasim-py report DIR`` long after the run,
``--report`` at the end of one, and a notebook. matplotlib runs on its non-interactive Agg
backend (:mod:`aquasim_py.reporting.figures`); nothing opens a window.

Run directory (``summary.json`` and the trace tables):

- ``map.png``: nodes by role, the links packets were heard on, true and estimated trajectories;
- ``error_vs_time.png``: localization error of each node over time;
- ``sync_vs_time.png``: clock error (estimated minus true time) of each node over time;
- ``error_cdf.png``: empirical CDF of the localization error;
- ``packets.png``: packet outcomes (received, and each drop reason) per time bin;
- ``environment.png`` (a range-dependent environment): the sound-speed section and floor under
  one link with its eigenrays (:mod:`aquasim_py.reporting.environment`);
- a tracker's tracks (MSWPF, SVL-PF, Ramezani tracking) scored by Stone Soup, OSPA and GOSPA
  beside our RMSE (:mod:`aquasim_py.tracks`; the ``stonesoup`` extra).

Variants run (``variants.csv`` and a run directory per variant): the variants side by side
(:mod:`aquasim_py.reporting.variants`), each variant's own report in its directory.

Sweep directory (``sweep.csv``): each metric against each swept value, a line per
combination of the other grid keys (:mod:`aquasim_py.reporting.sweep`), and the table per grid
point with n and the interval; with network metrics, throughput against offered load beside
the ALOHA curves (:mod:`aquasim_py.reporting.network`).

A plot whose table is missing or empty is skipped (a beacon run has no ``clocks``).
"""

from __future__ import annotations

import base64
import html
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from aquasim_py import trace
from aquasim_py.reporting import sweep as sweep_report
from aquasim_py.reporting import tables
from aquasim_py.reporting.figures import plt, save_figure

__all__ = ["ReportError", "report_run", "report_sweep", "write_report"]

_ROLE_STYLE = {
    "buoy": ("#1f77b4", "^"),
    "anchor": ("#d62728", "s"),
    "ordinary": ("#2ca02c", "o"),
    "target": ("#ff7f0e", "*"),
    "sink": ("#9467bd", "D"),
}


class ReportError(ValueError):
    """The directory holds neither a run's nor a sweep's output."""


def _plot_map(t: Mapping[str, pd.DataFrame], out: Path) -> Path | None:
    pos = t.get("positions")
    nodes = t.get("nodes")
    if pos is None or len(pos) == 0:
        return None
    fig, ax = plt.subplots(figsize=(7.0, 6.0))
    first = pos.sort_values("time").groupby("node").first()
    pk = t.get("packets")
    if pk is not None and len(pk):
        heard = pk[pk["event"] == "rx"][["src", "node"]].drop_duplicates()
        heard = heard[heard["src"].isin(first.index) & heard["node"].isin(first.index)]
        for s, r in heard.itertuples(index=False):
            ax.plot(*zip(first.loc[s, ["x", "y"]], first.loc[r, ["x", "y"]]), color="0.85", lw=0.6, zorder=0)
    for _node, tr in pos.groupby("node"):
        ax.plot(tr["x"], tr["y"], color="0.4", lw=0.8, zorder=1)
    est = t.get("estimates")
    if est is not None and len(est):
        for i, (_node, e) in enumerate(est.groupby("node")):
            ax.plot(
                e["x"],
                e["y"],
                ".",
                ms=3,
                color="tab:purple",
                alpha=0.6,
                zorder=2,
                label="estimates" if i == 0 else None,
            )
    roles = nodes.set_index("node")["role"].astype(str) if nodes is not None and len(nodes) else None
    for role, (color, marker) in _ROLE_STYLE.items():
        ids = first.index if roles is None else [n for n in first.index if roles.get(n) == role]
        if roles is None and role != "ordinary":
            continue
        if len(ids):
            ax.scatter(first.loc[ids, "x"], first.loc[ids, "y"], c=color, marker=marker, s=40, zorder=3, label=role)
    ax.plot([], [], color="0.4", lw=0.8, label="true trajectory")
    if pk is not None and len(pk):
        ax.plot([], [], color="0.85", lw=0.6, label="link heard")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title("Network map (start positions)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=8, loc="best")
    return save_figure(fig, out / "map.png")


def _per_node_lines(df: pd.DataFrame, y: pd.Series, ax: Any) -> None:
    for node, g in df.assign(_y=y).groupby("node"):
        ax.plot(g["time"], g["_y"], lw=0.9, label=f"node {node}")
    if df["node"].nunique() <= 12:
        ax.legend(fontsize=7, ncol=2)


def _plot_error_vs_time(t: Mapping[str, pd.DataFrame], out: Path) -> Path | None:
    est = t.get("estimates")
    if est is None or len(est) == 0 or "error" not in est:
        return None
    fig, ax = plt.subplots(figsize=(7.0, 4.0))
    _per_node_lines(est, est["error"], ax)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("localization error (m)")
    ax.set_yscale("log" if (est["error"] > 0).all() and est["error"].max() > 50 * est["error"].min() else "linear")
    ax.set_title("Localization error per node")
    return save_figure(fig, out / "error_vs_time.png")


def _plot_sync(t: Mapping[str, pd.DataFrame], out: Path) -> Path | None:
    clk = t.get("clocks")
    if clk is None or len(clk) == 0 or "error" not in clk:
        return None
    fig, ax = plt.subplots(figsize=(7.0, 4.0))
    err_us = 1e6 * clk["error"].abs()
    _per_node_lines(clk, err_us, ax)
    if (err_us > 0).all():
        ax.set_yscale("log")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("|clock error| (us)")
    ax.set_title("Time-synchronization error per node")
    return save_figure(fig, out / "sync_vs_time.png")


def _plot_cdf(t: Mapping[str, pd.DataFrame], out: Path) -> Path | None:
    est = t.get("estimates")
    if est is None or len(est) == 0 or "error" not in est:
        return None
    e = np.sort(est["error"].to_numpy(dtype=float))
    e = e[np.isfinite(e)]
    if e.size == 0:
        return None
    fig, ax = plt.subplots(figsize=(6.0, 4.0))
    ax.step(e, np.arange(1, e.size + 1) / e.size, where="post")
    for q in (0.5, 0.9):
        v = float(np.quantile(e, q))
        ax.axvline(v, color="0.6", ls=":", lw=0.8)
        ax.text(v, q, f" {int(q * 100)} %: {v:.3g} m", fontsize=8, va="bottom")
    ax.set_xlabel("localization error (m)")
    ax.set_ylabel("fraction of estimates")
    ax.set_ylim(0, 1.02)
    ax.set_title(f"Error CDF ({e.size} estimates)")
    return save_figure(fig, out / "error_cdf.png")


def _plot_packets(t: Mapping[str, pd.DataFrame], out: Path) -> Path | None:
    pk = t.get("packets")
    if pk is None or len(pk) == 0:
        return None
    rows = pk[pk["event"].isin(["rx", "drop"])]
    if len(rows) == 0:
        return None
    outcome = np.where(rows["event"] == "rx", "received", "drop: " + rows["reason"].fillna("").astype(str))
    span = float(rows["time"].max() - rows["time"].min()) or 1.0
    nbins = int(np.clip(span / 10.0, 10, 60))
    edges = np.linspace(float(rows["time"].min()), float(rows["time"].max()) + 1e-9, nbins + 1)
    mids = 0.5 * (edges[:-1] + edges[1:])
    fig, ax = plt.subplots(figsize=(7.0, 4.0))
    bottom = np.zeros(len(mids))
    times = rows["time"].to_numpy(dtype=float)
    for label in sorted(set(outcome), key=lambda o: (o != "received", o)):
        counts = np.histogram(times[outcome == label], edges)[0]
        ax.bar(mids, counts, width=edges[1] - edges[0], bottom=bottom, label=label)
        bottom += counts
    ax.set_xlabel("time (s)")
    ax.set_ylabel("packets per bin")
    ax.set_title(
        f"Packet outcomes ({int(edges[1] - edges[0])} s bins)" if edges[1] - edges[0] >= 1 else "Packet outcomes"
    )
    ax.legend(fontsize=8)
    return save_figure(fig, out / "packets.png")


def report_run(run_dir: str | Path, out: str | Path | None = None) -> list[Path]:
    """The run plots of ``run_dir`` written into ``out`` (default ``run_dir``); returns their paths."""
    run_dir = Path(run_dir)
    out = Path(out) if out is not None else run_dir
    out.mkdir(parents=True, exist_ok=True)
    return _run_plots(trace.load(run_dir), out)


def _run_plots(tables: Mapping[str, pd.DataFrame], out: Path) -> list[Path]:
    plots = (_plot_map, _plot_error_vs_time, _plot_sync, _plot_cdf, _plot_packets)
    return [p for f in plots if (p := f(tables, out)) is not None]


def report_sweep(
    sweep_dir: str | Path, out: str | Path | None = None, metrics: Sequence[str] | None = None
) -> list[Path]:
    """The sweep plots of ``sweep_dir`` (:mod:`aquasim_py.reporting.sweep`) for the metrics the
    shell ``metrics`` patterns select, written into ``out`` (default ``sweep_dir``)."""
    sweep_dir = Path(sweep_dir)
    out = Path(out) if out is not None else sweep_dir
    out.mkdir(parents=True, exist_ok=True)
    data = sweep_report.load(sweep_dir)
    chosen = sweep_report.select(data.metrics, metrics)
    return _network_plots(data, out) + sweep_report.plot_all(data, out, chosen)


def _network_plots(data: sweep_report.SweepData, out: Path) -> list[Path]:
    """A sweep's throughput against offered load with the ALOHA curves, where it has them."""
    from aquasim_py.reporting import network

    p = network.throughput_plot(data, out / "sweep_net_throughput_vs_load.png")
    return [] if p is None else [p]


def _img(path: Path) -> str:
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return f'<figure><img alt="{html.escape(path.stem)}" src="data:image/png;base64,{data}"><figcaption>{html.escape(path.name)}</figcaption></figure>'


_CSS = (
    "body{font-family:sans-serif;max-width:60em;margin:2em auto;color:#222}"
    "img{max-width:100%}figure{margin:1em 0}table{border-collapse:collapse;margin:1em 0}"
    "caption{text-align:left;font-weight:bold;padding:4px 0}"
    "td,th{border:1px solid #ccc;padding:2px 8px;text-align:left;vertical-align:top}"
    "pre{background:#f6f6f6;padding:1em;overflow:auto}"
)


def _run_body(
    directory: Path, out: Path, metrics: Sequence[str] | None, link: tuple[int, int] | None = None
) -> tuple[str, str, list[Path]]:
    from aquasim_py import tracks
    from aquasim_py.reporting import environment as plot_environment

    summary = json.loads((directory / "summary.json").read_text())
    t = trace.load(directory)
    out.mkdir(parents=True, exist_ok=True)
    images = _run_plots(t, out)
    if (env_plot := plot_environment.report_plot(summary, t, out, link)) is not None:
        images.append(env_plot)
    title = f"aquasim-py run: {summary.get('scenario_file', directory.name)}"
    shown = sweep_report.pick(summary.get("metrics", {}), metrics, keep_all=True)
    body = "<h2>Metrics</h2>" + tables.metrics_table(shown, "metrics (units per row)").html()
    body += tracks.report_section(t, summary.get("metrics", {}))
    body += "<h2>Plots</h2>" + "".join(_img(p) for p in images)
    scen = json.dumps(summary.get("scenario", {}), indent=2, sort_keys=True)
    body += f"<h2>Resolved scenario (seed {summary.get('seed')})</h2><pre>{html.escape(scen)}</pre>"
    return title, body, images


def _sweep_body(directory: Path, out: Path, metrics: Sequence[str] | None) -> tuple[str, str, list[Path]]:
    data = sweep_report.load(directory)
    chosen = sweep_report.select(data.metrics, metrics)
    summary = sweep_report.summary(data, chosen)
    images = _network_plots(data, out) + sweep_report.plot_all(data, out, chosen, summary)
    title = f"aquasim-py sweep: {directory.name}"
    failed = f", {data.failed} failed (left out)" if data.failed else ""
    body = f"<p>{len(data.runs)} successful runs{failed}.</p>"
    if chosen:
        table = tables.sweep_table(data, summary, chosen, "per grid point", max_points=10**6)
        body += "<h2>Per grid point</h2>" + table.html()
    if not metrics:
        body += "<p>Packet counts are left out: <code>aquasim-py report DIR --metrics 'packets.*'</code>.</p>"
    body += "<h2>Plots</h2>" + "".join(_img(p) for p in images)
    if (directory / "summary.csv").is_file():
        body += (
            "<details><summary>summary.csv: arithmetic mean, std and Student-t 95 % CI per grid point</summary>"
            + pd.read_csv(directory / "summary.csv").to_html(index=False)
            + "</details>"
        )
    return title, body, images


def _forget_plots(out: Path, prefix: str) -> None:
    """Remove the plots an earlier report wrote under ``out`` (listed in its manifest), so
    that a report with other ``--metrics`` shows only its own."""
    from aquasim_py.outdir import listed_files

    for name in listed_files(out):
        if name.startswith(prefix) and name.endswith(".png") and "/" not in name:
            (out / name).unlink(missing_ok=True)


def write_report(
    directory: str | Path,
    out: str | Path | None = None,
    metrics: Sequence[str] | None = None,
    link: tuple[int, int] | None = None,
) -> Path:
    """Plots and ``report.html`` (images embedded) for a run, a variants run or a sweep
    directory; returns the HTML path. ``metrics``: shell patterns of the metrics to show
    (default: all of a run's; for sweeps and variants all but the packet counts). ``link``:
    (sender, receiver) whose rays a range-dependent run's ``environment.png`` draws (default
    :func:`aquasim_py.reporting.environment.choose_link`).

    Raises :class:`ReportError` when ``directory`` holds none of ``summary.json``,
    ``variants.csv`` or ``sweep.csv``.
    """
    from aquasim_py.reporting import variants as report_variants

    directory = Path(directory)
    out = Path(out) if out is not None else directory
    out.mkdir(parents=True, exist_ok=True)
    if (directory / "summary.json").is_file():
        title, body, _ = _run_body(directory, out, metrics, link)
    elif (directory / "sweep.csv").is_file():
        _forget_plots(out, "sweep_")
        title, body, _ = _sweep_body(directory, out, metrics)
    elif (directory / "variants.csv").is_file():
        title, body = report_variants.body(directory, out, metrics, _img)
    else:
        raise ReportError(
            f"{directory}: neither a run (summary.json), a variants run (variants.csv) nor a sweep (sweep.csv) "
            "output directory"
        )
    page = (
        f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
        f"<style>{_CSS}</style></head><body><h1>{html.escape(title)}</h1>{body}</body></html>\n"
    )
    path = out / "report.html"
    path.write_text(page)
    return path
