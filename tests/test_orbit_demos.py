"""The orbit-determination live demo (kfcal_helpers.orbit.demos, notebook 24): its numbers are filterpy's runs of
kfcal_helpers.orbit.filters, its NIS band is built from the dof present at each step, its controls reach every
precomputed run, and no setting of them (nor a value set from Python) gives a traceback, a warning or a NaN."""

import matplotlib

matplotlib.use("Agg")

import ipywidgets as w  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from scipy import stats  # noqa: E402

from kfcal_helpers.demos import LiveDemo, figure_png  # noqa: E402
from kfcal_helpers.orbit import OrbitParams, log_params, run_filter, simulate, station_states  # noqa: E402
from kfcal_helpers.orbit.demos import (LIVE_FIGSIZE, LIVE_HINT, ORBIT_DEMO_FILTERS, Q_SCALES, OrbitDemo,  # noqa: E402
                                       OrbitDemoFigure, compute_orbit_demo, orbit_controls, precompute_orbit_demo)

from demo_checks import (check_render, fast_draw_is_full_draw, legend_is_outside_the_panels,  # noqa: E402
                         off_grid_defaults, png_size, slider_stops)


@pytest.fixture(scope="module")
def log():
    """A short seeded log (300 steps, 3000 s: passes of several stations), so the 12 runs take about 2 s."""
    return simulate(OrbitParams(n_steps=300)).log()


@pytest.fixture(scope="module")
def runs(log):
    return precompute_orbit_demo(log)


def _live(runs):
    """The live demo as notebook 24 builds it."""
    return LiveDemo(orbit_controls(runs), lambda **kw: compute_orbit_demo(runs, **kw),
                    OrbitDemoFigure(Figure(figsize=LIVE_FIGSIZE)), hint=LIVE_HINT)


@pytest.mark.parametrize("filter", ORBIT_DEMO_FILTERS)
@pytest.mark.parametrize("q_scale", [0.01, 1.0, 1000.0])
def test_the_demo_numbers_are_the_package_filters(log, runs, filter, q_scale):
    """Each redraw shows filterpy's run of run_filter with Q = q_scale Qtrue, bit for bit, and its own NIS statistics."""
    p = log_params(log)
    ref = run_filter(filter, log.y, p, truth=log.truth, Q=q_scale * p.Qtrue)
    demo = compute_orbit_demo(runs, filter, q_scale, t=float(log.t[57]))
    assert demo.filter == filter and demo.q_scale == q_scale
    np.testing.assert_array_equal(demo.errors, log.truth - ref.x_post)
    np.testing.assert_array_equal(demo.sigma2, 2 * np.sqrt(np.diagonal(ref.P_post, axis1=1, axis2=2)))
    np.testing.assert_array_equal(demo.nis, ref.nis)
    # the per-step band from the dof present: 3 per station with a measurement in the log
    dof = 3 * np.isfinite(log.y[:, :, 0]).sum(axis=1)
    np.testing.assert_array_equal(demo.dof, dof)
    has = dof > 0
    assert {3, 6} <= set(dof[has].tolist())     # the short log has steps with one and with two stations
    np.testing.assert_allclose(demo.nis_lower[has], stats.chi2.ppf(0.025, dof[has]), rtol=1e-12)
    np.testing.assert_allclose(demo.nis_upper[has], stats.chi2.ppf(0.975, dof[has]), rtol=1e-12)
    assert np.isnan(demo.nis_lower[~has]).all() and np.isnan(demo.nis[~has]).all()
    nis = ref.nis[has]
    assert demo.n_nis == has.sum() and demo.nis_mean == pytest.approx(nis.mean(), rel=1e-12)
    n = has.sum()
    assert demo.nis_bounds == pytest.approx((stats.chi2.ppf(0.025, dof.sum()) / n, stats.chi2.ppf(0.975, dof.sum()) / n))
    inside = (nis >= stats.chi2.ppf(0.025, dof[has])) & (nis <= stats.chi2.ppf(0.975, dof[has]))
    assert demo.inside_share == pytest.approx(inside.mean())
    # the pass geometry at the time shown: the stations whose measurements the filter used, and where they are
    assert demo.step == 57 and demo.time == log.t[57]
    np.testing.assert_array_equal(demo.seen, np.flatnonzero(np.isfinite(log.y[57, :, 0])))
    np.testing.assert_array_equal(demo.stations, station_states(log.t[57], p)[:, [0, 2]])
    np.testing.assert_array_equal(demo.satellite, log.truth[57, [0, 2]])


def test_too_small_a_q_puts_the_nis_above_its_bounds(runs):
    """The demo's point: Q = 0.01 Qtrue makes both filters overconfident (NIS above), Q = Qtrue is inside."""
    for f in ORBIT_DEMO_FILTERS:
        small, true = compute_orbit_demo(runs, f, 0.01), compute_orbit_demo(runs, f, 1.0)
        assert small.nis_verdict == "above" and small.inside_share < true.inside_share
        assert true.nis_verdict == "inside"


@pytest.mark.parametrize("kwargs, name", [
    ({"filter": "lkf"}, "filter"), ({"filter": 3}, "filter"),
    ({"q_scale": 0.5}, "q_scale"), ({"q_scale": float("nan")}, "q_scale"), ({"q_scale": True}, "q_scale"),
    ({"q_scale": "1"}, "q_scale"), ({"q_scale": 0.0}, "q_scale"),
    ({"t": -10.0}, "t"), ({"t": -1e-3}, "t"), ({"t": 1e9}, "t"), ({"t": float("inf")}, "t"), ({"t": "0"}, "t"),
])
def test_compute_orbit_demo_validates(runs, kwargs, name):
    with pytest.raises(ValueError, match=name):
        compute_orbit_demo(runs, **kwargs)


def test_precompute_needs_a_log_with_truth(log):
    from dataclasses import replace
    with pytest.raises(ValueError, match="truth"):
        precompute_orbit_demo(replace(log, truth=None))
    with pytest.raises((TypeError, ValueError), match="log"):
        precompute_orbit_demo(log.y)
    with pytest.raises(ValueError, match="alpha"):
        precompute_orbit_demo(log, alpha=1.5)
    with pytest.raises((TypeError, ValueError), match="runs"):
        compute_orbit_demo(log)


def test_the_controls_reach_every_precomputed_run_and_every_sample(log, runs):
    controls = orbit_controls(runs)
    assert set(controls) == {"filter", "q_scale", "t"}
    assert isinstance(controls["filter"], w.ToggleButtons) and [v for _, v in controls["filter"].options] == ["ekf", "ukf"]
    assert np.allclose(slider_stops(controls["q_scale"]), Q_SCALES, rtol=1e-12)
    assert np.allclose(slider_stops(controls["t"]), log.t, rtol=0, atol=1e-9)
    assert off_grid_defaults(controls) == []
    for c in controls.values():
        assert not getattr(c, "continuous_update", False)   # one redraw per release


def test_the_figure_draws_fast_and_as_a_full_draw(runs, log):
    view = OrbitDemoFigure(Figure(figsize=LIVE_FIGSIZE))
    for f, q, t in (("ekf", 1.0, 0.0), ("ukf", 1000.0, float(log.t[140])), ("ekf", 0.01, float(log.t[-1]))):
        demo = compute_orbit_demo(runs, f, q, t)
        assert view.update(demo) is view.fig
        assert fast_draw_is_full_draw(view)
        assert legend_is_outside_the_panels(view)
        assert f.upper() in view.fig.get_suptitle() and f"{demo.nis_mean:.2f}" in view.fig.get_suptitle()
        # the stations seeing the satellite are drawn in green, the others in grey, one line of sight each
        assert len(view.visible.get_xdata()) == demo.seen.size
        assert len(view.hidden.get_xdata()) == 12 - demo.seen.size
        assert np.isnan(view.sight.get_xdata()).sum() == demo.seen.size
    assert view.background.full_draws <= 4   # the first render and the full draws of the pixel comparisons


def test_the_live_demo_follows_the_controls(runs, log):
    live = _live(runs)
    assert not live.failed and live.image.value[:4] == b"\x89PNG"
    assert "EKF, Q = 1 Qtrue" in live.line.value
    first = live.image.value
    live.controls["filter"].value = "ukf"
    assert not live.failed and "UKF" in live.line.value and live.image.value != first
    live.controls["q_scale"].value = 100.0
    assert not live.failed and "Q = 100 Qtrue" in live.line.value
    t = float(log.t[63])
    live.controls["t"].value = t
    demo = compute_orbit_demo(runs, "ukf", 100.0, t)
    assert not live.failed and f"t = {t:.0f} s: {demo.seen_text()}" in live.line.value
    assert png_size(live.image.value) == tuple(round(s * live.view.fig.dpi) for s in LIVE_FIGSIZE)


@pytest.mark.parametrize("values", [
    {"q_scale": 0.5}, {"q_scale": float("nan")}, {"q_scale": 1e300}, {"t": float("nan")},
    {"t": -1e9}, {"filter": "lkf"},
])
def test_bad_values_draw_a_one_line_message(runs, values):
    """A value set from Python that the demo has no run for: a message in the image's place, never a traceback,
    warning or NaN."""
    live = _live(runs)
    assert check_render(live, values) is False


def test_a_typed_time_between_samples_draws_the_nearest_sample(runs, log):
    """The t readout takes typed values that ipywidgets clamps to the slider's range but does not round to its
    step: the demo draws the nearest sample time (halfway: the earlier one); outside the log, an error naming t."""
    assert float(log.t[21]) == 210.0 and float(log.t[1] - log.t[0]) == 10.0
    for typed, shown in ((215.0, 210.0), (215.001, 220.0), (212.5, 210.0), (0.4, 0.0), (float(log.t[-1]) - 3, float(log.t[-1]))):
        demo = compute_orbit_demo(runs, "ekf", 1.0, typed)
        assert demo.time == shown and demo.t[demo.step] == shown, (typed, demo.time)
    live = _live(runs)
    live.controls["t"].value = 215.0
    assert not live.failed and "t = 210 s:" in live.line.value
    assert check_render(live, {"t": 2345.6})
    with pytest.raises(ValueError, match="t must"):
        compute_orbit_demo(runs, t=float(log.t[-1]) + 1.0)


def test_an_off_stop_q_names_the_q_slider(runs):
    """A Q / Qtrue typed between the slider's stops (no run was made for it): one line that says why and names the
    Q slider and its stops, no traceback, warning or NaN."""
    import warnings

    live = _live(runs)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        live.controls["q_scale"].value = 0.5
    assert live.failed and "\n" not in live.line.value
    assert "q_scale must be one of the precomputed scales" in live.line.value
    assert "the Q / Qtrue slider has only its six precomputed stops" in live.line.value
    assert "nan" not in live.line.value.lower()


def test_the_title_says_which_stations_measured(runs, log):
    """The title names the stations whose measurements the log holds at the step shown, not the ones above their
    horizon: at t = 0 the log has no measurement although station 1 is above its horizon."""
    first = compute_orbit_demo(runs, "ekf", 1.0, 0.0)
    assert first.seen.size == 0 and first.seen_text() == "no station measurement at this step"
    two = compute_orbit_demo(runs, "ekf", 1.0, 210.0)
    assert two.seen.tolist() == [0, 1] and two.seen_text() == "stations 1, 2 measured"
    one = compute_orbit_demo(runs, "ekf", 1.0, 10.0)
    assert one.seen.size == 1 and one.seen_text() == f"station {one.seen[0] + 1} measured"
    view = OrbitDemoFigure(Figure(figsize=LIVE_FIGSIZE))
    assert "t = 0 s: no station measurement at this step" in view.update(first).get_suptitle()


def test_the_default_time_is_a_two_station_step_in_the_middle_of_the_log(runs, log):
    """The default time is away from the first minutes (where the cursor would sit on the panels' left edge, on the
    prior's 2 sigma lines): the step with two stations nearest the middle of the log."""
    two = log.t[runs.dof == 6]
    middle = 0.5 * (log.t[0] + log.t[-1])
    assert runs.default_time == two[np.argmin(np.abs(two - middle))]
    assert 0.25 * log.t[-1] < runs.default_time < 0.75 * log.t[-1]
    assert compute_orbit_demo(runs).seen.size == 2


def test_the_error_panels_have_their_own_time_labels(runs):
    """The four error panels are half as wide as the NIS panel: the lower row labels its own time axis (a reader
    must not read their times off the NIS panel's axis), and those labels do not run into the NIS panel."""
    view = OrbitDemoFigure(Figure(figsize=LIVE_FIGSIZE))
    view.update(compute_orbit_demo(runs))
    view.draw()
    renderer = view.fig.canvas.get_renderer()
    nis_box = view.nis_ax.get_tightbbox(renderer)
    for i, ax in enumerate(view.error_axes):
        labels = [lab for lab in ax.get_xticklabels() if lab.get_visible() and lab.get_text()]
        if i < 2:
            assert not labels
            continue
        assert len(labels) >= 2, i
        for lab in labels:
            box = lab.get_window_extent(renderer)
            assert box.y0 > view.nis_ax.get_window_extent(renderer).y1, (i, lab.get_text())
            assert not box.overlaps(nis_box) or box.y0 >= nis_box.y1 - 1
    assert fast_draw_is_full_draw(view)


def test_every_stop_of_the_controls_draws(runs, log):
    live = _live(runs)
    for f in ORBIT_DEMO_FILTERS:
        for q in slider_stops(live.controls["q_scale"]):
            for t in (log.t[0], log.t[100], log.t[-1]):
                assert check_render(live, {"filter": f, "q_scale": q, "t": float(t)})


def test_the_live_view_is_shown_pixel_for_pixel_and_readable(runs):
    import matplotlib as mpl

    from kfcal_helpers.demos import MIN_TEXT_PX, NOTEBOOK_WIDTH_PX, smallest_text
    from kfcal_helpers.style import style_params

    with mpl.rc_context(style_params()):
        view = OrbitDemoFigure(Figure(figsize=LIVE_FIGSIZE))
        view.update(compute_orbit_demo(runs))
        figure_png(view.draw(), drawn=True)
    width, height = view.fig.canvas.get_width_height()
    points, text = smallest_text(view.fig)
    assert width <= NOTEBOOK_WIDTH_PX and height <= 0.7 * width, (width, height)
    assert points * view.fig.dpi / 72 >= MIN_TEXT_PX, (text, points, view.fig.dpi)


def test_update_takes_only_an_orbit_demo(runs):
    view = OrbitDemoFigure(Figure(figsize=LIVE_FIGSIZE))
    with pytest.raises((TypeError, ValueError), match="demo"):
        view.update(runs)
    assert isinstance(compute_orbit_demo(runs), OrbitDemo)


def test_notebook_24_is_a_demo_not_a_graded_lesson():
    """Notebook 24 says ``kfcal: {graded: false}`` like the demos 17 and 18 (the nbgrader course leaves it out),
    and has no exercises."""
    from pathlib import Path

    from kfcal_helpers.assignments import answer_cells, read_source

    nb = read_source(Path(__file__).resolve().parents[1] / "notebooks" / "source" / "24_orbit_live_demo.md")
    assert nb.metadata["kfcal"] == {"graded": False} and not answer_cells(nb)
