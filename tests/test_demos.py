"""The shared live-demo machinery (kfcal_helpers.demos) on a toy demo: the controls above the image,
a redraw per change, and a one-line message instead of any traceback or warning.  The problems' own
demos are tested in tests/test_calibration_demos.py, tests/test_coop_demos.py and tests/test_orbit_demos.py."""

import dataclasses
import warnings

import ipywidgets as w
import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from kfcal_helpers.demos import (DEMO_FAILURES, CachedBackground, LiveDemo, describe_controls, failure_message,
                                 figure_png, new_figure, require_finite_demo, smallest_text)

from demo_checks import fast_draw_is_full_draw, off_grid_defaults, png_size, slider_stops


@dataclasses.dataclass
class ToyDemo:
    finite_fields = ("y",)
    gain: float
    y: np.ndarray

    def summary(self):
        return f"gain {self.gain:.2f}"


class ToyFigure:
    def __init__(self, figure=None):
        self.fig = new_figure(figure, (4.0, 3.0))
        self.ax = self.fig.add_subplot()
        (self.line,) = self.ax.plot([0, 1], [0, 0])

    def update(self, demo):
        self.line.set_ydata(demo.y)
        self.fig.suptitle(f"gain {demo.gain:g}")
        return self.fig


def toy_controls():
    return {"gain": w.FloatSlider(value=1.0, min=0.0, max=5.0, description="gain"),
            "on": w.Checkbox(value=True, description="line on"),
            "kind": w.ToggleButtons(options=[("Up", "up"), ("Down", "down")], value="up", description="kind")}


def toy_compute(gain=1.0, on=True, kind="up"):
    if not on:
        return None
    if gain > 4.0:
        raise np.linalg.LinAlgError("2-th leading minor of the array is not positive definite")
    sign = 1.0 if kind == "up" else -1.0
    return ToyDemo(gain, sign * gain * np.array([0.0, 1.0]))




def _live():
    return LiveDemo(toy_controls(), toy_compute, ToyFigure(Figure(figsize=(4.0, 3.0))), empty="tick the line",
                    hint="try a smaller gain")


def test_live_demo_shows_the_figure_and_follows_the_controls():
    live = _live()
    assert not live.failed and "gain 1.00" in live.line.value
    first = live.image.value
    assert first[:4] == b"\x89PNG" and png_size(first) == tuple(round(s * live.view.fig.dpi) for s in (4.0, 3.0))
    live.controls["gain"].value = 2.0
    assert not live.failed and live.image.value != first and "gain 2.00" in live.line.value
    bar, image, line = live.widget.children  # the controls in wrapping rows above the image, the line under it
    assert isinstance(live.widget, w.VBox) and list(bar.children) == list(live.controls.values())
    assert bar.layout.flex_flow == "row wrap" and (image, line) == (live.image, live.line)


@pytest.mark.parametrize("error, says", [
    (np.linalg.LinAlgError("6-th leading minor of the array is not positive definite"),
     "its covariance is no longer positive definite (6-th leading minor"),
    (ValueError("Singular matrix"), "cannot compute these settings: Singular matrix"),
    (FloatingPointError("overflow encountered"), "cannot compute these settings: overflow encountered"),
    (RuntimeWarning("invalid value encountered in sqrt"), "(RuntimeWarning: invalid value encountered in sqrt)")])
def test_a_failing_compute_draws_a_one_line_message(error, says):
    live = _live()
    good = live.image.value

    def fail(**values):
        if isinstance(error, Warning):
            warnings.warn(error)  # raised as an error inside a redraw, never shown
        raise error

    live.compute = fail
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning may escape the redraw
        live.controls["gain"].value = 3.0
    assert live.failed
    line = live.line.value
    assert says in line and "Traceback" not in line and "\n" not in line and "try a smaller gain" in line
    fig = live.message_fig
    assert png_size(live.image.value) == png_size(good) and live.image.value != good
    message = [t.get_text() for t in fig.texts if t.get_text() != fig.get_suptitle()]
    assert not fig.axes and len(message) == 1 and "\n" not in message[0] and message[0] in line
    assert "gain 3" in fig.get_suptitle() and "not drawn" in fig.get_suptitle()
    live.compute = toy_compute  # the next setting that works draws again
    live.controls["gain"].value = 2.5
    assert not live.failed and live.view.fig.get_suptitle() == "gain 2.5"


def test_the_slider_past_its_limit_fails_politely_and_comes_back():
    live = _live()
    live.controls["gain"].value = 4.5
    assert live.failed and "no longer positive definite" in live.line.value
    live.controls["gain"].value = 1.5
    assert not live.failed


def test_non_finite_results_and_nothing_to_draw_give_a_message():
    live = _live()
    live.compute = lambda **v: ToyDemo(1.0, np.array([0.0, np.nan]))
    live.refresh()
    assert live.failed and "not finite (y holds inf or NaN)" in live.line.value
    live.compute = toy_compute
    live.controls["on"].value = False
    assert live.failed and "tick the line" in live.line.value and "none ticked" in live.message_fig.get_suptitle()


def test_an_unexpected_error_is_one_line_too():
    live = _live()

    def broken(**values):
        raise KeyError("x")

    live.compute = broken
    live.refresh()  # a live demo never shows a traceback
    assert live.failed and "unexpected error" in live.line.value and "KeyError" in live.line.value
    with pytest.raises(KeyError):
        live.render()  # ... but the render path itself does not hide programming errors


def test_live_demo_validates():
    with pytest.raises(ValueError, match="controls"):
        LiveDemo({}, toy_compute, ToyFigure())
    with pytest.raises(ValueError, match="compute"):
        LiveDemo(toy_controls(), None, ToyFigure())
    with pytest.raises(ValueError, match="view"):
        LiveDemo(toy_controls(), toy_compute, Figure())


def test_describe_controls():
    c = toy_controls()
    assert describe_controls(c) == "gain 1; kind Up; on: line on"
    assert describe_controls(c, {"gain": 0.1234, "kind": "down", "on": False}) == "gain 0.123; kind Down; on: none ticked"


def test_failure_message_and_finite_check():
    assert failure_message(ValueError("x" * 200)).endswith("...") and len(failure_message(ValueError("x" * 200))) < 120
    assert failure_message(RuntimeWarning("overflow")).startswith("the computation overflowed")
    assert issubclass(np.linalg.LinAlgError, DEMO_FAILURES)
    require_finite_demo(ToyDemo(1.0, np.zeros(2)))
    with pytest.raises(ValueError, match="y holds inf"):
        require_finite_demo(ToyDemo(1.0, np.array([np.inf, 0.0])))
    require_finite_demo(object())  # nothing declared: nothing to check


def test_new_figure_and_png():
    fig = new_figure(None, (2.0, 1.0))
    assert tuple(fig.get_size_inches()) == (2.0, 1.0)
    given = Figure()
    assert new_figure(given, (9, 9)) is given
    with pytest.raises(ValueError, match="figure must be a matplotlib Figure"):
        new_figure("fig", (1, 1))
    with pytest.raises(ValueError, match="fig must be a matplotlib Figure"):
        figure_png(None)
    assert figure_png(given)[:4] == b"\x89PNG"
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_smallest_text_finds_the_smallest_visible_text():
    fig = Figure(figsize=(3.0, 2.0))
    ax = fig.subplots()
    ax.set_title("title", fontsize=12)
    ax.set_xlabel("x", fontsize=11)
    ax.tick_params(labelsize=10)
    FigureCanvasAgg(fig).draw()  # the tick labels exist once drawn
    assert smallest_text(fig)[0] == 10.0
    ax.text(0.5, 0.5, "note", fontsize=7)
    ax.text(0.5, 0.2, "hidden", fontsize=5, visible=False)  # hidden and empty texts do not count
    ax.text(0.5, 0.3, "  ", fontsize=4)
    legend = ax.legend(handles=[ax.plot([0, 1], label="line")[0]], fontsize=6)
    assert smallest_text(fig) == (6.0, "line")
    legend.set_visible(False)  # the text of a hidden legend is not shown
    assert smallest_text(fig) == (7.0, "note")
    with pytest.raises(ValueError, match="fig must be a matplotlib Figure"):
        smallest_text(ax)
    with pytest.raises(ValueError, match="fig has no visible text"):
        smallest_text(Figure())


class FastToyFigure(ToyFigure):
    """The toy figure with a kept background: its x axis (fixed limits) is drawn once."""

    def __init__(self, figure=None):
        super().__init__(figure)
        self.ax.set_xlim(0.0, 1.0)
        self.ax.set_title("toy")
        self.background = CachedBackground(self.fig, [self.ax.xaxis], key=lambda: self.ax.get_xlim())

    def update(self, demo):
        super().update(demo)
        self.ax.set_ylim(min(0.0, demo.y.min()) - 0.1, max(0.0, demo.y.max()) + 0.1)
        return self.fig

    def draw(self):
        return self.background.draw()


def test_cached_background_draws_what_a_full_draw_draws():
    view = FastToyFigure(Figure(figsize=(4.0, 3.0)))
    for gain in (1.0, 2.5, 0.5):
        view.update(toy_compute(gain))
        assert fast_draw_is_full_draw(view)
    assert view.background.full_draws == 1  # the background was rendered once
    view.ax.set_xlim(0.0, 2.0)  # what the kept part depends on changed: rendered again, still the same image
    assert fast_draw_is_full_draw(view) and view.background.full_draws == 2
    view.update(toy_compute(3.0, kind="down"))
    assert fast_draw_is_full_draw(view) and view.background.full_draws == 2


def test_cached_background_leaves_a_y_offset_beside_a_title_to_a_full_draw():
    view = FastToyFigure(Figure(figsize=(4.0, 3.0)))
    view.ax.set_title("a title as wide as the panel, over its offset text")  # matplotlib lifts it over the offset
    view.update(toy_compute(1.0))
    view.draw()
    drawn = view.background.full_draws
    view.ax.set_ylim(1e6, 1e6 + 1e-3)  # tick labels with an offset text (+1e6) at the top, beside the title
    assert fast_draw_is_full_draw(view) and view.background.full_draws == drawn + 1
    assert view.ax.yaxis.offsetText.get_text() and view.ax.title.get_position()[1] > 1.0
    view.update(toy_compute(2.0))  # back to plain ticks: the title goes back to its place, fast again
    assert fast_draw_is_full_draw(view) and view.background.full_draws == drawn + 1


def test_cached_background_ticks_the_changed_axes_once_and_gives_their_tickers_back():
    view = FastToyFigure(Figure(figsize=(4.0, 3.0)))
    view.ax.set_title("")  # no title: an offset text is drawn by the fast path too
    view.draw()  # the first redraw renders the kept background in full
    axis = view.ax.yaxis
    locator, formatter = axis.get_major_locator(), axis.get_major_formatter()
    flags = (axis.isDefault_majloc, axis.isDefault_majfmt)
    calls = []
    original = type(locator).__call__
    type(locator).__call__ = lambda self: calls.append(1) or original(self)
    try:
        for y in ([0.0, 1.0], [0.0, -3e-4], [2.0, 7.5]):
            view.line.set_ydata(y)
            view.ax.set_ylim(min(y) - 0.1 * abs(max(y) - min(y)), max(y) + 0.1 * abs(max(y) - min(y)))
            calls.clear()
            view.draw()
            assert len(calls) == 1  # asked once for this redraw (six times without the fixed ticks)
            assert fast_draw_is_full_draw(view)
        view.ax.set_ylim(1e6, 1e6 + 1e-3)  # tick labels with an offset text (+1e6)
        assert fast_draw_is_full_draw(view) and axis.offsetText.get_text()
        assert view.background.full_draws == 1  # every redraw above went by the fast path
    finally:
        type(locator).__call__ = original
    # the axis has its own locator and formatter back, untouched: a later draw ticks it as matplotlib does
    assert axis.get_major_locator() is locator and axis.get_major_formatter() is formatter
    assert (axis.isDefault_majloc, axis.isDefault_majfmt) == flags


def test_cached_background_validates_and_live_demo_uses_it():
    view = FastToyFigure(Figure(figsize=(4.0, 3.0)))
    with pytest.raises(ValueError, match="fig must be a matplotlib Figure"):
        CachedBackground(None, [])
    with pytest.raises(ValueError, match="key must be None or callable"):
        CachedBackground(view.fig, [], key=1)
    late = CachedBackground(view.fig, [view.line])  # the line is drawn after the (changing) y axis
    with pytest.raises(ValueError, match="static artist .* is drawn after a changing artist"):
        late.draw()
    with pytest.raises(ValueError, match="drawn=True"):
        figure_png(Figure(), drawn=True)  # a figure without an Agg canvas has no rendering to encode
    live = LiveDemo(toy_controls(), toy_compute, view)
    assert view.background.full_draws == 1
    live.controls["gain"].value = 2.0
    assert view.background.full_draws == 1 and not live.failed  # the slider move drew the changed part only
    assert live.image.value == figure_png(view.fig)  # the same PNG as a full draw


def test_jupyterlab_asks_no_news_question_in_this_environment():
    """The install puts the package's settings override where this environment's JupyterLab reads it
    (``<sys.prefix>/share/jupyter/lab/settings/overrides.d/``, editable install included): no "official
    Jupyter news?" toast and no update check over the live demos."""
    import json
    from pathlib import Path

    from jupyterlab.commands import get_app_dir
    from jupyterlab_server.settings_utils import _get_overrides

    repo = json.loads((Path(__file__).parents[1] / "lab_settings" / "overrides.d" / "kfcal-helpers.json").read_text())
    installed = Path(get_app_dir()) / "settings" / "overrides.d" / "kfcal-helpers.json"
    assert installed.is_file(), f"{installed} missing: reinstall the package (pip install -r environment.txt)"
    assert json.loads(installed.read_text()) == repo, f"{installed} is out of date: reinstall the package"
    overrides, error = _get_overrides(str(Path(get_app_dir()) / "settings"))
    assert not error
    notification = overrides["@jupyterlab/apputils-extension:notification"]
    assert notification["fetchNews"] == "false" and notification["checkForUpdates"] is False


def test_off_grid_defaults_finds_a_default_between_two_stops():
    # the check the demos' tests apply to their controls: the W slider notebook 17 had (4e-4 is no stop of
    # 10 ** (-6 + 0.1 k): the browser moved it to 10 ** -3.4 = 3.98e-4) and other kinds of slider
    controls = {
        "W": w.FloatLogSlider(value=4e-4, base=10, min=-6, max=-2, step=0.1),
        "sigma": w.FloatLogSlider(value=1.0, base=10, min=-1, max=1, step=0.05),
        "bias": w.FloatLogSlider(value=0.1, base=10, min=-3, max=0, step=0.1),
        "gain": w.FloatSlider(value=0.25, min=0.0, max=1.0, step=0.1),
        "window": w.FloatRangeSlider(value=(12.0, 18.25), min=0.0, max=30.0, step=0.5),
        "rate": w.SelectionSlider(options=[1.0, 2.0, 5.0], value=5.0),
        "noise": w.SelectionSlider(options=[("4e-4", 4e-4), ("5e-4", 5e-4)], value=4e-4),
        "on": w.Checkbox(value=True),
    }
    found = off_grid_defaults(controls)
    assert [(name, value) for name, value, _ in found] == [("W", 4e-4), ("gain", 0.25), ("window", 18.25)]
    assert found[0][2] == pytest.approx(10 ** -3.4, rel=1e-12)
    assert len(slider_stops(controls["W"])) == 41 and slider_stops(controls["on"]) is None
    assert slider_stops(controls["noise"]) == [4e-4, 5e-4]


def test_error_lines_and_show_errors():
    """The error panel shared by the problems' demos: the error and its +-2 sigma pair, symmetric y limits 15 %
    beyond the largest from sample ``skip`` on, and shapes checked."""
    from kfcal_helpers.demos import error_lines, show_errors

    fig = Figure()
    ax = fig.add_subplot()
    lines = error_lines(ax)
    assert [ln.get_label() for ln in lines[:2]] == ["error", r"$\pm 2\sigma$"] and all(ln.axes is ax for ln in lines)
    t = np.arange(5.0)
    show_errors(lines, t, np.array([9.0, 1.0, -3.0, 0.5, 0.0]), np.array([50.0, 2.0, 2.0, 2.0, 2.0]), skip=1)
    assert ax.get_ylim() == pytest.approx((-3.45, 3.45))
    np.testing.assert_array_equal(lines[2].get_ydata(), -np.array([50.0, 2.0, 2.0, 2.0, 2.0]))
    show_errors(lines, t, np.zeros(5), np.ones(5), skip=99)   # a skip past the end keeps the last sample
    assert ax.get_ylim() == pytest.approx((-1.15, 1.15))
    with pytest.raises(ValueError, match="t, error and sigma2"):
        show_errors(lines, t, np.zeros(4), np.ones(5))
    with pytest.raises(ValueError, match="ax"):
        error_lines(fig)
