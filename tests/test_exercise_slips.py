"""The slips of issue 32, item 3, one row per exercise and slip: each check, given the right answer with
that slip (a units factor, degrees for radians, reversed, transposed, one entry off, bearings wrapped to
[0, 2 pi), the NIS with the state's dimension, z = 2 for the quantile, a one-sided band), answers with a
hint naming the slip, never "correct".  A function exercise's rows slip the right function's output.

CONTRIBUTING's table "slips its tests cover" lists, for each exercise, exactly the slips of its rows here
(``test_the_contributing_table_lists_exactly_the_slips_tested``).

The right answers come from the other exercise tests, which compute them by another route than the checks.
"""

import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

import test_exercises_calibration as cal
import test_exercises_calibration_functions as calf
import test_exercises_coop as coop
import test_exercises_coop_functions as coopf
from kfcal_helpers.calibration import exercises as cx
from kfcal_helpers.coop import exercises as kx

#: every record of both problems, by id
RECORDS = {**cx.EXERCISES, **kx.EXERCISES}

UNITS, DEGREES, REVERSED, TRANSPOSED, ENTRY = "units", "degrees", "reversed", "transposed", "entry named"
WRAP, NIS_DIM, Z_TWO, ONE_SIDED = "wrap [0, 2π)", "NIS dof of the state", "z = 2", "one-sided"
LABELS = (UNITS, DEGREES, REVERSED, TRANSPOSED, ENTRY, WRAP, NIS_DIM, Z_TWO, ONE_SIDED)


def hint(exercise, key):
    return RECORDS[exercise].hints[key]


def chi2_band(dof, divide, lo=0.025, hi=0.975):
    return np.array([stats.chi2.ppf(lo, dof), stats.chi2.ppf(hi, dof)]) / divide


# --------------------------------------------------------------------------------------------
# the right answers of the judged (numeric) exercises and their checks
# --------------------------------------------------------------------------------------------
CHECK = {ex: cal.CASES[ex][0] for ex in cal.NUMERIC}
RIGHT = {ex: np.asarray(cal.CASES[ex][1], dtype=float) for ex in cal.NUMERIC}
for _ex, _check in coop.CHECKS.items():
    if not _check[1]:
        CHECK[_ex] = _check[0]
for _ex in ("08.1", "08.2", "09.1", "09.2", "09.3", "09.4", "10.1", "11.2", "12.1"):
    RIGHT[_ex] = np.asarray(coop.RIGHT[_ex](), dtype=float)
K_15S, K_SPARSE = kx.LOG_SAMPLES - 1, len(range(0, kx.SPARSE_SAMPLES, kx.SPARSE_EVERY)) - 1
RIGHT["13.1"] = coop.avg_bounds(5, K_15S, kx.LOG_ALPHA)
RIGHT["13.2"] = coop.avg_bounds(5, K_SPARSE, 0.05)
CHECK.update({"14.2": cx.check_phi02_coupling_change, "17.1": cx.check_demo_first_fix_sigma,
              "17.2": cx.check_demo_ratio_band, "18.1": kx.check_subset_nis_bounds, "18.2": kx.check_lost_directions})
RIGHT["14.2"] = np.array(200 * 0.005**2)                                       # k dt^2, k = 200 steps of 5 ms
RIGHT["17.1"] = np.sqrt([1 / (1 / 100 + 1 / 10), 1 / (1 / 1 + 1 / 0.0016), 0.01])   # inverse variances add
RIGHT["17.2"] = np.sqrt(chi2_band(199, 199))                                    # (N-1) s^2/sigma^2 ~ chi2(N-1)
RIGHT["18.1"] = chi2_band(3 * 1000, 1000)                                       # 3 measurements, K = 1000
RIGHT["18.2"] = np.array([0.0, 1.0, 3.0])   # nothing; the common north shift; translation and rotation

#: the entry each "entry named" row puts off (flat index), when not the last one
ENTRY_INDEX = {"02.3": 1, "04.1": 2, "04.3": 2, "04.4": 4, "05.2": 0, "05.3": 3, "08.1": 3, "08.2": 1, "09.1": 3,
               "09.2": 2, "09.4": 14, "10.1": 3, "11.2": 20, "12.1": 2, "15.2": 1, "16.1": 1, "17.1": 1, "18.2": 1}
#: the words a reversed or transposed answer is answered with, where a listed mistake is that slip
ORDER_WORDS = {"02.1": hint("02.1", "swapped"), "02.2": hint("02.2", "swapped"), "03.2": hint("03.2", "swapped"),
               "09.3": hint("09.3", "reversed"), "18.2": hint("18.2", "reversed"), "04.1": hint("04.1", "transposed"),
               "09.2": hint("09.2", "transposed"), "11.2": hint("11.2", "transposed"), "05.2": hint("05.2", "shape"),
               "10.1": hint("10.1", "order")}
#: judged exercises without a units slip (whole numbers: sample indices, a mask, ranks, counts)
NO_UNITS = {"03.1", "15.1", "09.3", "18.2"}


def _units_rows(ex):
    if ex in NO_UNITS:
        return []
    return [(ex, UNITS, RIGHT[ex] * 100, "your answer is 100 times the right one: check the units"),
            (ex, UNITS, RIGHT[ex] / 1000, "your answer is 0.001 times the right one: check the units")]


@pytest.mark.parametrize("exercise", sorted(NO_UNITS))
def test_indices_masks_ranks_and_counts_get_no_units_hint(exercise):
    assert not RECORDS[exercise].units
    fb = CHECK[exercise](RIGHT[exercise] * 10)
    assert not fb.correct and "units" not in fb.message, str(fb)


def _entry_row(ex):
    names = RECORDS[ex].components
    if not names:
        return []
    i = ENTRY_INDEX.get(ex, len(names) - 1)
    flat = RIGHT[ex].ravel().copy()
    flat[i] = flat[i] * 1.03 if flat[i] != 0 else 0.03
    if ex in ("09.3", "18.2"):
        flat[i] = RIGHT[ex].ravel()[i] + 2      # counts stay whole numbers
    return [(ex, ENTRY, flat.reshape(RIGHT[ex].shape), f"only {names[i]} is off, the rest is right")]


def _order_rows(ex):
    r = RIGHT[ex]
    rows = []
    if r.ndim == 1 and r.size > 1 and not np.allclose(r, r[::-1]):
        rows.append((ex, REVERSED, r[::-1], ORDER_WORDS.get(ex, "your entries are in reverse order")))
    if ex == "10.1":
        rows.append((ex, REVERSED, r[:, ::-1], ORDER_WORDS[ex]))
    if r.ndim == 2 and min(r.shape) > 1 and (r.shape != r.T.shape or not np.allclose(r, r.T)):
        words = ORDER_WORDS.get(ex, "transposed") if ex != "10.1" else "your matrix is transposed"
        rows.append((ex, TRANSPOSED, r.T, words))
    return rows


def _numeric_rows():
    rows = []
    for ex in sorted(RIGHT):
        rows += _units_rows(ex) + _order_rows(ex) + _entry_row(ex)
    # the slips that are listed mistakes (issue 32: quantile, one-sided, the NIS's dimension, wrapping, degrees)
    z = stats.norm.ppf(0.975)
    rho, n_fisher = math.atanh(0.8), 300 - 3
    level = 0.05 / 48622   # 06.3: alpha over the 48,622 entries of the seven checks at 151 fixes
    rows += [
        ("02.3", ONE_SIDED, 0.02 * np.sqrt(chi2_band(49, 49, 0.05, 0.95)), hint("02.3", "one_sided")),
        ("02.3", Z_TWO, 0.02 * (1 + np.array([-2.0, 2.0]) / math.sqrt(98)), hint("02.3", "normal")),
        ("03.3", ONE_SIDED, 0.04 * np.sqrt(chi2_band(100, 100, 0.05, 0.95)), hint("03.3", "one_sided")),
        ("03.3", Z_TWO, 0.04 * (1 + np.array([-2.0, 2.0]) / math.sqrt(200)), hint("03.3", "normal")),
        ("06.1", ONE_SIDED, chi2_band(100, 50, 0.05, 0.95), hint("06.1", "one_sided")),
        ("06.1", NIS_DIM, chi2_band(3 * 50, 50), hint("06.1", "dim3")),          # the state's 3, not the residual's 2
        ("06.2", ONE_SIDED, np.tanh(rho + np.array([-1, 1]) * stats.norm.ppf(0.95) / math.sqrt(n_fisher)),
         hint("06.2", "one_sided")),
        ("06.2", Z_TWO, np.tanh(rho + np.array([-2.0, 2.0]) / math.sqrt(n_fisher)), hint("06.2", "z_two")),
        ("06.3", ONE_SIDED, chi2_band(3000, 1000, level, 1 - level), hint("06.3", "one_sided")),
        ("10.1", ONE_SIDED, coop.wrong_10_1()["one_sided"], hint("10.1", "one_sided")),
        ("10.1", NIS_DIM, coop.wrong_10_1()["dim6"], hint("10.1", "dim6")),
        ("10.1", Z_TWO, np.array([[n - 2 * math.sqrt(2 * n / 20), n + 2 * math.sqrt(2 * n / 20)] for n in (6, 5)]),
         hint("10.1", "normal")),
        ("13.1", ONE_SIDED, coop.wrong_13(K_15S, 0.01)["one_sided"], hint("13.1", "one_sided")),
        ("13.1", NIS_DIM, coop.wrong_13(K_15S, 0.01)["dim6"], hint("13.1", "dim6")),
        ("13.2", ONE_SIDED, coop.wrong_13(K_SPARSE, 0.05)["one_sided"], hint("13.2", "one_sided")),
        ("13.2", NIS_DIM, coop.wrong_13(K_SPARSE, 0.05)["dim6"], hint("13.2", "dim6")),
        ("17.2", ONE_SIDED, np.sqrt(chi2_band(199, 199, 0.05, 0.95)), hint("17.2", "one_sided")),
        ("17.2", Z_TWO, 1 + np.array([-2.0, 2.0]) / math.sqrt(2 * 199), hint("17.2", "normal")),
        ("18.1", ONE_SIDED, chi2_band(3000, 1000, 0.05, 0.95), hint("18.1", "one_sided")),
        ("18.1", NIS_DIM, chi2_band(6000, 1000), hint("18.1", "dim6")),
        ("18.1", Z_TWO, 3 + np.array([-2.0, 2.0]) * math.sqrt(6 / 1000), hint("18.1", "normal")),
    ]
    assert abs(z - 1.96) < 1e-3
    heading = RIGHT["08.1"].copy()
    rows += [("08.1", DEGREES, np.where([0, 0, 1, 0, 0, 1], np.degrees(heading), heading), "your answer is in degrees"),
             ("08.1", WRAP, np.where([0, 0, 1, 0, 0, 1], np.mod(heading, 2 * np.pi), heading), hint("08.1", "wrap"))]
    assert heading[5] < 0   # the UAV's heading: [0, 2 pi) differs from (-pi, pi]
    meas = RIGHT["08.2"]
    rows += [("08.2", DEGREES, np.where([1, 0, 1, 0, 0], np.degrees(meas), meas), "your answer is in degrees"),
             ("08.2", ENTRY, meas * [1, 0.001, 1, 1, 1], "only the range is off, the rest is right: it is 0.001 times"),
             ("08.2", WRAP, np.where([1, 0, 1, 0, 0], np.mod(meas, 2 * np.pi), meas), hint("08.2", "wrap"))]
    return rows


# --------------------------------------------------------------------------------------------
# function exercises: the right function (another route than the check's), its output slipped
# --------------------------------------------------------------------------------------------
def trapezoid_loop(a, v0, dt):
    v = [v0]
    for j in range(len(a) - 1):
        v.append(v[-1] + (a[j] + a[j + 1]) * dt / 2)
    return np.array(v)


def residual(a, b):
    """The residual with +pi for -pi (the convention of the check's expected values, so that a slipped
    copy of pi is a slip of the check's value)."""
    d = coop.residual_arctan2(a, b)
    return np.where(np.isclose(d, -np.pi), np.pi, d)


def _bearings(out, f):
    out = np.array(out, dtype=float)
    out[..., [0, 2]] = f(out[..., [0, 2]])
    return out


def band_loops(e, alpha):
    """The ensemble mean error and its Student-t half-width, entry by entry."""
    n = len(e)
    flat = e.reshape(n, -1)
    mean = np.array([sum(flat[:, j]) / n for j in range(flat.shape[1])])
    sd = np.array([math.sqrt(sum((flat[:, j] - mean[j]) ** 2) / (n - 1)) for j in range(flat.shape[1])])
    return mean.reshape(e.shape[1:]), (stats.t.ppf(1 - alpha / 2, n - 1) * sd / math.sqrt(n)).reshape(e.shape[1:])


def _function_rows():
    euler, reckon, predict = cal.euler_loop, calf.reckon_loops, cal.predict_loop
    deg = lambda b: np.degrees(b)                                    # noqa: E731
    mod = lambda b: np.mod(b, 2 * np.pi)                             # noqa: E731
    return [
        ("01.3", UNITS, lambda a, p0, v0, dt: (euler(a, p0, v0, dt)[0] * 100, euler(a, p0, v0, dt)[1]),
         "your function's p is 100 times the right one"),
        ("02.4", UNITS, lambda a, p, v, dt: (reckon(a, p, v, dt)[0], reckon(a, p, v, dt)[1] / 10),
         "your function's v_c is 0.1 times the right one"),
        ("02.5", UNITS, lambda a, b, w: calf.imu_loops(a, b, w) * 1000, "your function's a_c is 1000 times the right one"),
        ("02.5", TRANSPOSED, lambda a, b, w: calf.imu_loops(a, b, w).T, hint("02.5", "transposed")),
        ("03.4", UNITS, lambda p, v, eta, r: calf.gps_loops(p, v, eta, r) * 100, "your function's z is 100 times"),
        ("03.4", ENTRY, lambda p, v, eta, r: calf.gps_loops(p, v, eta, r) * [1.0, 3.6],   # km/h for m/s
         "only the velocity z[..., 1] is off, the rest is right"),
        ("05.1", UNITS, lambda x, M, Phi, Q, n: (predict(x, M, Phi, Q, n)[0], predict(x, M, Phi, Q, n)[1] * 1000),
         "your function's M is 1000 times the right one"),
        ("05.1", ENTRY, lambda x, M, Phi, Q, n: (predict(x, M, Phi, Q, n)[0] * [1, 1, 1.5], predict(x, M, Phi, Q, n)[1]),
         "only x̄[2] (b) is off, the rest is right"),
        ("06.4", UNITS, lambda e, alpha: tuple(v * 1000 for v in band_loops(e, alpha)),
         "your function's e_bar is 1000 times the right one"),
        ("07.2", UNITS, lambda a, v0, dt: trapezoid_loop(a, v0, dt) / 1000, "your function's v is 0.001 times"),
        ("07.2", REVERSED, lambda a, v0, dt: trapezoid_loop(a, v0, dt)[::-1],
         "the entries of your function's v are in reverse order"),
        ("08.3", UNITS, lambda x: coopf.h_loops(x) * 10, "your function's result is 10 times the right one"),
        ("08.3", DEGREES, lambda x: coopf.h_loops(x, "degrees"), hint("08.3", "degrees")),
        ("08.3", WRAP, lambda x: _bearings(coopf.h_loops(x), mod), hint("08.3", "wrap_2pi")),
        ("08.3", ENTRY, lambda x: coopf.h_loops(x) + [0.0, 1.0, 0.0, 0.0, 0.0], "only the range is off"),
        ("10.2", UNITS, lambda *a: coop.lkf_right(*a) * 100, "your function's result is 100 times the right one"),
        ("10.2", DEGREES, lambda *a: _bearings(coop.lkf_right(*a), deg), "your function's result is in degrees"),
        ("10.2", WRAP, lambda *a: _bearings(coop.lkf_right(*a), mod), hint("10.2", "wrap_2pi")),
        ("10.2", ENTRY, lambda *a: coop.lkf_right(*a) + [0.0, 1.0, 0.0, 0.0, 0.0], "only the range is off"),
        ("10.2", ENTRY, lambda *a: coop.lkf_right(*a) * [1.0, 100.0, 1.0, 1.0, 1.0],     # the range in cm
         "only the range is off, the rest is right: it is 100 times the right value: check the units"),
        ("11.1", UNITS, lambda a, b: residual(a, b) / 1000, "your function's result is 0.001 times"),
        ("11.1", DEGREES, lambda a, b: _bearings(residual(a, b).T, deg).T,
         "your function's result is in degrees"),
        ("11.1", WRAP, lambda a, b: _bearings(residual(a, b).T, mod).T, hint("11.1", "mod_2pi")),
        ("11.1", ENTRY, lambda a, b: residual(a, b) + [[0.0], [0.0], [0.0], [2.0], [0.0]],
         "only the UAV's GPS east xi_a is off"),
        ("11.1", ENTRY, lambda a, b: residual(a, b) * [[180 / math.pi], [1.0], [1.0], [1.0], [1.0]],
         "only the bearing UGV->UAV is off, the rest is right: it is in degrees"),
        ("12.2", UNITS, lambda a, w: coop.circ_right(a, w) * 10, "your function's result is 10 times the right one"),
        ("12.2", DEGREES, lambda a, w: math.degrees(coop.circ_right(a, w)), "your function's result is in degrees"),
        ("12.2", WRAP, lambda a, w: coop.circ_right(a, w) % (2 * math.pi), hint("12.2", "wrap_2pi")),
    ]


NUMERIC_ROWS = _numeric_rows()
FUNCTION_ROWS = _function_rows()
FUNCTION_CHECK = {"01.3": cx.check_euler_truth, "02.4": cx.check_dead_reckoning, "02.5": cx.check_imu_output,
                  "03.4": cx.check_gps_measurement, "05.1": cx.check_predict_only,
                  "06.4": cx.check_mean_error_band, "07.2": cx.check_trapezoid_velocity,
                  "08.3": kx.check_measure_function, "10.2": kx.check_lkf_innovation, "11.1": kx.check_ekf_residual,
                  "12.2": kx.check_circular_mean}


def _id(row):
    return f"{row[0]}-{row[1]}"


@pytest.mark.parametrize("row", NUMERIC_ROWS, ids=[_id(r) for r in NUMERIC_ROWS])
def test_a_slipped_answer_gets_the_slips_hint(row):
    exercise, _, answer, words = row
    assert CHECK[exercise](RIGHT[exercise]).correct   # the right answer of this table is right
    fb = CHECK[exercise](answer)
    assert not fb.correct and fb.answered and words in fb.message, (exercise, str(fb))


@pytest.mark.parametrize("row", FUNCTION_ROWS, ids=[_id(r) for r in FUNCTION_ROWS])
def test_a_function_whose_output_slipped_gets_the_slips_hint(row):
    exercise, _, func, words = row
    fb = FUNCTION_CHECK[exercise](func)
    assert not fb.correct and fb.answered and words in fb.message, (exercise, str(fb))


def test_every_function_exercise_has_a_slip_row():
    assert {r[0] for r in FUNCTION_ROWS} == set(FUNCTION_CHECK)


def test_the_right_functions_of_the_rows_are_right():
    right = {"01.3": cal.euler_loop, "02.4": calf.reckon_loops, "02.5": calf.imu_loops, "03.4": calf.gps_loops,
             "05.1": cal.predict_loop, "06.4": band_loops, "07.2": trapezoid_loop, "08.3": coopf.h_loops, "10.2": coop.lkf_right,
             "11.1": residual, "12.2": coop.circ_right}
    for exercise, check in FUNCTION_CHECK.items():
        assert check(right[exercise]).correct, exercise


def slip_table():
    """CONTRIBUTING's table: {exercise id: set of slip labels} (a dash: none)."""
    text = (Path(__file__).parents[1] / "CONTRIBUTING.md").read_text(encoding="utf-8")
    table = {}
    for first, slips in re.findall(r"^\| (\d\d\.\d) \| ([^|]*) \|$", text, flags=re.M):
        table[first] = {s.strip() for s in slips.split(";")} - {"—"}
    return table


def test_the_contributing_table_lists_exactly_the_slips_tested():
    table = {ex: slips for ex, slips in slip_table().items() if ex[:2] not in ("19", "20", "21", "22", "23")}
    assert set(table) == set(RECORDS), "one row per exercise"   # orbit's rows: tests/test_exercise_slips_orbit.py
    tested = {ex: set() for ex in RECORDS}
    for row in NUMERIC_ROWS + FUNCTION_ROWS:
        tested[row[0]].add(row[1])
    assert set().union(*table.values()) <= set(LABELS)
    assert table == tested
