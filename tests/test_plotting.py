"""Plots a reader can trust (issue 24): no title of a figure that rockjax draws runs past
the figure's edges (`rockjax._plotting.fit_titles` wraps them; `titles_inside` measures
the drawn extent), and a plot of several models says whose numbers its title gives."""

from __future__ import annotations

import numpy as np
import pytest

import rockjax
from rockjax import _plotting

LONG = ("a title much longer than any figure is wide, as the command line writes them: "
        "model simplified, impact rule paper, r = 0.735 (Eq 3), El Centro 1940 NS x 1.0, "
        "units g from the file header, dt 0.01 s, 4000 points, PGA 0.3129 g")


def test_the_checker_sees_a_clipped_title():
    fig = _plotting.new_figure(figsize=(6, 5))
    ax = fig.subplots()
    ax.set_title(LONG)
    fig.suptitle(LONG)
    assert len(_plotting.titles_inside(fig)) == 2  # both run past the edges
    _plotting.fit_titles(fig)
    assert _plotting.titles_inside(fig) == []
    assert "\n" in ax.get_title()  # wrapped, every word kept
    assert ax.get_title().split() == LONG.split()


@pytest.mark.parametrize("layout", [None, "constrained"])
def test_titles_fit_with_either_layout(layout):
    fig = _plotting.new_figure(figsize=(6, 4), layout=layout)
    axes = fig.subplots(2, 1)
    axes[0].set_title(LONG + "\nsecond line: " + LONG, fontsize=10)
    axes[1].set_title("short")
    assert _plotting.titles_inside(_plotting.fit_titles(fig)) == []
    assert axes[1].get_title() == "short"


@pytest.fixture(scope="module")
def free(column):
    return rockjax.simulate(column, rockjax.FreeVibration(0.05), 1.0,
                            ts=np.linspace(0, 1.0, 201))


def test_the_plots_keep_their_titles_inside(column, free):
    figs = [_plotting.plot_pushover(column, title=LONG),
            _plotting.plot_response(column, free, title=LONG),
            _plotting.plot_response(column, free, title=LONG, label="simplified",
                                    overlay=[("exact", free)])]
    for fig in figs:
        assert _plotting.titles_inside(fig) == [], fig.axes[0].get_title()


def test_several_models_say_whose_numbers_the_title_gives(column, free):
    fig = _plotting.plot_response(column, free, label="simplified", overlay=[("exact", free)])
    assert fig.axes[0].get_title().startswith("simplified: peak |u| =")
    one = _plotting.plot_response(column, free)
    assert one.axes[0].get_title().startswith("peak |u| =")


def test_the_command_line_saves_every_figure_with_its_titles_inside(tmp_path):
    """`rockjax.cli._common.save`, through which every command writes its plot (spectrum
    and fragility included, whose `.plot()` draws on a given axes), fits the titles."""
    from rockjax.cli._common import save

    fig = _plotting.new_figure(figsize=(6.4, 4.8))
    ax = fig.subplots()
    ax.set_title(LONG)
    path = save(fig, tmp_path / "plot.png")
    assert path.stat().st_size > 0 and _plotting.titles_inside(fig) == []


@pytest.mark.parametrize("changes", [{}, {"B": 0.6, "H_e": 0.5}, {"B": 0.1, "k_f": 5e6}])
def test_the_pushover_labels_stay_inside_the_frame(column, changes):
    """The u_crit / P_crit and u_overturn labels of the pushover lie inside its axes (the
    u_crit label ran over the top of the frame), for slender and squat structures."""
    fig = _plotting.plot_pushover(column.replace(**changes))
    renderer = _plotting._drawn(fig)
    ax = fig.axes[0]
    frame = ax.get_window_extent(renderer)
    for t in ax.texts:
        e = t.get_window_extent(renderer)
        assert frame.x0 <= e.x0 and e.x1 <= frame.x1 and frame.y0 <= e.y0 and \
            e.y1 <= frame.y1, t.get_text()
