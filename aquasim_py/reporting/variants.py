"""The cross-variant report of a variants run (``aquasim-py scenarios/itmtl.toml``): the
variants side by side on one network and seed.

The directory holds ``variants.csv`` and one run directory per variant (each with its own
``summary.json``, trace tables and, from ``aquasim-py report``, its own ``report.html``).
The page shows the comparison table (every metric with its unit, each protocol's own family
aligned, :func:`aquasim_py.reporting.tables.comparison_table`), the protocols' papers beside the run
(``paper.csv``) with the network described, and the distributions of the localization and
clock errors of every variant on one plot each (``variants_error_cdf.png``,
``variants_sync_cdf.png``), with links to each variant's own report.
"""

from __future__ import annotations

import html
import json
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from aquasim_py import trace, tracks
from aquasim_py.reporting import tables
from aquasim_py.reporting.figures import plt, save_figure
from aquasim_py.reporting.sweep import pick

__all__ = ["body", "variant_dirs"]


def variant_dirs(directory: Path) -> dict[str, Path]:
    """Variant name -> its run directory, in the order of ``variants.csv``."""
    order = pd.read_csv(directory / "variants.csv", usecols=["variant"], dtype=str)["variant"].tolist()
    return {v: directory / v for v in order if (directory / v / "summary.json").is_file()}


def _cdf(samples: Mapping[str, np.ndarray], xlabel: str, title: str, path: Path) -> Path | None:
    samples = {k: v[np.isfinite(v)] for k, v in samples.items()}
    samples = {k: v for k, v in samples.items() if v.size}
    if not samples:
        return None
    fig, ax = plt.subplots(figsize=(7.0, 4.5))
    positive = all(v.min() > 0 for v in samples.values())
    for name, v in samples.items():
        v = np.sort(v)
        ax.step(v, np.arange(1, v.size + 1) / v.size, where="post", label=f"{name} (median {np.median(v):.3g})")
    hi = max(v.max() for v in samples.values())
    lo = min(v.min() for v in samples.values())
    if positive and hi > 50 * lo:
        ax.set_xscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("fraction")
    ax.set_ylim(0, 1.02)
    ax.set_title(title)
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.25)
    return save_figure(fig, path)


def _citations(summaries: Mapping[str, dict[str, Any]]) -> tuple[list[str], str | None]:
    """The papers the protocols compare with and the network, from the resolved scenarios
    (None when a scenario no longer loads, e.g. a CTD file moved)."""
    from aquasim_py import scenario
    from aquasim_py.reporting.display import describe_network
    from aquasim_py.runner import citations_of

    classes: list[type] = []
    network = None
    for s in summaries.values():
        try:
            sc = scenario.load_dict(s["scenario"], s.get("scenario_file"))
        except Exception:  # an old or moved run: the table is still shown, unnamed
            continue
        network = network or describe_network(sc)
        classes += [c for c in sc.protocols() if c not in classes]
    return citations_of(classes), network


def _track_scores(scored: Sequence[tuple[str, list[Any]]]) -> str:
    """The trackers' tracks of every variant scored by Stone Soup (:func:`aquasim_py.tracks.scores`)."""
    if not any(found for _, found in scored):
        return ""
    head = "<h2>Tracks scored by Stone Soup, every variant</h2>"
    try:
        frames = [tracks.scores(found).assign(variant=v) for v, found in scored if found]
    except ImportError:
        return head + "<p>OSPA and GOSPA need Stone Soup: <code>pip install 'aquasim-py[stonesoup]'</code>.</p>"
    df = pd.concat(frames, ignore_index=True)
    df = df[["variant", *(c for c in df.columns if c != "variant")]]
    note = (
        f"<p>Time means over every step of each track, c = {tracks.C_M:g} m, p = {tracks.P} "
        "(each variant's own report has the details).</p>"
    )
    return head + df.to_html(index=False, float_format=lambda x: f"{x:.4g}") + note


def body(directory: Path, out: Path, metrics: Sequence[str] | None, img: Callable[[Path], str]) -> tuple[str, str]:
    """The page title and HTML body of the cross-variant report; writes its plots into ``out``."""
    dirs = variant_dirs(directory)
    summaries = {v: json.loads((d / "summary.json").read_text()) for v, d in dirs.items()}
    shown = {v: pick(s.get("metrics", {}), metrics) for v, s in summaries.items()}
    first: dict[str, Any] = next(iter(summaries.values()), {})
    title = f"aquasim-py variants: {first.get('scenario_file', directory.name)} (seed {first.get('seed')})"
    parts = [tables.comparison_table(shown, "the variants side by side (variants.csv)").html()]
    cites, network = _citations(summaries)
    if network:
        parts.insert(0, f"<p>One network and seed: {html.escape(network)}.</p>")
    if (directory / "paper.csv").is_file():
        paper = pd.read_csv(directory / "paper.csv", dtype=str, keep_default_na=False)
        name = "; ".join(cites) if cites else "the protocols' papers"
        parts.append(f"<h2>{html.escape(name)}, beside this run (paper.csv)</h2>" + paper.to_html(index=False))
    est = {}
    clk = {}
    scored = []
    for v, d in dirs.items():
        t = trace.load(d)
        scored.append((v, tracks.track_data(t)))
        if t.get("estimates") is not None and "error" in t["estimates"]:
            est[v] = t["estimates"]["error"].to_numpy(float)
        if t.get("clocks") is not None and "error" in t["clocks"]:
            clk[v] = 1e6 * np.abs(t["clocks"]["error"].to_numpy(float))
    images = [
        p
        for p in (
            _cdf(est, "localization error (m)", "Localization error, every estimate", out / "variants_error_cdf.png"),
            _cdf(clk, "|clock error| (us)", "Clock error, every clocks row", out / "variants_sync_cdf.png"),
        )
        if p is not None
    ]
    parts.append(_track_scores(scored))
    parts.append("<h2>Plots</h2>" + "".join(img(p) for p in images))
    links = "".join(
        f'<li><a href="{html.escape(v)}/report.html">{html.escape(v)}</a></li>'
        for v, d in dirs.items()
        if (d / "report.html").is_file()
    )
    if links:
        parts.append(f"<h2>Each variant's own report</h2><ul>{links}</ul>")
    return title, "".join(parts)
