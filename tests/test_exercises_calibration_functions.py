"""The checks of the exercises that ask the student to WRITE a piece of the simulation as a function:
02.4 the dead reckoning, 02.5 the IMU output, 03.4 the GPS fixes.

Each check accepts a right function written here by another route (plain loops over every index),
answers each listed wrong function with that mistake's hint, and answers a half-written or raising
function with a hint, never a traceback."""

import numpy as np
import pytest

import kfcal_helpers.calibration.exercises as ex
from kfcal_helpers.calibration import CalibrationParams, simulate
from kfcal_helpers.calibration.exercises import EXERCISES
from kfcal_helpers.exercises._core import PLACEHOLDER_FUNC

HINTS = {i: EXERCISES[i].hints for i in ("02.4", "02.5", "03.4")}


def has_hint(fb, exercise, key):
    return (not fb.correct) and fb.answered and fb.message == HINTS[exercise][key]


# --------------------------------------------------------------------------------------------
# 02.4 dead reckoning
# --------------------------------------------------------------------------------------------
def reckon_loops(a_c, p_init, v_init, dt, kind="ok"):
    """Every realization and every sample by plain Python loops (no numpy vector operation)."""
    a_c = np.asarray(a_c, dtype=float)
    n, n_t = a_c.shape
    p, v = np.zeros((n, n_t)), np.zeros((n, n_t))
    for m in range(n):
        p[m, 0], v[m, 0] = p_init, v_init
        for j in range(n_t - 1):
            acc = a_c[m, j + 1] if kind == "right" else a_c[m, j]
            v[m, j + 1] = v[m, j] + acc * dt
            vel = v[m, j + 1] if kind == "new_v" else v[m, j]
            half = {"no_acc": 0.0, "dt2": acc * dt * dt}.get(kind, 0.5 * acc * dt * dt)
            p[m, j + 1] = p[m, j] + vel * dt + half
    return p, v


def test_dead_reckoning_accepts_the_recursion_written_with_loops():
    fb = ex.check_dead_reckoning(reckon_loops)
    assert fb.correct and fb.message == EXERCISES["02.4"].praise


def test_dead_reckoning_accepts_cumulative_sums():
    def cumsums(a_c, p_init, v_init, dt):
        v = np.concatenate([np.zeros((len(a_c), 1)), np.cumsum(a_c[:, :-1], axis=1)], axis=1) * dt + v_init
        step = v[:, :-1] * dt + a_c[:, :-1] * dt**2 / 2
        p = p_init + np.concatenate([np.zeros((len(a_c), 1)), np.cumsum(step, axis=1)], axis=1)
        return p, v
    assert ex.check_dead_reckoning(cumsums).correct


def test_dead_reckoning_on_the_simulation_is_what_simulate_does():
    """The right answer, run on simulate()'s a_c, gives simulate()'s p_c, v_c: the exercise is the real step."""
    params = CalibrationParams(duration=2.0)
    sim = simulate(params, 3, 5)
    p_c, v_c = reckon_loops(sim.a_c, params.p0_mean, params.v0_mean, params.dt)
    assert np.allclose(p_c, sim.p_c, rtol=1e-12, atol=1e-9) and np.allclose(v_c, sim.v_c, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("kind", ["new_v", "no_acc", "dt2", "right"])
def test_dead_reckoning_names_each_recursion_mistake(kind):
    fb = ex.check_dead_reckoning(lambda a_c, p, v, dt: reckon_loops(a_c, p, v, dt, kind))
    assert has_hint(fb, "02.4", kind), str(fb)


def test_dead_reckoning_names_the_other_mistakes():
    along_rows = lambda a_c, p, v, dt: tuple(x.T for x in reckon_loops(a_c.T, p, v, dt))  # noqa: E731
    assert has_hint(ex.check_dead_reckoning(along_rows), "02.4", "axis")
    swapped = lambda a_c, p, v, dt: reckon_loops(a_c, p, v, dt)[::-1]  # noqa: E731
    assert has_hint(ex.check_dead_reckoning(swapped), "02.4", "swapped")
    no_start = lambda a_c, p, v, dt: tuple(x[:, 1:] for x in reckon_loops(a_c, p, v, dt))  # noqa: E731
    assert has_hint(ex.check_dead_reckoning(no_start), "02.4", "shape")
    one = lambda a_c, p, v, dt: reckon_loops(a_c, p, v, dt)[0]  # noqa: E731
    assert has_hint(ex.check_dead_reckoning(one), "02.4", "tuple")
    assert has_hint(ex.check_dead_reckoning(lambda *args: "p, v"), "02.4", "tuple")


def test_dead_reckoning_tells_which_half_is_right():
    p_wrong = lambda a_c, p, v, dt: (reckon_loops(a_c, p, v, dt)[0] + 1.0, reckon_loops(a_c, p, v, dt)[1])  # noqa: E731
    fb = ex.check_dead_reckoning(p_wrong)
    assert not fb.correct and fb.message.startswith("v_c is right, p_c is not")
    fb = ex.check_dead_reckoning(lambda a_c, p, v, dt: (np.zeros(a_c.shape), np.zeros(a_c.shape)))
    assert not fb.correct and fb.answered and fb.message == EXERCISES["02.4"].hint


# --------------------------------------------------------------------------------------------
# 02.5 IMU output
# --------------------------------------------------------------------------------------------
def imu_loops(a, b, w):
    out = np.empty((len(b), len(a)))
    for m in range(len(b)):
        for j in range(len(a)):
            out[m, j] = a[j] + b[m] + w[m, j]
    return out


def test_imu_output_accepts_the_sum_written_with_loops():
    fb = ex.check_imu_output(imu_loops)
    assert fb.correct and fb.message == EXERCISES["02.5"].praise


def test_imu_output_on_the_simulation_is_what_simulate_does():
    sim = simulate(CalibrationParams(duration=1.0), 2, 7)
    assert np.array_equal(imu_loops(sim.a, sim.b, sim.w), sim.a_c)


@pytest.mark.parametrize("key, func", [
    ("bias_sign", lambda a, b, w: a - b[:, None] + w),
    ("noise_sign", lambda a, b, w: a + b[:, None] - w),
    ("no_bias", lambda a, b, w: a + w),
    ("no_noise", lambda a, b, w: a + b[:, None] + 0 * w),
    ("broadcast", lambda a, b, w: a + b + w),              # raises: (5,) + (3,)
    ("transposed", lambda a, b, w: (a[:, None] + b + w.T)),  # the transpose, (n_imu, n): not the b[:, None] hint
    ("broadcast", lambda a, b, w: (a[:, None] + b[::-1] + w.T)),  # (n_imu, n) and not the transpose of the sum
    ("shape", lambda a, b, w: a + b.mean()),
])
def test_imu_output_names_each_mistake(key, func):
    assert has_hint(ex.check_imu_output(func), "02.5", key), str(ex.check_imu_output(func))


# --------------------------------------------------------------------------------------------
# 03.4 GPS fixes
# --------------------------------------------------------------------------------------------
def gps_loops(p, v, eta, steps_per_fix):
    n, n_gps, _ = eta.shape
    z = np.empty((n, n_gps, 2))
    for m in range(n):
        i = 0
        for j in range(p.shape[1]):
            if j % steps_per_fix == 0:
                z[m, i] = [p[m, j] + eta[m, i, 0], v[m, j] + eta[m, i, 1]]
                i += 1
    return z


def test_gps_measurement_accepts_the_fixes_written_with_loops():
    fb = ex.check_gps_measurement(gps_loops)
    assert fb.correct and fb.message == EXERCISES["03.4"].praise


def test_gps_measurement_on_the_simulation_is_what_simulate_does():
    params = CalibrationParams(duration=2.0)
    sim = simulate(params, 2, 9)
    eta = sim.z - np.stack([sim.p[:, params.fix_indices], sim.v[:, params.fix_indices]], axis=-1)
    assert np.array_equal(gps_loops(sim.p, sim.v, eta, params.steps_per_fix), sim.z)


def _stack(p, v, idx, eta, sign=1.0):
    return np.stack([p[:, idx], v[:, idx]], axis=-1) + sign * eta


@pytest.mark.parametrize("key, func", [
    ("count", lambda p, v, eta, r: _stack(p, v, slice(r, None, r), eta)),             # no fix at t = 0: raises
    ("count", lambda p, v, eta, r: _stack(p, v, slice(0, p.shape[1] - 1, r), eta)),   # last fix dropped: raises
    ("count", lambda p, v, eta, r: _stack(p, v, slice(r - 1, None, r), eta)),         # one sample early: raises
    ("count", lambda p, v, eta, r: np.stack([p[:, r::r], v[:, r::r]], axis=-1)),       # wrong count, no error
    ("swapped", lambda p, v, eta, r: np.stack([v[:, ::r], p[:, ::r]], axis=-1) + eta),
    ("minus", lambda p, v, eta, r: _stack(p, v, slice(None, None, r), eta, -1.0)),
    ("no_noise", lambda p, v, eta, r: _stack(p, v, slice(None, None, r), 0 * eta)),
    ("axis", lambda p, v, eta, r: np.stack([p[:, ::r], v[:, ::r]]) + np.moveaxis(eta, -1, 0)),
    ("shape", lambda p, v, eta, r: p[:, ::r]),
])
def test_gps_measurement_names_each_mistake(key, func):
    fb = ex.check_gps_measurement(func)
    assert has_hint(fb, "03.4", key), str(fb)


# --------------------------------------------------------------------------------------------
# all three: placeholders, half-written and raising functions give a hint, not a traceback
# --------------------------------------------------------------------------------------------
CHECKS = [ex.check_dead_reckoning, ex.check_imu_output, ex.check_gps_measurement]


@pytest.mark.parametrize("check", CHECKS)
def test_placeholders_are_not_answered_yet(check):
    def half_written(*args):
        ...
    for answer in (..., None, half_written):
        fb = check(answer)
        assert not fb.correct and not fb.answered and PLACEHOLDER_FUNC in fb.message


@pytest.mark.parametrize("check", CHECKS)
def test_raising_and_malformed_functions_get_a_hint(check):
    def raises(*args):
        raise ZeroDivisionError("oops")
    fb = check(raises)
    assert not fb.correct and fb.answered and "ZeroDivisionError" in fb.message and "oops" in fb.message
    fb = check(lambda x: x)  # wrong number of arguments
    assert not fb.correct and fb.answered and "TypeError" in fb.message
    fb = check(lambda *args: np.full((3, 7), np.nan))
    assert not fb.correct and fb.answered
    fb = check(42)
    assert not fb.correct and fb.answered and "function" in fb.message


@pytest.mark.parametrize("check", CHECKS)
def test_the_student_input_is_not_changed_for_the_next_call(check):
    """A function that writes into its arguments does not spoil the check's test input."""
    def vandal(*args):
        for x in args:
            if isinstance(x, np.ndarray):
                x[...] = 0.0
        return None
    check(vandal)
    right = {ex.check_dead_reckoning: reckon_loops, ex.check_imu_output: imu_loops,
             ex.check_gps_measurement: gps_loops}[check]
    assert check(right).correct


def test_records_are_listed():
    for name in ("check_dead_reckoning", "check_imu_output", "check_gps_measurement"):
        assert name in ex.__all__
    assert {"02.4", "02.5", "03.4"} <= set(EXERCISES)


# --------------------------------------------------------------------------------------------
# issue 32: a function that modifies its inputs is never accepted (01.3, 02.4, 02.5, 03.4, 05.1)
# --------------------------------------------------------------------------------------------
def _in_place_imu_output(a, b, w):
    w += a + b[:, None]   # the notebook's own w would be corrupted
    return w


def test_an_in_place_imu_output_is_told_not_to_modify_w():
    fb = ex.check_imu_output(_in_place_imu_output)
    assert not fb.correct and fb.message.startswith("don't modify your inputs: your function changed w;"), str(fb)
    w = np.zeros((3, 5))
    ex.check_imu_output(lambda a, b, w_: a + b[:, None] + w_)
    assert np.array_equal(w, np.zeros((3, 5)))


@pytest.mark.parametrize("check, func", [
    (ex.check_euler_truth, lambda a, p0, v0, dt: (a.fill(0.0), (a, a))[1]),
    (ex.check_dead_reckoning, lambda a_c, p, v, dt: (a_c.fill(0.0), (a_c, a_c))[1]),
    (ex.check_gps_measurement, lambda p, v, eta, r: (eta.fill(0.0), eta)[1]),
    (ex.check_predict_only, lambda x, M, Phi, Q, n: (M.fill(0.0), (x, M))[1]),
], ids=["01.3", "02.4", "03.4", "05.1"])
def test_a_function_that_modifies_an_input_is_told_which(check, func):
    fb = check(func)
    name = list(__import__("inspect").signature(func).parameters)[{"01.3": 0, "02.4": 0, "03.4": 2, "05.1": 1}[fb.exercise]]
    assert not fb.correct and f"your function changed {name};" in fb.message, str(fb)
