"""aquasim_py.reporting.figures: what save_figure mends before writing, and what problems()
and the independent checks (readable.py) find in a figure left as drawn."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator
from readable import findings, unnoted_identical  # tests/reporting, beside this file

from aquasim_py.reporting import figures


def _close(fig) -> None:
    figures.plt.close(fig)


def test_a_legend_over_a_point_is_found_and_moved_off_the_data() -> None:
    fig, ax = figures.subplots(figsize=(5.0, 3.5))
    x = np.linspace(0.0, 1.0, 40)
    ax.plot(x, np.ones_like(x), label="flat at the top")
    ax.plot(x, 1.0 - x, label="falling")
    ax.plot([0.02], [0.98], "o", label="one point in the corner")
    ax.legend(loc="upper left")  # over the corner point and the top line
    fig.draw_without_rendering()
    assert any("legend over" in f for f in findings(fig))
    assert any("covers" in p for p in figures.problems(fig))
    figures.finish(fig)
    assert findings(fig) == [] and figures.problems(fig) == []
    assert fig.legends, "a single panel's legend moves below the figure"
    _close(fig)


def test_crowded_tick_labels_are_found_and_thinned() -> None:
    fig, ax = figures.subplots(figsize=(2.2, 2.5))
    ax.plot([2.40251, 2.41249], [0.0, 1.0])
    ax.xaxis.set_major_locator(MaxNLocator(nbins=12))  # far too many for the width
    fig.draw_without_rendering()
    assert any("/" in f for f in findings(fig)) and any("tick labels" in p for p in figures.problems(fig))
    figures.finish(fig)
    assert findings(fig) == [] and figures.problems(fig) == []
    _close(fig)


def test_crowded_categories_are_slanted() -> None:
    fig, ax = figures.subplots(figsize=(3.0, 2.5))
    names = ["itmtl_model_delay", "wsc_model_delay", "mobi_sync", "mu_sync"]
    ax.plot(range(4), range(4), "o")
    ax.set_xticks(range(4), names)
    figures.finish(fig)
    assert figures.problems(fig) == [] and findings(fig) == []
    assert all(t.get_rotation() > 0 for t in ax.xaxis.get_majorticklabels() if t.get_text())
    _close(fig)


@pytest.mark.parametrize("gap", [0.0, 1e-4])  # the same data; data closer than a pixel
def test_coinciding_lines_are_drawn_in_turns_and_noted(gap: float) -> None:
    fig, ax = figures.subplots(figsize=(5.0, 3.5))
    x = np.linspace(0.0, 1.0, 50)
    ax.plot(x, x**2, label="a (median 0.25 m)")
    ax.plot(x, x**2 + gap, label="b (median 0.25 m)")
    ax.plot(x, 1.0 - x, label="c")
    ax.legend(loc="center left")
    fig.draw_without_rendering()
    assert any("without a note" in p for p in figures.problems(fig))
    assert (unnoted_identical(fig) != []) == (gap == 0.0)  # the independent check compares data alone
    figures.finish(fig)
    assert figures.problems(fig) == [] and findings(fig) == []
    b = ax.lines[1]
    assert b.get_label() == "b (median 0.25 m) (coincides with a)"
    assert b.get_linestyle() == "--" and ax.lines[0].get_linestyle() == "-"  # a shows in b's gaps
    assert ax.lines[2].get_label() == "c"
    _close(fig)


def test_lines_that_only_cross_are_not_noted() -> None:
    fig, ax = figures.subplots(figsize=(5.0, 3.5))
    x = np.linspace(0.0, 1.0, 50)
    ax.plot(x, x, label="up")
    ax.plot(x, 1.0 - x, label="down")
    ax.legend()
    figures.finish(fig)
    assert [line.get_label() for line in ax.lines] == ["up", "down"]
    assert [line.get_linestyle() for line in ax.lines] == ["-", "-"]
    _close(fig)


def test_panels_with_a_figure_legend_say_it_in_their_title() -> None:
    fig, axes = figures.subplots(1, 2, figsize=(7.0, 3.0))
    for ax, same in zip(axes, (True, False)):
        ax.set_title("panel")
        ax.errorbar([1.0, 2.0], [1.0, 2.0], yerr=0.1, color="C0", label="0.1 m")
        ax.errorbar([1.0, 2.0], [1.0, 2.0] if same else [2.0, 1.0], yerr=0.1, color="C1", label="1 m")
    proxies = [Line2D([], [], color=f"C{i}", label=t) for i, t in enumerate(("0.1 m", "1 m"))]
    fig.legend(handles=proxies, loc="outside right upper")
    fig.draw_without_rendering()
    assert figures.problems(fig) != [] and findings(fig) != []
    figures.finish(fig)
    assert axes[0].get_title() == "panel\n1 m coincides with 0.1 m" and axes[1].get_title() == "panel"
    assert figures.problems(fig) == [] and findings(fig) == []
    _close(fig)


def test_dodged_series_keep_their_data() -> None:
    fig, ax = figures.subplots()
    a = ax.errorbar([1.0, 2.0], [3.0, 4.0], yerr=0.5, transform=figures.dodge(ax, 0, 2), label="a")
    b = ax.errorbar([1.0, 2.0], [3.0, 4.0], yerr=0.5, transform=figures.dodge(ax, 1, 2), label="b")
    fig.draw_without_rendering()
    assert np.array_equal(a.lines[0].get_xydata(), b.lines[0].get_xydata())
    pa = a.lines[0].get_transform().transform(a.lines[0].get_xydata())
    pb = b.lines[0].get_transform().transform(b.lines[0].get_xydata())
    assert np.allclose(pb[:, 0] - pa[:, 0], 7.0 / 72.0 * fig.dpi) and np.allclose(pb[:, 1], pa[:, 1])
    _close(fig)


def test_a_legend_moved_below_carries_the_note_and_finishing_again_changes_nothing() -> None:
    fig, ax = figures.subplots(figsize=(5.0, 3.5))
    x = np.linspace(0.0, 1.0, 50)
    ax.plot(x, x, label="a")
    ax.plot(x, x, label="b")
    ax.plot(x, 1.0 - x, label="c")
    ax.legend(loc="center")  # over the crossing: moves below the figure
    figures.finish(fig)
    (below,) = fig.legends
    assert ax.get_legend() is None
    assert [t.get_text() for t in below.get_texts()] == ["a", "b (coincides with a)", "c"]
    figures.finish(fig)  # a note is not noted twice, nor the legend moved again
    (again,) = fig.legends
    assert [t.get_text() for t in again.get_texts()] == ["a", "b (coincides with a)", "c"]
    assert [line.get_label() for line in ax.lines] == ["a", "b (coincides with a)", "c"]
    assert figures.problems(fig) == [] and findings(fig) == []
    _close(fig)


def test_coincidence_is_measured_in_pixels() -> None:
    """Points within TOL_PX of each other cover each other; a shift of 3 px does not; far apart
    sets meet nowhere."""
    a = np.column_stack([np.linspace(10.0, 200.0, 400), np.full(400, 50.0)])
    assert figures.coincides(a, a + [0.0, 1.0])
    assert not figures.coincides(a, a + [0.0, 3.0])
    assert not figures.coincides(a, a + [0.0, 500.0])
    assert figures.coincides(a, a[::-1] + [0.4, -0.4])  # order does not matter


def test_a_series_that_no_longer_coincides_is_drawn_as_before() -> None:
    fig, ax = figures.subplots(figsize=(5.0, 3.5))
    x = np.linspace(0.0, 1.0, 50)
    ax.plot(x, x, label="a")
    (b,) = ax.plot(x, x, ":", marker="s", ms=4, label="b")
    ax.legend(loc="lower right")
    figures.finish(fig)
    assert b.get_label() == "b (coincides with a)" and b.get_linestyle() == "--" and b.get_fillstyle() == "none"
    figures.finish(fig)  # again: the same turns, the markers no larger
    assert b.get_label() == "b (coincides with a)" and b.get_markersize() == 4 + 2.5
    b.set_ydata(x**3)  # apart now: the note and the turns go, b's own style comes back
    figures.finish(fig)
    assert b.get_label() == "b" and b.get_linestyle() == ":" and b.get_fillstyle() == "full" and b.get_markersize() == 4
    (leg,) = [ax.get_legend()] if ax.get_legend() else fig.legends
    assert [t.get_text() for t in leg.get_texts()] == ["a", "b"]
    assert leg.legend_handles[1].get_linestyle() == ":"
    assert figures.problems(fig) == [] and findings(fig) == []
    _close(fig)
