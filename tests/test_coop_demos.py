"""The cooperative-localization live demo (notebook 18): the filters' ``measurements=`` subsets,
compute_coop_demo against the filters, its figure and controls in the shared LiveDemo, and the
exercise checks 18.1 and 18.2."""

import matplotlib

matplotlib.use("Agg")

from dataclasses import replace

import numpy as np
import pytest
from matplotlib.figure import Figure
from scipy import stats

from kfcal_helpers.coop import (TUNED_Q_SCALE, CoopParams, jacobian_C, measure, measurement_residual,
                                nominal_trajectory, run_filter, simulate, state_residual)
from kfcal_helpers.coop.demos import (LIVE_FIGSIZE, MEASUREMENT_NAMES, CoopDemoFigure, compute_coop_demo, coop_controls,
                                      draw_coop_demo)
from kfcal_helpers.coop.exercises import EXERCISES, check_lost_directions, check_subset_nis_bounds
from kfcal_helpers.coop.fast import run_filter_fast
from kfcal_helpers.demos import LiveDemo, describe_controls, figure_png

from demo_checks import check_render, fast_draw_is_full_draw, legend_is_outside_the_panels, off_grid_defaults, png_size

SHORT = replace(CoopParams(), duration=20.0)


# ---------------------------------------------------------------------------
# filters: measurements=
@pytest.fixture(scope="module")
def short_log():
    return simulate(SHORT, seed=7).log()


@pytest.mark.parametrize("bad", [[], (5,), (0, 0), (-1, 2), ("a",), (1.0, 2), 1.5, "01", (True,)])
@pytest.mark.parametrize("name", ["lkf", "ekf", "ukf"])
def test_measurements_validated(short_log, name, bad):
    with pytest.raises(ValueError, match="measurements"):
        run_filter(name, short_log.y, SHORT, measurements=bad)


@pytest.mark.parametrize("name", ["lkf", "ekf", "ukf"])
def test_all_five_in_any_order_is_the_default(short_log, name):
    a = run_filter(name, short_log.y, SHORT)
    b = run_filter(name, short_log.y, SHORT, measurements=[4, 3, 2, 1, 0])
    assert a.measurements == b.measurements == (0, 1, 2, 3, 4)
    for f in ("x_prior", "P_prior", "x_post", "P_post", "y", "S", "K", "nis"):
        assert np.array_equal(getattr(a, f), getattr(b, f), equal_nan=True)


@pytest.mark.parametrize("name", ["lkf", "ekf", "ukf"])
@pytest.mark.parametrize("subset", [(0, 1, 2), (1, 3, 4), (2, 4)])
def test_subset_is_an_infinite_variance_on_the_rest(short_log, name, subset):
    """Dropping measurements = giving them a huge variance (and no correlation)."""
    r = run_filter(name, short_log.y, SHORT, measurements=subset, truth=short_log.truth)
    R = SHORT.Rtrue.copy()
    rest = [i for i in range(5) if i not in subset]
    R[rest, rest] = 1e14
    big = run_filter(name, short_log.y, SHORT, R=R)
    assert np.allclose(r.x, big.x, rtol=0, atol=1e-5)
    assert np.allclose(r.P, big.P, rtol=1e-6, atol=1e-9)
    assert r.measurements == subset
    rows = list(subset)
    assert np.all(np.isnan(r.y[1:, rest])) and np.all(np.isfinite(r.y[1:, rows]))
    assert np.allclose(r.y[1:, rows], big.y[1:, rows], rtol=0, atol=1e-6)
    # the NIS uses only the rows used: nu_s^T S_s^-1 nu_s, len(subset) degrees of freedom
    nu, S = r.y[1:, rows], r.S[1:][:, rows][:, :, rows]
    assert np.allclose(r.nis[1:], [v @ np.linalg.solve(s, v) for v, s in zip(nu, S)], rtol=1e-9)
    assert np.allclose(r.y[1:, rows], measurement_residual(short_log.y[1:], r.z_pred[1:])[:, rows])


def test_subset_nis_is_chi2_with_the_subset_dimension():
    """Five seeded truth-model logs, EKF with Q = Qtrue, bearings and range only: the averaged
    NIS of all updates lies in the 3-dimensional band, far from the 5-dimensional one."""
    values = np.concatenate([run_filter("ekf", simulate(SHORT, seed=s).y, SHORT, Q=SHORT.Qtrue,
                                        measurements=(0, 1, 2)).nis[1:] for s in range(5)])
    K = values.size
    lo, hi = stats.chi2.ppf([0.005, 0.995], 3 * K) / K
    assert lo < values.mean() < hi
    assert values.mean() < stats.chi2.ppf(0.005, 5 * K) / K


# ---------------------------------------------------------------------------
# coop demo
@pytest.fixture(scope="module")
def log():
    return simulate().log()


def test_coop_demo_numbers(log):
    d = compute_coop_demo(log, "ekf", q_scale=2.0, measurements=[2, 0, 1])
    r = run_filter("ekf", log.y, log.params(), Q=2.0 * log.params().Qtrue, measurements=(0, 1, 2))
    assert d.measurements == (0, 1, 2) and d.nis_dim == 3 and d.q_scale == 2.0
    assert np.allclose(d.errors, state_residual(log.truth, r.x))
    assert np.allclose(d.sigma2, 2 * np.sqrt(np.einsum("kii->ki", r.P)))
    K = int(np.isfinite(log.y[:, 0]).sum())
    assert d.n_nis == K == 1000
    assert d.nis_mean == pytest.approx(np.nanmean(r.nis), rel=1e-12)
    assert d.nis_bounds == pytest.approx(tuple(stats.chi2.ppf([0.025, 0.975], 3 * K) / K), rel=1e-12)
    assert d.nis_inside == (d.nis_bounds[0] <= d.nis_mean <= d.nis_bounds[1])
    assert "3 measurements" in d.summary() and MEASUREMENT_NAMES[1] in d.summary()
    full = compute_coop_demo(log, "ukf")
    assert full.q_scale == 1.0 and full.nis_dim == 5
    assert full.nis_bounds == pytest.approx(tuple(stats.chi2.ppf([0.025, 0.975], 5 * K) / K), rel=1e-12)


def test_losing_the_gps_grows_the_common_shift(log):
    v = np.array([1.0, 0, 0, 1.0, 0, 0])
    shift = {sub: 1 / np.sqrt(np.einsum("i,kij,j->k", v, np.linalg.inv(compute_coop_demo(log, "ekf", measurements=sub).P), v))
             for sub in [(0, 1, 2), (0, 2, 3, 4)]}
    # without the GPS nothing shrinks the common shift: it only grows (by the process noise dt^2 Qtrue per
    # step and the heading errors); with the GPS it shrinks below its initial value
    assert np.all(np.diff(shift[(0, 1, 2)]) >= -1e-9) and shift[(0, 1, 2)][-1] > 1.3 * shift[(0, 1, 2)][0]
    assert shift[(0, 2, 3, 4)][-1] < 0.8 * shift[(0, 2, 3, 4)][0] < shift[(0, 1, 2)][-1]


@pytest.mark.parametrize("kwargs, name", [({"filter": "lkf"}, "filter"), ({"q_scale": 0.0}, "q_scale"),
                                          ({"measurements": (7,)}, "measurements"), ({"alpha": 0.0}, "alpha")])
def test_compute_coop_demo_validates(log, kwargs, name):
    with pytest.raises(ValueError, match=name):
        compute_coop_demo(log, **kwargs)
    with pytest.raises(ValueError, match="log"):
        compute_coop_demo(log.y)


def test_coop_figure_and_controls(log):
    view = CoopDemoFigure(Figure(figsize=(11, 5.4)))
    lines = [tuple(ax.lines) for ax in view.axes.flat]
    view.update(compute_coop_demo(log, "ekf", measurements=(3, 4)))
    assert [tuple(ax.lines) for ax in view.axes.flat] == lines and len(lines) == 6
    d = compute_coop_demo(log, "ekf", measurements=(3, 4))
    title = view.fig.get_suptitle()
    assert "UAV GPS east" in title and f"(2 dof per update, {d.n_nis} updates): {d.nis_verdict} [" in title
    assert d.nis_verdict in ("inside", "below", "above") and (d.nis_verdict == "inside") == d.nis_inside
    assert all("[" in ax.get_ylabel() for ax in view.axes.flat)
    # the rows say which vehicle: UGV on top, UAV below
    assert [ax.get_ylabel().split()[0] for ax in view.axes.flat] == ["UGV"] * 3 + ["UAV"] * 3
    assert figure_png(view.fig)[:4] == b"\x89PNG"
    # the live view renders only what a change alters (x axes kept): the same image as a full draw
    assert fast_draw_is_full_draw(view)
    view.update(compute_coop_demo(log, "ekf", q_scale=0.05, measurements=(0, 1, 2)))
    assert fast_draw_is_full_draw(view) and view.background.full_draws == 1
    assert len(draw_coop_demo(compute_coop_demo(log)).axes) == 6
    c = coop_controls()
    assert set(c) == {"filter", "q_scale", "m0", "m1", "m2", "m3", "m4"}
    assert c["filter"].value == "ekf" and c["q_scale"].value == pytest.approx(TUNED_Q_SCALE["ekf"])
    assert [c[f"m{i}"].description for i in range(5)] == list(MEASUREMENT_NAMES)


def test_coop_slider_defaults_are_stops_of_their_sliders():
    # a default between two stops is moved to the nearest one by the browser when it draws the slider
    assert off_grid_defaults(coop_controls()) == []




# ---------------------------------------------------------------------------
# exercise checks 18.1, 18.2
def _rejected(fb, exercise, key):
    return (not fb.correct) and fb.answered and fb.message == EXERCISES[exercise].hints[key]



def test_check_18_1_subset_nis_bounds():
    K, m = 1000, 3
    right = stats.chi2.ppf([0.025, 0.975], m * K) / K
    assert check_subset_nis_bounds(right).correct
    wrong = {
        "dim5": stats.chi2.ppf([0.025, 0.975], 5 * K) / K,
        "dim6": stats.chi2.ppf([0.025, 0.975], 6 * K) / K,   # the state's dimension
        "count_nan": stats.chi2.ppf([0.025, 0.975], m * (K + 1)) / (K + 1),
        "not_divided": stats.chi2.ppf([0.025, 0.975], m * K),
        "one_sided": stats.chi2.ppf([0.05, 0.95], m * K) / K,
        "normal": m + np.array([-1, 1]) * 1.959964 * np.sqrt(2 * m / K),
    }
    for key, value in wrong.items():
        assert _rejected(check_subset_nis_bounds(value), "18.1", key), key
    assert not check_subset_nis_bounds(...).answered and not check_subset_nis_bounds("bounds").correct
    with pytest.raises(ValueError, match="n_meas"):
        check_subset_nis_bounds(right, n_meas=6)


def _lost_directions_independently(rows, window=10):
    """6 - rank by my own stacking (exact one-step Jacobian by finite differences) and an SVD gap,
    and the common translations and the rotation of the whole scene checked as null vectors."""
    p = CoopParams()
    x = nominal_trajectory(p, window)
    blocks, Phi, e = [], np.eye(6), 1e-6
    for k in range(window):
        blocks.append(jacobian_C(x[k])[rows] @ Phi)
        J = np.stack([measurement_free_diff(x[k], j, e, p) for j in range(6)], axis=1)
        Phi = J @ Phi
    O = np.vstack(blocks)
    sv = np.linalg.svd(O, compute_uv=False)
    lost = 6 - int(np.sum(sv > 1e-6 * sv[0]))
    shifts = np.array([[1.0, 0, 0, 1.0, 0, 0], [0, 1.0, 0, 0, 1.0, 0],
                       [-x[0, 1], x[0, 0], 1.0, -x[0, 4], x[0, 3], 1.0]])  # translations, rotation about 0
    return lost, np.abs(O @ shifts.T).max() / sv[0]


def measurement_free_diff(xk, j, e, p):
    """Central difference of the exact one-step map along state j (headings wrapped)."""
    from kfcal_helpers.coop import state_residual, step

    d = np.eye(6)[j] * e
    return state_residual(step(xk + d, p.u0, p.dt, p.L), step(xk - d, p.u0, p.dt, p.L)) / (2 * e)


def test_check_18_2_lost_directions():
    counts = []
    for rows in ([1, 3, 4], [0, 1, 2, 3], [0, 2]):  # no bearings, no GPS north, bearings only
        lost, null_residual = _lost_directions_independently(rows)
        counts.append(lost)
        if rows == [0, 2]:  # bearings only: both common shifts and the rotation change no measurement
            assert null_residual < 1e-8
    assert counts == [0, 1, 3]
    # a common shift and a rotation of the whole scene change no relative measurement of the nonlinear model
    x = nominal_trajectory(CoopParams(), 5)
    assert np.allclose(measure(x + [3.0, -2.0, 0, 3.0, -2.0, 0])[:, :3], measure(x)[:, :3], atol=1e-12)
    c, s_ = np.cos(0.3), np.sin(0.3)
    rot = x.copy()
    for i in (0, 3):
        rot[:, i], rot[:, i + 1] = c * x[:, i] - s_ * x[:, i + 1], s_ * x[:, i] + c * x[:, i + 1]
        rot[:, i + 2] = x[:, i + 2] + 0.3
    assert np.allclose(measurement_residual(measure(rot)[:, :3], measure(x)[:, :3]), 0, atol=1e-12)
    assert check_lost_directions(counts).correct and check_lost_directions(np.array(counts, float)).correct
    wrong = {"ranks": [6, 5, 3], "euler": [0, 1, 2], "north_observable": [0, 0, 3], "north_both_lost": [0, 2, 3],
             "bearings_observable": [0, 1, 0], "bearings_scale_lost": [0, 1, 4], "no_bearings_lost": [1, 1, 3],
             "reversed": [3, 1, 0]}
    for key, value in wrong.items():
        assert _rejected(check_lost_directions(value), "18.2", key), key
    assert "whole number" in check_lost_directions([0, 1.5, 3]).message
    assert not check_lost_directions(...).answered and not check_lost_directions([0, 2]).correct
    with pytest.raises(ValueError, match="window"):
        check_lost_directions(counts, window=1)


# ---------------------------------------------------------------------------
# live demos: argument checks, layout, failures drawn as a one-line message
# ---------------------------------------------------------------------------
# the live demo
def coop_demo_for(log):
    """Notebook 18's mapping of the controls to compute_coop_demo, for ``log``."""
    def demo_for(filter="ekf", q_scale=1.5, m0=True, m1=True, m2=True, m3=True, m4=True):
        ticked = tuple(i for i, on in enumerate((m0, m1, m2, m3, m4)) if on)
        return compute_coop_demo(log, filter, q_scale, measurements=ticked) if ticked else None
    return demo_for


def _coop_live(log):
    return LiveDemo(coop_controls(), coop_demo_for(log), CoopDemoFigure(Figure(figsize=LIVE_FIGSIZE)),
                    empty="tick at least one measurement", hint="try a smaller Q / Qtrue")




def test_live_demo_shows_the_figure_and_follows_the_controls(log):
    live = _coop_live(log)
    assert not live.failed and "5 measurements" in live.line.value
    first = live.image.value
    assert png_size(first) == tuple(round(s * live.view.fig.dpi) for s in LIVE_FIGSIZE)
    live.controls["m1"].value = False  # untick the range: the observer recomputes and redraws
    assert not live.failed and live.image.value != first
    assert "4 measurements" in live.line.value and "range" not in live.view.fig.get_suptitle().split("\n")[0]
    # the layout: the controls in wrapping rows above the image, the line under it
    import ipywidgets as w

    bar, image, line = live.widget.children
    assert isinstance(live.widget, w.VBox) and list(bar.children) == list(live.controls.values())
    assert (image, line) == (live.image, live.line)


@pytest.mark.parametrize("error, says", [
    (np.linalg.LinAlgError("6-th leading minor of the array is not positive definite"),
     "its covariance is no longer positive definite (6-th leading minor"),
    (ValueError("Singular matrix"), "cannot compute these settings: Singular matrix"),
    (FloatingPointError("overflow encountered"), "cannot compute these settings: overflow encountered"),
    (RuntimeWarning("invalid value encountered in sqrt"), "(RuntimeWarning: invalid value encountered in sqrt)")])
def test_a_failing_filter_draws_a_one_line_message(log, monkeypatch, error, says):
    import warnings

    import kfcal_helpers.coop.demos as demos

    live = _coop_live(log)
    good = live.image.value

    def fail(*args, **kwargs):
        if isinstance(error, Warning):
            warnings.warn(error)  # raised as an error inside a redraw, never shown
            return run_filter_fast(*args, **kwargs)
        raise error

    monkeypatch.setattr(demos, "run_filter_fast", fail)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning may escape the redraw
        live.controls["filter"].value = "ukf"
        live.controls["q_scale"].value = 10 ** 0.5
    assert live.failed
    line = live.line.value
    assert says in line
    assert "Traceback" not in line and "\n" not in line and "try a smaller Q / Qtrue" in line
    # the image: same size, no axes, the settings of the failed redraw as its title, one line of message
    fig = live.message_fig
    assert png_size(live.image.value) == png_size(good) and live.image.value != good
    message = [t.get_text() for t in fig.texts if t.get_text() != fig.get_suptitle()]
    assert not fig.axes and len(message) == 1 and "\n" not in message[0] and message[0] in line
    title = fig.get_suptitle()
    assert "filter UKF" in title and "Q / Qtrue 3.16" in title and "not drawn" in title
    assert all(name in title for name in MEASUREMENT_NAMES)
    # the next setting that works draws the filter again, under its own title
    monkeypatch.undo()
    live.controls["filter"].value = "ekf"
    assert not live.failed and live.view.fig.get_suptitle().startswith("EKF, Q = 3.16 Qtrue")


def test_non_finite_results_and_empty_subsets_draw_a_message(log, monkeypatch):
    import dataclasses

    live = _coop_live(log)
    real = live.compute

    def nan_errors(**values):
        d = real(**values)
        return dataclasses.replace(d, errors=np.full_like(d.errors, np.nan))

    live.compute = nan_errors
    live.refresh()
    assert live.failed and "not finite" in live.line.value
    live.compute = real
    for i in range(5):
        live.controls[f"m{i}"].value = False
    assert live.failed and "tick at least one measurement" in live.line.value
    assert "none ticked" in live.message_fig.get_suptitle()


def test_an_unexpected_error_is_one_line_too(log):
    live = _coop_live(log)

    def broken(**values):
        raise KeyError("x")

    live.compute = broken
    live.refresh()  # a live demo never shows a traceback
    assert live.failed and "unexpected error" in live.line.value and "KeyError" in live.line.value
    with pytest.raises(KeyError):
        live.render()  # ... but the render path itself does not hide programming errors


def test_describe_controls():
    c = coop_controls()
    c["m0"].value = c["m2"].value = False
    assert describe_controls(c) == f"filter EKF; Q / Qtrue {TUNED_Q_SCALE['ekf']:g}; on: range, UAV GPS east, UAV GPS north"
    assert describe_controls(c, {"filter": "ukf", "m1": False, "m3": False, "m4": False}).endswith("on: none ticked")




#: slider positions (the ends, the default, and 2.51 and 3.16, where the UKF lost positive definiteness
#: without the bearing UGV->UAV and with the GPS alone) and measurement subsets of the grid
COOP_Q_POSITIONS = (0.01, 1.0, 10 ** 0.4, 10 ** 0.5, 100.0)
COOP_SUBSETS = {"all five": (0, 1, 2, 3, 4), "no bearing UGV->UAV": (1, 2, 3, 4), "GPS only": (3, 4)}


@pytest.mark.parametrize("filter", ["ekf", "ukf"])
def test_coop_demo_over_a_grid_of_controls(log, filter):
    live = _coop_live(log)
    positions = COOP_Q_POSITIONS if filter == "ukf" else (0.01, 100.0)
    outcome = {}
    for q in positions:
        for label, subset in COOP_SUBSETS.items():
            values = {"filter": filter, "q_scale": q, **{f"m{i}": i in subset for i in range(5)}}
            ok = outcome[q, label] = check_render(live, values)
            if ok:
                assert legend_is_outside_the_panels(live.view)
                title = live.view.fig.get_suptitle()
                assert title.startswith(f"{filter.upper()}, Q = {q:.3g} Qtrue, measurements: "
                                        + ", ".join(MEASUREMENT_NAMES[i] for i in subset) + "\n")
    print(filter, "combinations not drawn:", [k for k, ok in outcome.items() if not ok])
    assert filter == "ekf" or outcome[1.0, "all five"]  # the UKF's tuned defaults draw



def test_the_live_view_is_shown_pixel_for_pixel_and_readable(log):
    """The live figure fits the notebook's width in JupyterLab's default layout at 1280x800 (so it is
    not scaled down) and its smallest text is at least MIN_TEXT_PX on screen."""
    import matplotlib as mpl

    from kfcal_helpers.demos import MIN_TEXT_PX, NOTEBOOK_WIDTH_PX, smallest_text
    from kfcal_helpers.style import style_params

    with mpl.rc_context(style_params()):  # the notebooks' style (90 dpi), as in notebooks 17 and 18
        view = CoopDemoFigure(Figure(figsize=LIVE_FIGSIZE))
        view.update(compute_coop_demo(log, "ekf"))
        view.draw()
    width, height = view.fig.canvas.get_width_height()
    points, text = smallest_text(view.fig)
    assert width <= NOTEBOOK_WIDTH_PX and height <= 0.7 * width, (width, height)
    assert points * view.fig.dpi / 72 >= MIN_TEXT_PX, (text, points, view.fig.dpi)
