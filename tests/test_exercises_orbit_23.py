"""Exercise checks of notebook 23 (kfcal_helpers.orbit.exercises, 23.1-23.2).

For every check: (1) it accepts the right answer, computed here by another route than the check's (the
chi-square quantile as the gamma distribution's, shape dof/2 and scale 2, by scipy.special.gammaincinv);
(2) it rejects each listed wrong answer, built here by making the mistake, with that mistake's hint; (3) the
placeholder gives "not answered yet"; (4) a rounded copy and bad settings get their own answers.
"""

from pathlib import Path

import numpy as np
import pytest
from scipy.special import gammaincinv

from kfcal_helpers.exercises._core import ROUNDED_HINT
from kfcal_helpers.orbit import exercises as ex
from kfcal_helpers.orbit.exercises import _shared


def hint(exercise, key):
    return ex.EXERCISES[exercise].hints[key]


def chi2_quantile(q, dof):
    """The chi-square(dof) quantile q: 2 x the regularized lower incomplete gamma's inverse at dof/2."""
    return 2.0 * gammaincinv(dof / 2.0, q)


def band(dof, n, alpha, tails=2):
    a = alpha / tails
    return np.array([chi2_quantile(a, dof), chi2_quantile(1 - a, dof)]) / n


ONE, TWO, EMPTY, ALPHA = _shared.LOG_ONE_STATION, _shared.LOG_TWO_STATIONS, _shared.LOG_EMPTY_STEPS, _shared.LOG_ALPHA
N_UPD, D = ONE + TWO, 3 * ONE + 6 * TWO
RIGHT_23_1 = band(D, N_UPD, ALPHA)
M, LOG_STEP_ALPHA = _shared.LOG_STEP_STATIONS, _shared.LOG_STEP_ALPHA
RIGHT_23_2 = band(3 * M, 1, LOG_STEP_ALPHA)


def test_23_1_accepts_the_band_of_the_dof_summed():
    fb = ex.check_log_nis_band(RIGHT_23_1)
    assert fb.correct and f"n_upd = {N_UPD}" in fb.message and f"{D} degrees" in fb.message, str(fb)


@pytest.mark.parametrize("key, wrong", [
    ("fixed_dof", band(3 * N_UPD, N_UPD, ALPHA)),
    ("station_dof", band(ONE + 2 * TWO, N_UPD, ALPHA)),
    ("count_empty", band(D, N_UPD + EMPTY, ALPHA)),
    ("per_dof", band(D, D, ALPHA)),
    ("not_divided", band(D, 1, ALPHA)),
    ("one_sided", band(D, N_UPD, ALPHA, tails=1)),
    ("state_dof", band(4 * N_UPD, N_UPD, ALPHA)),
])
def test_23_1_names_each_mistake(key, wrong):
    fb = ex.check_log_nis_band(wrong)
    assert not fb.correct and fb.message == hint("23.1", key), str(fb)


def test_23_1_with_other_settings_and_without_a_two_station_step():
    assert ex.check_log_nis_band(band(3 * 500, 500, 0.01), one=500, two=0, empty=3, alpha=0.01).correct
    # one station only: the fixed 3 dof are right, so that mistake is not one
    assert "3 per visible station" in ex.check_log_nis_band(band(3 * 500, 500, 0.05), one=500, two=0).message


def test_23_2_accepts_the_band_of_the_steps_dof():
    fb = ex.check_step_nis_band(RIGHT_23_2)
    assert fb.correct and "6 dof" in fb.message, str(fb)


@pytest.mark.parametrize("key, wrong", [
    ("fixed_dof", band(3, 1, LOG_STEP_ALPHA)),
    ("station_dof", band(M, 1, LOG_STEP_ALPHA)),
    ("one_sided", band(3 * M, 1, LOG_STEP_ALPHA, tails=1)),
    ("notebook_alpha", band(3 * M, 1, 0.05)),
    ("state_dof", band(4, 1, LOG_STEP_ALPHA)),
])
def test_23_2_names_each_mistake(key, wrong):
    fb = ex.check_step_nis_band(wrong)
    expected = hint("23.2", key).format(m=M, alpha=LOG_STEP_ALPHA)
    assert not fb.correct and fb.message == expected, str(fb)


def test_every_listed_hint_of_23_is_tested_placeholders_unanswered_rounding_told():
    assert set(ex.EXERCISES["23.1"].hints) == {"fixed_dof", "station_dof", "count_empty", "per_dof", "not_divided",
                                               "one_sided", "state_dof"}
    assert set(ex.EXERCISES["23.2"].hints) == {"fixed_dof", "station_dof", "one_sided", "notebook_alpha", "state_dof"}
    for check, right in ((ex.check_log_nis_band, RIGHT_23_1), (ex.check_step_nis_band, RIGHT_23_2)):
        fb = check(...)
        assert not fb.correct and not fb.answered
        fb = check(np.round(right, 2))
        assert not fb.correct and ROUNDED_HINT[:20] in fb.message, str(fb)


@pytest.mark.parametrize("check, setting, name", [
    (ex.check_log_nis_band, {"one": -1}, "one"), (ex.check_log_nis_band, {"two": 1.5}, "two"),
    (ex.check_log_nis_band, {"empty": -2}, "empty"), (ex.check_log_nis_band, {"alpha": 1.5}, "alpha"),
    (ex.check_log_nis_band, {"one": 0, "two": 0}, "one"), (ex.check_step_nis_band, {"stations": 0}, "stations"),
    (ex.check_step_nis_band, {"stations": 13}, "stations"), (ex.check_step_nis_band, {"alpha": 0.0}, "alpha")])
def test_bad_settings_raise_valueerror_naming_them(check, setting, name):
    with pytest.raises(ValueError, match=f"^{name} "):
        check(np.zeros(2), **setting)


def test_the_notebook_23_states_the_exercises_numbers():
    text = (Path(__file__).resolve().parents[1] / "notebooks" / "source" / "23_orbit_data_log.md").read_text()
    assert "at 1200 of them one station" in text and "at 180 two stations do, at 20 none" in text
    assert (ONE, TWO, EMPTY, ALPHA) == (1200, 180, 20, 0.05) and "$\\alpha = 0.05$ with `scipy.stats.chi2.ppf`" in text
    assert "two stations see the satellite" in text and "$\\alpha = 0.01$" in text and (M, LOG_STEP_ALPHA) == (2, 0.01)
