"""The calibration lecture demo (notebook 17): the compute function against the filters by other
routes, the figure and the controls, the live demo over a grid of controls, and the exercise checks.
(The engine functions the demo calls, the error recursion and the draws at the fixes, are tested in
tests/test_calibration_engine.py.)"""

import numpy as np
import pytest
from matplotlib.figure import Figure
from scipy import stats

from kfcal_helpers.calibration import (CalibrationParams, covariance_sequence, outage_mask, run_filterpy, simulate)
from kfcal_helpers.calibration.demos import (LIVE_FIGSIZE, W_STOPS, CalibrationDemo, CalibrationDemoFigure,
                                             calibration_controls, compute_calibration_demo, draw_calibration_demo,
                                             valid_gps_rates)
from kfcal_helpers.calibration.exercises import (EXERCISES, check_demo_first_fix_sigma, check_demo_ratio_band,
                                                 first_fix_sigmas)
from kfcal_helpers.demos import LiveDemo, describe_controls, figure_png
from kfcal_helpers.exercises import ROUNDED_HINT

from demo_checks import check_render, fast_draw_is_full_draw, legend_is_outside_the_panels, off_grid_defaults

P = CalibrationParams()
HINTS = {i: EXERCISES[i].hints for i in ("17.1", "17.2")}


def test_valid_gps_rates_divide_the_imu_rate():
    assert valid_gps_rates() == tuple(float(r) for r in range(1, 26) if 200 % r == 0)
    for r in valid_gps_rates(max_rate=200.0):
        assert CalibrationParams(gps_rate=r).steps_per_fix * r == 200
    assert valid_gps_rates(100.0, 100.0)[-1] == 100.0
    with pytest.raises(ValueError, match="imu_rate"):
        valid_gps_rates(200.5)


def test_demo_sigma_is_the_filters_and_its_realization_is_filterpys():
    demo = compute_calibration_demo(gps_rate=4.0, W=1e-3, gps_pos_var=2.0, bias_var=0.02, outage=(9.0, 14.0), seed=3)
    p = P.replace(gps_rate=4.0, W=1e-3, gps_pos_var=2.0, bias_var=0.02)
    missing = outage_mask(p, [(9.0, 14.0)])
    assert np.array_equal(demo.missing, missing)
    P_seq, P_prior, _, _ = covariance_sequence(p, missing)
    assert np.allclose(demo.sigma, np.sqrt(np.einsum("jaa->ja", P_seq)), rtol=1e-9, atol=0)
    assert np.allclose(demo.P_post, P_seq[p.fix_indices], rtol=1e-9, atol=0)
    assert np.allclose(demo.P_prior, P_prior, rtol=1e-9, atol=0)
    # the drawn realization: the demo's first seeded stream, filtered by filterpy instead
    rng = np.random.default_rng(np.random.SeedSequence(3).spawn(2)[0])
    sim = simulate(p, 1, rng, missing_fixes=missing)
    fp = run_filterpy(p, sim.dz[0])
    assert np.allclose(demo.error, sim.dx[0] - fp.x, rtol=0, atol=1e-8)


@pytest.mark.parametrize("ensemble", ["fixes", "simulate"])
def test_ensemble_sigma_within_its_chi2_band(ensemble):
    demo = compute_calibration_demo(outage=(10.0, 16.0), n_runs=300, seed=11, ensemble=ensemble)
    N = demo.n_runs
    assert demo.ratio_band == pytest.approx(np.sqrt(stats.chi2.ppf([0.025, 0.975], N - 1) / (N - 1)), rel=1e-12)
    # simultaneous (Bonferroni) band over all fixes and states: a right P passes with probability >= 0.95
    level = 0.05 / demo.ratio.size
    lo, hi = np.sqrt(stats.chi2.ppf([level / 2, 1 - level / 2], N - 1) / (N - 1))
    assert np.all((demo.ratio > lo) & (demo.ratio < hi))
    z = stats.norm.ppf(1 - level / 2)
    assert np.all(np.abs(demo.ens_mean) < z * demo.ens_std / np.sqrt(N))
    assert 0.8 < demo.inside_fraction <= 1.0


def test_outage_grows_sigma_and_the_first_fix_back_cuts_it():
    demo = compute_calibration_demo(outage=(12.0, 18.0))
    clear = compute_calibration_demo()
    j0, j1 = int(12.0 * P.imu_rate) - P.steps_per_fix, int(18.0 * P.imu_rate)  # last fix before, first fix back
    s = demo.sigma
    assert np.all(np.diff(s[j0:j1, 0]) > 0) and np.all(np.diff(s[j0:j1, 1]) > 0)
    assert np.allclose(s[j0:j1, 2], s[j0, 2], rtol=1e-12)  # nothing drives the bias in the gap
    assert s[j1, 0] < s[j1 - 1, 0] and s[j1, 1] < s[j1 - 1, 1]
    assert np.all(s[j0 + 1:j1 + 1] >= clear.sigma[j0 + 1:j1 + 1] - 1e-15)
    assert s[j1 - 1, 0] > 1.2 * clear.sigma[j1 - 1, 0]


def test_slider_effects_go_the_stated_way():
    slow, fast = compute_calibration_demo(gps_rate=1.0), compute_calibration_demo(gps_rate=25.0)
    saw = [np.sqrt(d.P_prior[:, 1, 1] / d.P_post[:, 1, 1])[np.searchsorted(d.t_gps, 2.0 - 1e-9)] for d in (slow, fast)]
    assert saw[0] > saw[1] > 1.0
    low_w, high_w = compute_calibration_demo(W=4e-5), compute_calibration_demo(W=4e-3)
    assert high_w.sigma[-1, 2] > low_w.sigma[-1, 2]
    assert np.all(np.diff(high_w.sigma_fix[:, 2]) < 0)  # still shrinking: no floor


@pytest.mark.parametrize("kwargs, name", [
    ({"gps_rate": 3.0}, "gps_rate"), ({"W": -1.0}, "W"), ({"gps_pos_var": 0.0}, "gps_pos_var"),
    ({"bias_var": np.nan}, "bias_var"), ({"outage": (20.0, 10.0)}, "outage"), ({"outage": (25.0, 40.0)}, "outage"),
    ({"outage": 5.0}, "outage"), ({"n_runs": 1}, "n_runs"), ({"seed": -1}, "seed"), ({"ensemble": "mc"}, "ensemble"),
    ({"alpha": 1.5}, "alpha"), ({"base": "defaults"}, "base"),
])
def test_compute_calibration_demo_validates(kwargs, name):
    with pytest.raises(ValueError, match=name):
        compute_calibration_demo(**kwargs)


def test_calibration_figure_updates_in_place():
    view = CalibrationDemoFigure(Figure(figsize=(9, 7.2)))
    assert len(view.fig.axes) == 3
    lines = [tuple(ax.lines) for ax in view.axes]
    view.update(compute_calibration_demo(outage=(12.0, 18.0), n_runs=50))
    view.update(compute_calibration_demo(gps_rate=2.0, outage=(5.0, 8.0), n_runs=50))
    assert [tuple(ax.lines) for ax in view.axes] == lines  # the same artists, new data
    assert len(view.spans) == 3 and len(view.axes[0].patches) == 1
    assert view.axes[0].lines[0].get_xdata().size == P.n_imu
    title = view.fig.get_suptitle()
    assert "GPS 2 Hz" in title and "outage 5–8 s" in title
    # the ensemble's share is about all three panels: in the figure's title, not over one panel
    assert "\nEnsemble, all three panels: s/σ inside [" in title and "of (GPS epoch, state) pairs" in title
    assert all(ax.get_title(loc) == "" for ax in view.axes for loc in ("left", "center", "right"))
    assert view.note.get_text() == "y axes scaled to t ≥ 2 s"
    for ax in view.axes:
        assert "[" in ax.get_ylabel()
    assert "[s]" in view.axes[-1].get_xlabel()
    png = figure_png(view.fig)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    fig = draw_calibration_demo(compute_calibration_demo(n_runs=20))
    assert len(fig.axes) == 3 and "GPS 5 Hz" in fig.get_suptitle()
    assert draw_calibration_demo(compute_calibration_demo(n_runs=20), t_zoom=0.0).texts[0].get_text() == ""
    with pytest.raises(ValueError, match="demo"):
        view.update("demo")
    with pytest.raises(ValueError, match="figure"):
        CalibrationDemoFigure(figure="fig")


def test_calibration_fast_draw_is_the_full_draw():
    # the live view renders only what a slider move changes (x axes kept): the same image as a full draw
    view = CalibrationDemoFigure(Figure(figsize=LIVE_FIGSIZE))
    for kw in ({"outage": (12.0, 18.0)}, {"gps_rate": 25.0}, {"gps_rate": 1.0, "outage": (0.0, 30.0)},
               {"W": 1e-6, "gps_pos_var": 0.01, "bias_var": 1e-6}):
        view.update(compute_calibration_demo(n_runs=200, **kw))  # the live demo's 200 runs: the legend stays
        assert fast_draw_is_full_draw(view)
        assert len(view.spans) == (3 if "outage" in kw else 0)
        assert all(s.get_visible() == ("outage" in kw) for s in view.axes[0].patches)
    assert view.background.full_draws == 1
    live = LiveDemo(calibration_controls(), calibration_demo_for, view)
    live.controls["W"].value = 1e-3
    assert not live.failed and live.image.value == figure_png(view.fig) and view.background.full_draws == 1
    # the kept background holds the legend and the note: a change of their text renders it again
    view.update(compute_calibration_demo(n_runs=20))
    assert "(20 realizations)" in view.legend.get_texts()[2].get_text() and fast_draw_is_full_draw(view)
    assert view.background.full_draws == 2


def test_calibration_demo_keeps_its_draws_not_its_numbers():
    # the ensemble's standard normals are kept across redraws; the numbers are those of fresh draws
    from kfcal_helpers.calibration.engine import filter_errors_time_major, noise_of_simulation, sample_noise_time_major

    for kw in ({"W": 1e-3}, {"W": 2e-4, "outage": (3.0, 9.0)}):
        demo = compute_calibration_demo(gps_rate=4.0, n_runs=30, seed=5, **kw)
        p = P.replace(gps_rate=4.0, W=kw["W"])
        missing = demo.missing
        rng_one, rng_ens = (np.random.default_rng(s) for s in np.random.SeedSequence(5).spawn(2))
        sim = simulate(p, 1, rng_one, missing_fixes=missing)
        e0, w_t, eta_t = sample_noise_time_major(p, 30, rng_ens)
        one = noise_of_simulation(sim)
        e_post = filter_errors_time_major(p, covariance_sequence(p, missing), np.concatenate([one[0], e0]),
                                          np.concatenate([one[1].transpose(1, 0, 2), w_t], axis=1),
                                          np.concatenate([one[2].transpose(1, 0, 2), eta_t], axis=1))[1]
        assert np.allclose(demo.ens_std, e_post[:, 1:].std(axis=1, ddof=1), rtol=1e-12, atol=0)
        assert np.allclose(demo.ens_mean, e_post[:, 1:].mean(axis=1), rtol=1e-12, atol=1e-15)


def test_calibration_controls_match_the_compute_function():
    c = calibration_controls()
    assert set(c) == {"gps_rate", "W", "gps_pos_sigma", "bias_sigma", "outage_on", "outage"}
    assert tuple(c["gps_rate"].options) == valid_gps_rates()
    v = {k: w.value for k, w in c.items()}
    assert (v["gps_rate"], v["W"], v["gps_pos_sigma"] ** 2, v["bias_sigma"] ** 2) == (P.gps_rate, P.W, P.gps_pos_var,
                                                                                      pytest.approx(P.bias_var))
    assert P.W in W_STOPS and len(W_STOPS) == 41 and np.all(np.diff(W_STOPS) > 0)
    # the stops are those of a log slider of ten steps a decade, rounded to the R10 preferred numbers
    assert np.allclose(np.log10(W_STOPS), np.linspace(-6, -2, 41), rtol=0, atol=0.005)


def test_calibration_slider_defaults_are_stops_of_their_sliders():
    # a default between two stops is moved to the nearest one by the browser when it draws the slider
    # (W = 4e-4 on a log slider of 0.1-decade steps became 10 ** -3.4 = 3.98e-4, and the live figure showed
    # other numbers than the lesson's)
    assert off_grid_defaults(calibration_controls()) == []



# ---------------------------------------------------------------------------
# exercise checks
def _rejected(fb, exercise, key):
    return (not fb.correct) and fb.answered and fb.message == HINTS[exercise][key]


def test_check_17_1_first_fix_sigma():
    # default M0, V with sigma_p = sqrt(10) m: the slider's stop 10^0.5 (V[0, 0] = 10 m^2)
    right = np.sqrt([1 / (1 / 100 + 1 / 10), 1 / (1 / 1 + 1 / 0.0016), 0.01])
    assert check_demo_first_fix_sigma(right).correct
    assert check_demo_first_fix_sigma(list(right)).correct
    demo = compute_calibration_demo(gps_pos_var=10.0, n_runs=10)
    assert np.allclose(demo.sigma[0], right, rtol=1e-12)  # what the slider shows
    stops = 10 ** (-1 + 0.05 * np.arange(41))              # the GPS sigma slider's stops (log scale)
    slider = calibration_controls()["gps_pos_sigma"]
    assert (slider.min, slider.max, slider.step, slider.base, slider.readout_format) == (-1, 1, 0.05, 10, ".2f")
    assert np.isclose(stops, 10**0.5, rtol=1e-12).any() and not np.isclose(stops, 3.0, rtol=1e-3).any()
    assert check_demo_first_fix_sigma(first_fix_sigmas(stops[30])).correct   # the stop dragged to, 10^(-1 + 30 * 0.05)
    r10 = np.sqrt(10)
    wrong = {
        "gps_only": [r10, 0.04, 0.1],
        "sigma_sum": [1 / (1 / 10 + 1 / r10), 1 / (1 + 1 / 0.04), 0.1],
        "variance": right**2,
        "variance_sum": [np.sqrt(110), np.sqrt(1.0016), 0.1],
        "prior": [10.0, 1.0, 0.1],
        "default_gps": np.sqrt([1 / (1 / 100 + 1), 1 / (1 + 1 / 0.0016), 0.01]),
        "bias": [right[0], right[1], 0.05],
        "rounded_readout": np.sqrt([1 / (1 / 100 + 1 / 3.16**2), 1 / (1 + 1 / 0.0016), 0.01]),  # sigma_p 3.0131
    }
    for key, value in wrong.items():
        assert _rejected(check_demo_first_fix_sigma(value), "17.1", key), key
    # sigma_p computed from the 3.16 readout is 6.6e-4 (relative) below the right one: a small difference of method
    # (not a rounding of the right value), which gets its own hint, also when copied to 4 significant digits
    assert 1e-4 < abs(wrong["rounded_readout"][0] / right[0] - 1) < 1e-3
    four_digits = lambda a: [float(f"{x:.4g}") for x in a]  # noqa: E731
    assert four_digits(wrong["rounded_readout"]) == [3.013, 0.03997, 0.1]
    assert _rejected(check_demo_first_fix_sigma(four_digits(wrong["rounded_readout"])), "17.1", "rounded_readout")
    # the one format rule: the computed value, no rounding; the right value rounded is told so
    assert check_demo_first_fix_sigma(four_digits(right)).message == ROUNDED_HINT  # [3.015, 0.03997, 0.1]
    near = check_demo_first_fix_sigma([3.0156, 0.03997, 0.1])   # near, but no rounding: the entry that is off named
    assert not near.correct and near.message != ROUNDED_HINT and "σ_p" in near.message
    assert not check_demo_first_fix_sigma(...).answered
    for bad in ("3.015", [1.0, 2.0], None):
        fb = check_demo_first_fix_sigma(bad)
        assert not fb.correct
    assert check_demo_first_fix_sigma(np.sqrt([1 / (1 / 100 + 1 / 4), 1 / (1 + 625), 0.01]), gps_pos_sigma=2.0).correct
    with pytest.raises(ValueError, match="gps_pos_sigma"):
        check_demo_first_fix_sigma(right, gps_pos_sigma=0.0)


def test_check_17_2_ratio_band():
    N = 200
    right = np.sqrt(stats.chi2.ppf([0.025, 0.975], N - 1) / (N - 1))
    assert check_demo_ratio_band(right).correct
    # rounded to any number of decimals, it is told to pass the computed value, never accused of a mistake
    # (rounded to 3 decimals it is also the N-degrees-of-freedom band rounded: [0.902, 1.098] both)
    for decimals in (3, 4, 5):
        assert check_demo_ratio_band(np.round(right, decimals)).message == ROUNDED_HINT, decimals
    demo = compute_calibration_demo(n_runs=N)
    assert np.allclose(demo.ratio_band, right, rtol=1e-12)
    wrong = {
        "n_dof": np.sqrt(stats.chi2.ppf([0.025, 0.975], N) / N),
        "variance": stats.chi2.ppf([0.025, 0.975], N - 1) / (N - 1),
        "one_sided": np.sqrt(stats.chi2.ppf([0.05, 0.95], N - 1) / (N - 1)),
        "normal": 1 + np.array([-1, 1]) * stats.norm.ppf(0.975) / np.sqrt(2 * (N - 1)),
        "mean_band": 1 + np.array([-1, 1]) * stats.norm.ppf(0.975) / np.sqrt(N),
    }
    for key in ("normal", "mean_band"):  # with the usual z = 1.96 too
        assert _rejected(check_demo_ratio_band(1 + (wrong[key] - 1) * 1.96 / stats.norm.ppf(0.975)), "17.2", key)
    for key, value in wrong.items():
        assert _rejected(check_demo_ratio_band(value), "17.2", key), key
    assert not check_demo_ratio_band(...).answered and not check_demo_ratio_band([0.9]).correct
    with pytest.raises(ValueError, match="n_runs"):
        check_demo_ratio_band(right, n_runs=1)



# ---------------------------------------------------------------------------
# live demo
def test_draw_calibration_demo_rejects_a_negative_t_zoom():
    demo = compute_calibration_demo(n_runs=20)
    for bad in (-1, -0.5, float("nan"), "2"):
        with pytest.raises(ValueError, match="t_zoom"):
            draw_calibration_demo(demo, t_zoom=bad)
    assert len(draw_calibration_demo(demo, t_zoom=0.0).axes) == 3


def calibration_demo_for(gps_rate=5.0, W=4e-4, gps_pos_sigma=1.0, bias_sigma=0.1, outage_on=True,
                         outage=(12.0, 18.0)):
    """Notebook 17's mapping of the controls to compute_calibration_demo."""
    window = outage if outage_on and outage[0] < outage[1] else None
    return compute_calibration_demo(gps_rate=gps_rate, W=W, gps_pos_var=gps_pos_sigma**2, bias_var=bias_sigma**2,
                                    outage=window, n_runs=200, seed=17)




def test_live_demo_validates():
    with pytest.raises(ValueError, match="controls"):
        LiveDemo({}, calibration_demo_for, CalibrationDemoFigure(Figure()))
    with pytest.raises(ValueError, match="compute"):
        LiveDemo(calibration_controls(), None, CalibrationDemoFigure(Figure()))
    with pytest.raises(ValueError, match="view"):
        LiveDemo(calibration_controls(), calibration_demo_for, Figure())


def test_demo_declares_its_finite_fields():
    demo = compute_calibration_demo(n_runs=20)
    assert CalibrationDemo.finite_fields == ("error", "sigma", "ens_std", "P_post")
    assert all(np.all(np.isfinite(getattr(demo, name))) for name in CalibrationDemo.finite_fields)
    import dataclasses

    assert "finite_fields" not in {f.name for f in dataclasses.fields(CalibrationDemo)}  # a class attribute


def test_calibration_live_demo_non_finite_result_draws_a_message():
    import dataclasses

    live = LiveDemo(calibration_controls(), calibration_demo_for,
                    CalibrationDemoFigure(Figure(figsize=LIVE_FIGSIZE)))
    assert not live.failed

    def nan_sigma(**values):
        d = calibration_demo_for(**values)
        return dataclasses.replace(d, sigma=np.full_like(d.sigma, np.nan))

    live.compute = nan_sigma
    live.refresh()
    assert live.failed and "not finite" in live.line.value and "sigma" in live.line.value


def test_describe_calibration_controls():
    assert describe_controls(calibration_controls()) == ("GPS rate [Hz] 5; IMU noise W [(m/s²)²] 0.0004; GPS σ [m] 1; "
                                                         "bias prior σ [m/s²] 0.1; outage window [s] 12–18; on: GPS outage")




def test_calibration_demo_over_a_grid_of_controls():
    live = LiveDemo(calibration_controls(), calibration_demo_for,
                    CalibrationDemoFigure(Figure(figsize=LIVE_FIGSIZE)))
    c = live.controls
    corners = [{"W": c["W"].options[0][1], "gps_pos_sigma": 10.0 ** c["gps_pos_sigma"].min,
                "bias_sigma": 10.0 ** c["bias_sigma"].min},
               {"W": c["W"].options[-1][1], "gps_pos_sigma": 10.0 ** c["gps_pos_sigma"].max,
                "bias_sigma": 10.0 ** c["bias_sigma"].max}]
    outages = [(False, (12.0, 18.0)), (True, (0.0, 30.0)), (True, (0.0, 0.5)), (True, (29.5, 30.0)),
               (True, (10.0, 10.0))]
    for rate in (c["gps_rate"].options[0], c["gps_rate"].options[-1]):
        for corner in corners:
            for on, window in outages:
                values = {"gps_rate": rate, **corner, "outage_on": on, "outage": window}
                if check_render(live, values):
                    assert legend_is_outside_the_panels(live.view)
                    title = live.view.fig.get_suptitle().split("\n")[0]
                    assert f"GPS {rate:g} Hz" in title and (("outage" in title) == (on and window[0] < window[1]))


def test_the_live_view_is_shown_pixel_for_pixel_and_readable():
    """The live figure fits the notebook's width in JupyterLab's default layout at 1280x800 (so it is
    not scaled down) and its smallest text is at least MIN_TEXT_PX on screen."""
    import matplotlib as mpl

    from kfcal_helpers.demos import MIN_TEXT_PX, NOTEBOOK_WIDTH_PX, smallest_text
    from kfcal_helpers.style import style_params

    with mpl.rc_context(style_params()):  # the notebooks' style (90 dpi), as in notebooks 17 and 18
        view = CalibrationDemoFigure(Figure(figsize=LIVE_FIGSIZE))
        view.update(compute_calibration_demo(outage=(12.0, 18.0)))
        view.draw()
    width, height = view.fig.canvas.get_width_height()
    points, text = smallest_text(view.fig)
    assert width <= NOTEBOOK_WIDTH_PX and height <= 0.7 * width, (width, height)
    assert points * view.fig.dpi / 72 >= MIN_TEXT_PX, (text, points, view.fig.dpi)
