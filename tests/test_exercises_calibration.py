"""Exercise checks of notebooks 01-07, 15, 16: every check accepts the right answer (computed
here by another route), rejects each listed wrong answer with its hint, reports a placeholder
as "not answered yet", and turns a malformed answer into a hint instead of an exception."""

import re

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter
from scipy import stats

import kfcal_helpers.calibration.exercises as ex
from kfcal_helpers.calibration import (CalibrationParams, covariance_sequence, error_state_model,
                                       rts_smooth_fixes, run_monte_carlo)
from kfcal_helpers.calibration.exercises import EXERCISES
from kfcal_helpers.exercises._core import ROUNDED_HINT, Exercise, Feedback

#: the records' hints, generic hints and praise, by exercise id
HINTS = {i: e.hints for i, e in EXERCISES.items()}
GENERIC = {i: e.hint for i, e in EXERCISES.items()}
PRAISE = {i: e.praise for i, e in EXERCISES.items()}

DT = 0.005  # s, the default IMU period
A = 10.0  # m/s^2


# --------------------------------------------------------------------------------------------
# independent reference computations (plain loops and formulas, not the package's helpers)
# --------------------------------------------------------------------------------------------
def euler_loop(a, p0, v0, dt, kind="ok"):
    p, v = [p0], [v0]
    for j in range(len(a) - 1):
        aj = a[j + 1] if kind == "right" else a[j]
        v_new = v[-1] + aj * dt
        vel = v_new if kind == "new_v" else v[-1]
        acc = {"no_acc": 0.0, "dt2": aj * dt**2}.get(kind, aj * dt**2 / 2)
        p.append(p[-1] + vel * dt + acc)
        v.append(v_new)
    return np.array(p), np.array(v)


def truths(omega, t_end):
    """Analytic and Euler (p, v) on the 200 Hz grid up to t_end, p0 = v0 = 0."""
    n = int(round(t_end / DT)) + 1
    t = np.arange(n) * DT
    a = A * np.sin(omega * t)
    v_an = A / omega * (1 - np.cos(omega * t))
    p_an = A / omega * t - A / omega**2 * np.sin(omega * t)
    p_e, v_e = euler_loop(a, 0.0, 0.0, DT)
    return p_an, v_an, p_e, v_e


def phi(dt, k=1):
    s = k * dt
    return np.array([[1, s, -s**2 / 2], [0, 1, -s], [0, 0, 1]])


def two_sided(dof, divide, alpha=0.05):
    return np.array(stats.chi2.interval(1 - alpha, dof)) / divide


def filterpy_gain_at_second_fix():
    m = error_state_model(CalibrationParams())
    kf = KalmanFilter(dim_x=3, dim_z=2)
    kf.F, kf.Q, kf.H, kf.R = m.Phi, m.Q, m.H, m.V
    kf.x, kf.P = np.zeros((3, 1)), m.M0.copy()
    kf.update(np.zeros((2, 1)))
    for _ in range(40):
        kf.predict()
    kf.update(np.zeros((2, 1)))
    return kf.K.copy(), kf


def predict_loop(x, P, Phi, Q, n, q=True, transposed=False):
    for _ in range(n):
        x = Phi @ x
        P = (Phi.T @ P @ Phi if transposed else Phi @ P @ Phi.T) + (Q if q else 0)
    return x, P


def noise_sum_closed_form(n, dt=DT, W=4e-4):
    """sum_{j<n} Phi^j Q Phi^jT with Phi^j Gamma = [-dt^2/2 - j dt^2, -dt, 0] (closed form)."""
    j = np.arange(n)
    g = np.stack([-dt**2 / 2 - j * dt**2, -dt * np.ones(n), np.zeros(n)], axis=1)
    return W * g.T @ g


def coast(P0, n, q=True):
    F = phi(DT, n)
    return F @ P0 @ F.T + (noise_sum_closed_form(n) if q else 0)


# --------------------------------------------------------------------------------------------
# the table: check, right answer, [(hint key, wrong answer)], extra accepted answers
# --------------------------------------------------------------------------------------------
def cases():
    out = {}
    # 01.1 --------------------------------------------------------------------------------
    p_an, v_an, p_e, v_e = truths(0.8, 10.0)
    approx = DT / 2 * A * np.sin(8.0)
    out["01.1"] = (ex.check_euler_velocity_gap, v_an[-1] - v_e[-1],
                   [("sign", v_e[-1] - v_an[-1]), ("no_half", DT * A * np.sin(8.0)),
                    ("omega", DT / 2 * A * np.sin(2.0)), ("hertz", DT / 2 * A * np.sin(2 * np.pi * 8.0)),
                    ("position", DT / 2 * A / 0.8 * (1 - np.cos(8.0))), ("bound", DT / 2 * A)], [approx])
    # 01.2 --------------------------------------------------------------------------------
    p_an, v_an, p_e, v_e = truths(0.8, 30.0)
    out["01.2"] = (ex.check_euler_position_gap_max, np.max(np.abs(p_an - p_e)),
                   [("no_two", 0.03125), ("velocity", 0.025), ("units", DT * A / 0.64), ("omega", 0.25),
                    ("full_dt", 0.125)], [DT * A / 0.8])
    # 02.1 --------------------------------------------------------------------------------
    out["02.1"] = (ex.check_imu_drift, [2 - 6 - 10, -0.3 - 1.0],
                   [("sign", [2 - 6 + 10, -0.3 + 1]), ("no_half", [2 - 6 - 20, -1.3]), ("no_dv0_t", [2 - 10, -1.3]),
                    ("swapped", [-1.3, -14]), ("no_initial", [-10, -1])], [np.array([[-14.0], [-1.3]])])
    # 02.2 --------------------------------------------------------------------------------
    dt, W, n = 0.01, 4e-4, 2000
    sig_v = np.sqrt(W) * dt * np.sqrt(n)
    sig_p = np.sqrt(W * dt**4 * np.sum((np.arange(n) + 0.5) ** 2))
    sig_p200 = np.sqrt(W * DT**4 * np.sum((np.arange(4000) + 0.5) ** 2))
    out["02.2"] = (ex.check_imu_random_walk, [sig_p, sig_v],
                   [("variance", [sig_p**2, sig_v**2]), ("rate", [sig_p200, np.sqrt(W * DT * 20)]),
                    ("no_dt", [np.sqrt(W * 8000 / 3), np.sqrt(W * 20)]), ("linear", [0.02 * 200, 0.02 * 20]),
                    ("swapped", [sig_v, sig_p]), ("no_third", [np.sqrt(W * dt * 8000), sig_v]),
                    *[("steps", [np.sqrt(W * dt**4 * np.sum((np.arange(m) + 0.5) ** 2)), np.sqrt(W * m) * dt])
                      for m in (n - 1, n + 1)]],
                   [[np.sqrt(W * dt * 8000 / 3), sig_v]])
    # 02.3 --------------------------------------------------------------------------------
    out["02.3"] = (ex.check_imu_std_band, 0.02 * np.sqrt(two_sided(49, 49)),
                   [("n_dof", 0.02 * np.sqrt(two_sided(50, 50))), ("variance", 4e-4 * two_sided(49, 49)),
                    ("one_sided", 0.02 * np.sqrt(two_sided(49, 49, alpha=0.1))),
                    ("no_divide", 0.02 * np.sqrt(two_sided(49, 1))),
                    ("normal", 0.02 * (1 + np.array([-1, 1]) * stats.norm.ppf(0.975) / np.sqrt(98))),
                    ("normal", 0.02 * (1 + np.array([-1, 1]) * 1.96 / np.sqrt(98)))], [])
    # 03.1 --------------------------------------------------------------------------------
    idx = [50 * i for i in range(121)]
    out["03.1"] = (ex.check_gps_fix_indices, idx,
                   [("no_last", idx[:-1]), ("no_first", idx[1:]), ("times", [0.25 * i for i in range(121)]),
                    ("rate", list(range(0, 6001, 40))), ("one_based", [i + 1 for i in idx])],
                   [np.array(idx, dtype=np.int64)])
    # 03.2 --------------------------------------------------------------------------------
    out["03.2"] = (ex.check_gps_dz, [2.47, -0.058],
                   [("sign", [-2.47, 0.058]), ("swapped", [-0.058, 2.47]), ("noise", [0.56, -0.038]),
                    ("truth", [1.91, -0.02])], [])
    # 03.3 --------------------------------------------------------------------------------
    out["03.3"] = (ex.check_gps_rms_band, 0.04 * np.sqrt(two_sided(100, 100)),
                   [("n_minus_1", 0.04 * np.sqrt(two_sided(99, 99))), ("variance", 0.0016 * two_sided(100, 100)),
                    ("one_sided", 0.04 * np.sqrt(two_sided(100, 100, alpha=0.1))),
                    ("normal", 0.04 * (1 + np.array([-1.959963984540054, 1.959963984540054]) / np.sqrt(200)))], [])
    # 04.1 --------------------------------------------------------------------------------
    d = 0.01
    right = phi(d)
    out["04.1"] = (ex.check_phi_100hz, right,
                   [("sign_corner", right + [[0, 0, d**2], [0, 0, 0], [0, 0, 0]]),
                    ("dt_corner", right + [[0, 0, d**2 / 2 - d], [0, 0, 0], [0, 0, 0]]),
                    ("signs_bias", np.abs(right)), ("rate", phi(DT)), ("transposed", right.T),
                    ("no_half", right - [[0, 0, d**2 / 2], [0, 0, 0], [0, 0, 0]])], [right.tolist()])
    # 04.2 --------------------------------------------------------------------------------
    out["04.2"] = (ex.check_gamma_100hz, [-5e-5, -0.01, 0.0],
                   [("dt_first", [-0.01, -0.01, 0.0]), ("no_half", [-1e-4, -0.01, 0.0]),
                    ("rate", [-1.25e-5, -0.005, 0.0]), ("bias_noise", [-5e-5, -0.01, 1.0]),
                    ("dt_first", [0.01, 0.01, 0.0]), ("bias_noise", [5e-5, 0.01, -1.0])],  # the same with -Γ
                   [np.array([[-5e-5], [-0.01], [0.0]]), [5e-5, 0.01, 0.0]])  # -Γ: the same Q = W Γ Γᵀ
    # 04.3 --------------------------------------------------------------------------------
    right = np.linalg.matrix_power(phi(d), 25)
    out["04.3"] = (ex.check_phi_fix_to_fix, right,
                   [("linear", np.eye(3) + 25 * (phi(d) - np.eye(3))), ("steps", np.linalg.matrix_power(phi(d), 40)),
                    ("rate", np.linalg.matrix_power(phi(DT), 25)), ("signs", np.abs(right)),
                    ("one_short", np.linalg.matrix_power(phi(d), 24))], [phi(0.25)])
    # 04.4 --------------------------------------------------------------------------------
    out["04.4"] = (ex.check_m0, np.diag([25.0, 0.25, 0.0025]),
                   [("sigmas", np.diag([5.0, 0.5, 0.05])), ("swapped", np.diag([0.25, 25.0, 0.0025])),
                    ("default", np.diag([100.0, 1.0, 0.01]))], [])
    # 05.2 --------------------------------------------------------------------------------
    right = np.array([[100 / 104, 0], [0, 1 / 1.01], [0, 0]])
    out["05.2"] = (ex.check_first_gain, right,
                   [("default_v", [[100 / 101, 0], [0, 1 / 1.0016], [0, 0]]),
                    ("swapped", [[100 / 100.01, 0], [0, 1 / 5], [0, 0]]), ("no_p_in_s", [[25, 0], [0, 100], [0, 0]]),
                    ("no_p", [[1 / 104, 0], [0, 1 / 1.01], [0, 0]])], [])
    # 05.3 --------------------------------------------------------------------------------
    K, _ = filterpy_gain_at_second_fix()
    m = error_state_model(CalibrationParams())
    S0 = m.M0[:2, :2] + m.V
    K0 = m.M0[:, :2] @ np.linalg.inv(S0)
    P_first = (np.eye(3) - K0 @ m.H) @ m.M0  # a posteriori at t = 0

    def gain(P):
        return P[:, :2] @ np.linalg.inv(P[:2, :2] + m.V)

    out["05.3"] = (ex.check_second_gain, K,
                   [("one_short", gain(coast(P_first, 39))), ("one_long", gain(coast(P_first, 41))),
                    ("no_q", gain(coast(P_first, 40, q=False))), ("no_first_update", gain(coast(m.M0, 40))),
                    ("once_per_fix", gain(coast(P_first, 1))), ("first_gain", K0),
                    ("fix_phi_one_q", gain(coast(P_first, 40, q=False) + noise_sum_closed_form(1)))], [])
    # 06.1 --------------------------------------------------------------------------------
    out["06.1"] = (ex.check_mc_nis_bounds, two_sided(100, 50),
                   [("dim3", two_sided(150, 50)), ("dim1", two_sided(50, 50)), ("one_sided", two_sided(100, 50, 0.1)),
                    ("sum", two_sided(100, 1)), ("n_minus_1", two_sided(98, 49))], [])
    # 06.2 --------------------------------------------------------------------------------
    z = 1.959963984540054
    out["06.2"] = (ex.check_fisher_band, np.tanh(np.arctanh(0.8) + np.array([-z, z]) / np.sqrt(297)),
                   [("sqrt_n", np.tanh(np.arctanh(0.8) + np.array([-z, z]) / np.sqrt(300))),
                    ("linear", 0.8 + np.array([-z, z]) / np.sqrt(297)),
                    ("z_space", np.arctanh(0.8) + np.array([-z, z]) / np.sqrt(297)),
                    ("one_sided", np.tanh(np.arctanh(0.8) + np.array([-1.6448536269514722, 1.6448536269514722])
                                          / np.sqrt(297))),
                    ("z_rounded", np.tanh(np.arctanh(0.8) + np.array([-1.96, 1.96]) / np.sqrt(297))),
                    ("z_two", np.tanh(np.arctanh(0.8) + np.array([-2.0, 2.0]) / np.sqrt(297)))], [])
    # 06.3 --------------------------------------------------------------------------------
    # the seven checks' entries at 151 fixes: 3 + 6 + 9 + 2 + 1 + 1 per fix and 4 per pair of fixes, one family
    lvl = 0.05 / (151 * (3 + 6 + 9 + 2 + 1 + 1) + 4 * (151 * 150 // 2))
    out["06.3"] = (ex.check_simultaneous_nees_band, two_sided(3000, 1000, lvl),
                   [("pointwise", two_sided(3000, 1000)), ("fixes_only", two_sided(3000, 1000, 0.05 / 151)),
                    ("per_check", two_sided(3000, 1000, 0.05 / 7 / 151)), ("one_sided", two_sided(3000, 1000, 2 * lvl)),
                    ("dim2", two_sided(2000, 1000, lvl)), ("sum", two_sided(3000, 1, lvl)),
                    ("dof3", two_sided(3, 1, lvl))], [])
    # 07.1 --------------------------------------------------------------------------------
    w = 2 * np.pi * 0.1
    t = np.linspace(0, 30, 300001)
    jerk = np.gradient(DT / 2 * A * np.sin(w * t), t)  # d/dt of the velocity mismatch
    out["07.1"] = (ex.check_apparent_bias, np.max(np.abs(jerk)),
                   [("velocity", 0.025), ("hertz", DT / 2 * A * 0.1), ("no_half", DT * A * w),
                    ("second_derivative", DT / 2 * A * w**2), ("omega", DT / 2 * A * 0.2)], [])
    # 15.1 --------------------------------------------------------------------------------
    tg = np.arange(151) / 5
    eps = 1e-6
    right = ((tg > 5 - eps) & (tg < 7 - eps)) | ((tg > 20 - eps) & (tg < 21.5 - eps))
    closed = ((tg > 5 - eps) & (tg < 7 + eps)) | ((tg > 20 - eps) & (tg < 21.5 + eps))
    open_start = ((tg > 5 + eps) & (tg < 7 - eps)) | ((tg > 20 + eps) & (tg < 21.5 - eps))
    out["15.1"] = (ex.check_outage_mask, right,
                   [("closed", closed), ("open_start", open_start), ("inverted", ~right),
                    ("imu_rate", np.zeros(6001, bool))], [right.astype(int).tolist()])
    # 15.2 --------------------------------------------------------------------------------
    P0 = np.diag([0.04, 1e-4, 1e-6])
    sd = lambda P: np.sqrt(np.diag(P))  # noqa: E731
    out["15.2"] = (ex.check_outage_sigma, sd(coast(P0, 2040)),
                   [("from_gap_start", sd(coast(P0, 2000))), ("no_q", sd(coast(P0, 2040, q=False))),
                    ("variance", np.diag(coast(P0, 2040)))], [])
    # 16.1 --------------------------------------------------------------------------------
    dz16 = np.array([[3.0, -0.5], [2.5, -0.45]])
    assert np.array_equal(ex.BATCH_TWO_FIXES_DZ, dz16)
    kf = KalmanFilter(dim_x=3, dim_z=2)                  # the filter on the same two fixes: the same mean
    kf.F, kf.Q, kf.H, kf.R = m.Phi, m.Q, m.H, m.V
    kf.x, kf.P = np.zeros((3, 1)), m.M0.copy()
    kf.update(dz16[0][:, None])
    for _ in range(40):
        kf.predict()
    x_prior1 = kf.x[:, 0].copy()                          # a priori at 0.2 s: conditioned on dz_0 only
    kf.update(dz16[1][:, None])
    Pi1 = coast(m.M0, 40)
    only_last = Pi1[:, :2] @ np.linalg.solve(Pi1[:2, :2] + m.V, dz16[1])
    C10 = phi(DT, 40) @ m.M0

    def cond_mean(Pi1, z, v=True):
        Sxz = np.hstack([C10[:, :2], Pi1[:, :2]])
        Czz = np.block([[m.M0[:2, :2], C10[:2, :2].T], [C10[:2, :2], Pi1[:2, :2]]])
        return Sxz @ np.linalg.solve(Czz + (np.kron(np.eye(2), m.V) if v else 0), z)

    right16 = kf.x[:, 0]
    assert np.allclose(cond_mean(Pi1, dz16.ravel()), right16, rtol=1e-9)   # conditioning = filter
    no_q_sum = cond_mean(coast(m.M0, 40, q=False), dz16.ravel())  # the process-noise sum of the 40 steps dropped
    out["16.1"] = (ex.check_batch_two_fixes, right16,
                   [("only_last", only_last), ("prior", x_prior1), ("unconditioned", np.zeros(3)),
                    ("sign", -right16), ("no_v", cond_mean(Pi1, dz16.ravel(), v=False)),
                    ("swapped", cond_mean(Pi1, dz16[::-1].ravel())), ("no_q_sum", no_q_sum)], [])
    # 16.2 --------------------------------------------------------------------------------
    p10 = CalibrationParams(duration=10.0)
    P, P_prior, _, _ = covariance_sequence(p10)
    xz = np.zeros((p10.n_gps, 3))
    _, Ps = rts_smooth_fixes(p10, xz, xz, P_prior, P[p10.fix_indices])
    full = covariance_sequence(CalibrationParams())[0][-1, 2, 2]
    out["16.2"] = (ex.check_smoothed_bias_sigma, np.sqrt(Ps[0, 2, 2]),
                   [("full_run", np.sqrt(full)), ("prior", np.sqrt(P_prior[-1, 2, 2])), ("filtered", 0.1),
                    ("variance", Ps[0, 2, 2])], [])
    return out


CASES = cases()
NUMERIC = sorted(CASES)


def _assert_feedback(fb, exercise):
    assert isinstance(fb, Feedback)
    assert fb.exercise == exercise
    assert "\n" not in str(fb)


@pytest.mark.parametrize("exercise", NUMERIC)
def test_accepts_right_answer(exercise):
    check, right, _, also = CASES[exercise]
    for answer in [right, *also]:
        fb = check(answer)
        _assert_feedback(fb, exercise)
        assert fb.correct, (exercise, str(fb))
        assert str(fb).startswith(f"✔ {exercise} correct")


@pytest.mark.parametrize("exercise", NUMERIC)
def test_rejects_each_wrong_answer_with_its_hint(exercise):
    check, _, wrong, _ = CASES[exercise]
    listed = {k for k in HINTS[exercise]} - {"shape", "tuple", "length", "type", "unknown", "missing"}
    assert listed <= {k for k, _ in wrong}, f"untested hints of {exercise}: {listed - {k for k, _ in wrong}}"
    for key, answer in wrong:
        fb = check(answer)
        _assert_feedback(fb, exercise)
        assert not fb.correct and fb.answered
        assert HINTS[exercise][key] in fb.message, (exercise, key, str(fb))
        assert str(fb).startswith(f"✘ {exercise} not yet: ")


@pytest.mark.parametrize("exercise", NUMERIC)
def test_unknown_wrong_answer_gets_the_generic_hint(exercise):
    check, right, _, _ = CASES[exercise]
    fb = check(np.asarray(right, dtype=float) * 1.37 + 0.11)
    assert not fb.correct and fb.message == GENERIC[exercise]


@pytest.mark.parametrize("exercise", NUMERIC + ["01.3", "05.1", "06.4", "07.2", "07.3"])
def test_placeholder_is_not_answered_yet(exercise):
    check = CASES[exercise][0] if exercise in CASES else FUNCTION_CHECKS[exercise]
    for placeholder in (None, ...):
        fb = check(placeholder)
        assert not fb.correct and not fb.answered
        assert str(fb).startswith(f"✘ {exercise} not answered yet: ")


@pytest.mark.parametrize("exercise", NUMERIC)
def test_malformed_answers_give_a_hint(exercise):
    check, right, _, _ = CASES[exercise]
    size = np.size(right)
    for bad in ("0.5", "abc", np.zeros(size + 1), [[1, 2], [3]], {"a": 1}, lambda x: x, [np.nan] * size,
                np.full(size, np.inf), object()):
        fb = check(bad)
        _assert_feedback(fb, exercise)
        assert not fb.correct and fb.answered and fb.message


@pytest.mark.parametrize("exercise", ["04.1", "04.3", "04.4"])
def test_transposed_or_flat_matrix_gets_a_shape_hint(exercise):
    check, right, _, _ = CASES[exercise]
    fb = check(np.ravel(right))
    assert "has shape (9,): the exercise asks for a matrix" in fb.message and "(3, 3)" not in fb.message, str(fb)


def test_transposed_gain_gets_the_shape_hint():
    right = CASES["05.2"][1]
    for bad in (np.transpose(right), np.ravel(right)):
        fb = ex.check_first_gain(bad)
        assert not fb.correct and fb.message == HINTS["05.2"]["shape"]
    fb = ex.check_second_gain(np.transpose(CASES["05.3"][1]))
    assert not fb.correct and "is transposed (shape (2, 3))" in fb.message, str(fb)


# --------------------------------------------------------------------------------------------
# function exercises: 01.3, 05.1, 06.4, 07.2; the set exercise 07.3
# --------------------------------------------------------------------------------------------
FUNCTION_CHECKS = {"01.3": ex.check_euler_truth, "05.1": ex.check_predict_only, "06.4": ex.check_mean_error_band,
                   "07.2": ex.check_trapezoid_velocity, "07.3": ex.check_mismatch_failures}


def test_euler_truth_check():
    check = ex.check_euler_truth
    assert check(lambda a, p0, v0, dt: euler_loop(a, p0, v0, dt)).correct
    assert check(lambda a, p0, v0, dt: list(euler_loop(a, p0, v0, dt))).correct  # a list is fine too
    for kind in ("new_v", "no_acc", "dt2", "right"):
        fb = check(lambda a, p0, v0, dt, kind=kind: euler_loop(a, p0, v0, dt, kind))
        assert not fb.correct and HINTS["01.3"][kind] in fb.message, (kind, str(fb))
    fb = check(lambda a, p0, v0, dt: euler_loop(a, p0, v0, dt)[::-1])
    assert HINTS["01.3"]["swapped"] in fb.message
    fb = check(lambda a, p0, v0, dt: tuple(x[:-1] for x in euler_loop(a, p0, v0, dt)))
    assert HINTS["01.3"]["length"] in fb.message
    for out in (np.zeros(7), "p, v", (np.zeros(7), np.zeros(7), np.zeros(7)), 3.0):
        fb = check(lambda a, p0, v0, dt, out=out: out)
        assert not fb.correct and fb.message == HINTS["01.3"]["tuple"]
    fb = check(lambda a, p0, v0, dt: (np.zeros(7), euler_loop(a, p0, v0, dt)[1]))
    assert fb.message.startswith("v is right, p is not")


def test_predict_only_check():
    check = ex.check_predict_only

    def right(x, P, Phi, Q, n):
        return predict_loop(x, P, Phi, Q, n)

    assert check(right).correct
    assert check(lambda *a: (right(*a)[0].reshape(3, 1), right(*a)[1])).correct  # column x accepted
    wrong = {"no_q": lambda x, P, Phi, Q, n: predict_loop(x, P, Phi, Q, n, q=False),
             "transposed": lambda x, P, Phi, Q, n: predict_loop(x, P, Phi, Q, n, transposed=True),
             "x_static": lambda x, P, Phi, Q, n: (x, predict_loop(x, P, Phi, Q, n)[1]),
             "one_short": lambda x, P, Phi, Q, n: predict_loop(x, P, Phi, Q, n - 1),
             "one_long": lambda x, P, Phi, Q, n: predict_loop(x, P, Phi, Q, n + 1),
             "q_once": lambda x, P, Phi, Q, n: (predict_loop(x, P, Phi, Q, n)[0],
                                                predict_loop(x, P, Phi, Q, n, q=False)[1] + Q),
             "p_static": lambda x, P, Phi, Q, n: (predict_loop(x, P, Phi, Q, n)[0], P)}
    assert set(wrong) == set(HINTS["05.1"]) - {"tuple"}
    for key, func in wrong.items():
        fb = check(func)
        assert not fb.correct and HINTS["05.1"][key] in fb.message, (key, str(fb))
    for out in (np.zeros(3), (np.zeros(3),), (np.zeros(2), np.eye(3)), (np.zeros(3), np.eye(2)), "x"):
        fb = check(lambda *a, out=out: out)
        assert fb.message == HINTS["05.1"]["tuple"]
    fb = check(lambda x, P, Phi, Q, n: (predict_loop(x, P, Phi, Q, n)[0], np.eye(3)))
    assert fb.message.startswith("x̄ is right, M is not")


def mean_error_loops(e, alpha, rule="ok"):
    """The mean error and its band by plain loops over every entry (no numpy reductions over the ensemble);
    the quantile from scipy's Student-t interval (or the rule's wrong one)."""
    e = np.asarray(e, dtype=float)
    n = e.shape[0]
    e_bar, half = np.zeros(e.shape[1:]), np.zeros(e.shape[1:])
    for idx in np.ndindex(*e.shape[1:]):
        col = [e[(l, *idx)] for l in range(n)]
        mean = sum(col) / n
        ss = sum((x - mean) ** 2 for x in col)
        sd = (ss / (n if rule == "ddof0" else n - 1)) ** 0.5
        q = {"z": stats.norm.interval(1 - alpha)[1], "dof_n": stats.t.interval(1 - alpha, n)[1],
             "one_sided": stats.t.interval(1 - 2 * alpha, n - 1)[1], "two": 2.0,
             "fixed_alpha": stats.t.interval(0.95, n - 1)[1]}.get(rule, stats.t.interval(1 - alpha, n - 1)[1])
        se = {"no_sqrt_n": sd, "over_n": sd / n}.get(rule, sd / n ** 0.5)
        e_bar[idx], half[idx] = mean, q * se
    return e_bar, half


def test_mean_error_band_check():
    check = ex.check_mean_error_band
    assert check(mean_error_loops).correct
    assert check(lambda e, alpha: [list(x) for x in mean_error_loops(e, alpha)]).correct   # lists are fine too
    wrong = ("z", "dof_n", "ddof0", "no_sqrt_n", "over_n", "one_sided", "two", "fixed_alpha")
    assert set(wrong) == set(HINTS["06.4"]) - {"tuple", "axis"}
    for rule in wrong:
        fb = check(lambda e, alpha, rule=rule: mean_error_loops(e, alpha, rule))
        assert not fb.correct and fb.message == HINTS["06.4"][rule], (rule, str(fb))
    fb = check(lambda e, alpha: (e.mean(axis=1), mean_error_loops(e, alpha)[1]))
    assert not fb.correct and fb.message == HINTS["06.4"]["axis"], str(fb)
    for out in (np.zeros(15), (np.zeros((5, 3)),), "e_bar", (np.zeros((5, 3)), np.zeros((5, 3)), np.zeros((5, 3)))):
        fb = check(lambda e, alpha, out=out: out)
        assert not fb.correct and fb.message == HINTS["06.4"]["tuple"], str(fb)
    fb = check(lambda e, alpha: (mean_error_loops(e, alpha)[0], np.ones((5, 3))))
    assert fb.message.startswith("e_bar is right, the half-width is not")
    fb = check(lambda e, alpha: (mean_error_loops(e, alpha)[0] + 1.0, mean_error_loops(e, alpha)[1]))
    assert fb.message.startswith("e_bar is not the ensemble mean")
    fb = check(lambda e, alpha: (e.sort(axis=0), mean_error_loops(e, alpha))[1])   # sorts its input in place
    assert not fb.correct and "changed" in fb.message, str(fb)


def test_06_4_numbers_have_one_home_that_the_source_notebook_agrees_with():
    from pathlib import Path

    text = (Path(__file__).parents[1] / "notebooks" / "source" / "06_monte_carlo_validation.md").read_text(encoding="utf-8")
    n, n_fix, n_comp, alpha = ex.MEAN_ERROR_TEST
    assert n_comp == 3 and f"ensemble of {n} realizations of {n_fix} fixes with `alpha = {alpha:g}`" in text


def test_trapezoid_check():
    check = ex.check_trapezoid_velocity

    def loop(a, v0, dt, rule):
        v = [v0]
        for j in range(len(a) - 1):
            step = {"trap": (a[j] + a[j + 1]) / 2, "left": a[j], "right": a[j + 1], "no_half": a[j] + a[j + 1]}[rule]
            v.append(v[-1] + step * dt)
        return np.array(v)

    assert check(lambda a, v0, dt: loop(a, v0, dt, "trap")).correct
    assert check(lambda a, v0, dt: list(loop(a, v0, dt, "trap"))).correct
    for rule in ("left", "right", "no_half"):
        fb = check(lambda a, v0, dt, rule=rule: loop(a, v0, dt, rule))
        assert not fb.correct and HINTS["07.2"][rule] in fb.message
    fb = check(lambda a, v0, dt: loop(a, v0, dt, "trap")[1:])
    assert fb.message == HINTS["07.2"]["length"]
    fb = check(lambda a, v0, dt: "v")
    assert not fb.correct and "got str" in fb.message


@pytest.mark.parametrize("exercise", ["01.3", "05.1", "06.4", "07.2"])
def test_function_checks_survive_half_written_functions(exercise):
    check = FUNCTION_CHECKS[exercise]

    def raises(*args):
        raise ZeroDivisionError("division by zero\nsecond line")

    def wrong_arity(a):
        return a

    for bad, name in ((raises, "ZeroDivisionError"), (wrong_arity, "TypeError"),
                      (lambda *a: np.linalg.inv(np.zeros((3, 3))), "LinAlgError"),
                      (lambda *a: undefined_name, "NameError")):  # noqa: F821
        fb = check(bad)
        _assert_feedback(fb, exercise)
        assert not fb.correct and fb.answered and f"raised {name}" in fb.message, str(fb)
    fb = check(lambda *a: None)
    assert not fb.answered and "returns None" in fb.message
    for not_a_function in (3.0, "def f(): pass", np.zeros(3)):
        fb = check(not_a_function)
        assert not fb.correct and fb.answered and "expected a function" in fb.message


def test_apparent_bias_accepts_a_differenced_answer():
    from kfcal_helpers.calibration import acceleration
    from kfcal_helpers.exercises._core import ROUNDED_HINT

    p = CalibrationParams(omega=2 * np.pi * 0.1)
    right = p.dt / 2 * p.A * p.omega
    a = acceleration(p.t_imu, p)
    # what a student computes by differencing the sampled acceleration: off by about (ωΔt)²/6
    for answer in (np.abs(p.dt / 2 * np.diff(a) / p.dt).max(), np.abs(p.dt / 2 * np.gradient(a, p.dt)).max()):
        assert 1e-6 < abs(answer / right - 1) < 1e-5
        assert ex.check_apparent_bias(answer).correct
    # digits copied from a printout are still told so
    for copied in (0.0157, 0.01571, float(f"{right:.3g}")):
        fb = ex.check_apparent_bias(copied)
        assert not fb.correct and fb.message == ROUNDED_HINT


def test_mismatch_failures_check():
    check = ex.check_mismatch_failures
    m = error_state_model(CalibrationParams())
    from dataclasses import replace

    quiet = replace(m, W=m.W / 100, Q=m.Q / 100)
    mc = run_monte_carlo(CalibrationParams(), n_runs=1000, seed=77, model=quiet)
    failing = {name for name, c in mc.checks().items() if not c.passed}
    # what the exercise teaches: too small a P fails the checks that compare the spread with P
    assert failing == {"covariance", "nees"}
    for answer in (failing, sorted(failing), tuple(failing), frozenset(failing)):
        assert check(answer).correct
    from kfcal_helpers.calibration import CHECK_NAMES

    # a wrong set is told whether it holds a passing check, misses a failing one, or both, never which one
    # (naming them would solve the exercise by elimination)
    for extra in ("mean_error", "orthogonality", "nis", "residual_variance", "residual_independence"):
        for answer, key in ((failing | {extra}, "extra"), ({"nees", extra}, "mixed")):
            fb = check(answer)
            assert not fb.correct and fb.message == HINTS["07.3"][key], (answer, str(fb))
            assert not any(name in fb.message for name in CHECK_NAMES), str(fb)
    for partial in ({"nees"}, {"covariance"}, set()):
        fb = check(partial)
        assert not fb.correct and fb.message == HINTS["07.3"]["missing"]
        assert not any(name in fb.message for name in CHECK_NAMES), str(fb)
    fb = check({"nees", "NEES"})
    assert not fb.correct and "'NEES'" in fb.message and HINTS["07.3"]["unknown"] in fb.message
    for bad in ("nees", 3, {1, 2}, np.array([1.0]), lambda: None):
        fb = check(bad)
        assert not fb.correct and fb.answered and HINTS["07.3"]["type"] in fb.message


# --------------------------------------------------------------------------------------------
# package-level properties
# --------------------------------------------------------------------------------------------
def test_every_check_is_exported_and_has_one_record():
    checks = [n for n in ex.__all__ if n.startswith("check_")]
    assert len(checks) == 34 and len(set(checks)) == 34
    for name in checks:
        assert callable(getattr(ex, name)), name
    assert all(isinstance(e, Exercise) and e.id == i for i, e in EXERCISES.items())
    ids = set(CASES) | set(FUNCTION_CHECKS)
    assert ids | {"14.1", "14.2", "17.1", "17.2"} | {"02.4", "02.5", "03.4"} == set(EXERCISES)  # the last three: test_exercises_calibration_functions.py
    assert {i.split(".")[0] for i in ids} == {"01", "02", "03", "04", "05", "06", "07", "15", "16"}


def test_settings_are_keyword_only():
    """The naming and calling rule: check_<topic>(answer, *, settings...)."""
    import inspect

    for name in (n for n in ex.__all__ if n.startswith("check_")):
        params = list(inspect.signature(getattr(ex, name)).parameters.values())
        assert params[0].kind is inspect.Parameter.POSITIONAL_OR_KEYWORD, name
        assert all(p.kind is inspect.Parameter.KEYWORD_ONLY for p in params[1:]), name


def _numbers(text):
    return [float(x) for x in re.findall(r"(?<![\w.])\d+(?:\.\d+)?(?:e-?\d+)?", text)]


@pytest.mark.parametrize("exercise", ["02.2", "02.3"])
def test_four_significant_figures_get_the_message_of_what_was_rounded(exercise):
    """Copied to 4 significant figures, the right value is told it is rounded and each mistake that
    lies within 1e-3 of it (02.2 step count off by one, 02.3 normal approximation) gets its own hint."""
    check, right, wrong, _ = CASES[exercise]
    fig4 = lambda x: np.array([float(f"{v:.4g}") for v in np.ravel(x)])  # noqa: E731
    assert not check(fig4(right)).correct and check(fig4(right)).message == ROUNDED_HINT
    near = [(k, w) for k, w in wrong if k in ("steps", "normal")]
    assert len(near) == 2  # 02.2: one step too few or too many; 02.3: the normal approximation, z exact or 1.96
    for key, answer in near:
        assert np.max(np.abs(np.asarray(answer) - right)) / np.max(np.abs(right)) < 1e-3  # the case in point
        fb = check(fig4(answer))
        assert not fb.correct and HINTS[exercise][key] in fb.message, (key, str(fb))


@pytest.mark.parametrize("exercise", NUMERIC)
def test_hints_do_not_contain_the_answer(exercise):
    right = np.ravel(np.asarray(CASES[exercise][1], dtype=float))
    values = [v for v in np.abs(right) if v not in (0.0, 1.0)]
    for text in [*HINTS[exercise].values(), GENERIC[exercise]]:
        for x in _numbers(text):
            assert not any(np.isclose(x, v, rtol=1e-3) for v in values), (exercise, text, x)


@pytest.mark.parametrize("call, name", [
    (lambda: ex.check_euler_velocity_gap(0.1, omega=0.0), "omega"),
    (lambda: ex.check_euler_velocity_gap(0.1, t=40.0), "t"),
    (lambda: ex.check_euler_position_gap_max(0.1, omega=0.05), "omega"),
    (lambda: ex.check_imu_std_band([1, 2], n=1), "n"),
    (lambda: ex.check_gps_fix_indices([0], gps_rate=7.0), "gps_rate"),
    (lambda: ex.check_gps_dz([0, 0], z=(1.0,)), "z"),
    (lambda: ex.check_first_gain(np.zeros((3, 2)), V=np.eye(3)), "V"),
    (lambda: ex.check_mc_nis_bounds([1, 2], alpha=1.5), "alpha"),
    (lambda: ex.check_fisher_band([0, 1], rho=1.0), "rho"),
    (lambda: ex.check_mismatch_failures({"nees"}, n_runs=1), "n_runs"),
    (lambda: ex.check_outage_mask(np.zeros(151), windows=[(7.0, 5.0)]), "windows"),
    (lambda: ex.check_outage_sigma(np.zeros(3), P0=-np.eye(3)), "P0"),
    (lambda: ex.check_outage_sigma(np.zeros(3), start=0.0, end=2.0), "start"),
    (lambda: ex.check_smoothed_bias_sigma(0.1, duration=-1.0), "duration"),
])
def test_bad_parameters_raise_naming_them(call, name):
    with pytest.raises(ValueError, match=name):
        call()


def test_keyword_parameters_change_the_right_answer():
    # 02.1 with other values; 06.1 with another N; 04.1 at 50 Hz; 15.2 another window
    assert ex.check_imu_drift([0 - 0.1 * 50, -0.1 * 10], b=0.1, dp0=0.0, dv0=0.0, t=10.0).correct
    assert ex.check_mc_nis_bounds(two_sided(40, 20), n_runs=20).correct
    assert ex.check_phi_100hz(phi(0.02), imu_rate=50.0).correct
    P0 = np.diag([0.04, 1e-4, 1e-6])
    assert ex.check_outage_sigma(np.sqrt(np.diag(coast(P0, 440))), P0=P0, start=3.0, end=5.0).correct


@pytest.mark.parametrize("exercise", ["01.3", "02.1", "02.2", "03.2", "04.3", "05.1", "05.2", "05.3", "06.2", "07.2",
                                      "15.1"])
def test_generic_hint_is_a_nudge_not_the_formula(exercise):
    hint = GENERIC[exercise]
    assert not any(sym in hint for sym in ("=", "←", "⁻¹", "Σ", "√", "[[")), hint


def test_gamma_of_either_sign_is_right():
    right = np.array([-5e-5, -0.01, 0.0])
    fb = ex.check_gamma_100hz(-right)
    assert fb.correct and fb.message == ex.GAMMA_OTHER_SIGN_PRAISE and "same" in fb.message
    assert ex.check_gamma_100hz(right).message == PRAISE["04.2"]
    # the other sign rounded is told it is rounded, like the notebook's sign
    dt = 1 / 300
    flipped = np.array([dt**2 / 2, dt, 0.0])
    assert ex.check_gamma_100hz(flipped, imu_rate=300.0).correct
    assert ex.check_gamma_100hz([float(f"{x:.4g}") for x in flipped], imu_rate=300.0).message == ROUNDED_HINT


@pytest.mark.parametrize("exercise", NUMERIC)
def test_the_right_value_as_complex_is_not_right(exercise):
    """A complex answer never loses its imaginary part silently (no ComplexWarning, no praise)."""
    import warnings

    check, right, _, _ = CASES[exercise]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for answer in (np.asarray(right, dtype=float) + 1e-3j, np.asarray(right, dtype=complex)):
            fb = check(answer)
            assert not fb.correct and "complex" in fb.message, str(fb)


def test_batch_two_fixes_recognises_the_ill_conditioned_mistake_on_any_machine():
    """16.1's "no V" mistake solves with Σ_zz of condition number ~3e11: computations of it differ by
    ~1e-5 between BLAS builds, so the check recognises it at rtol 1e-3 (the right answer is ~10 % away)."""
    _, right, wrong, _ = CASES["16.1"]
    no_v = dict(wrong)["no_v"]
    assert not np.allclose(no_v, right, rtol=0.05)
    for factor in (1 + 3e-5, 1 - 2e-4):
        fb = ex.check_batch_two_fixes(no_v * factor)
        assert not fb.correct and HINTS["16.1"]["no_v"] in fb.message, str(fb)
    fb = ex.check_batch_two_fixes(no_v * 1.01)  # farther off: no longer that mistake
    assert not fb.correct and HINTS["16.1"]["no_v"] not in fb.message, str(fb)


# --------------------------------------------------------------------------------------------
# issue 32: shape hints that never reveal the size, units and order slips, one home for 03.1's numbers
# --------------------------------------------------------------------------------------------
def test_the_03_1_shape_hint_does_not_give_away_the_count():
    right = CalibrationParams(gps_rate=ex.GPS_FIX_RATE).fix_indices
    for bad in (right[:-3], np.r_[right, right[-1] + 50, right[-1] + 100]):
        fb = ex.check_gps_fix_indices(bad)
        assert not fb.correct and str(right.size) not in fb.message, str(fb)
        assert "not the shape the exercise asks for" in fb.message, str(fb)


def test_03_1_numbers_have_one_home_that_the_source_notebook_agrees_with():
    from pathlib import Path

    text = (Path(__file__).parents[1] / "notebooks" / "source" / "03_gps_model.md").read_text(encoding="utf-8")
    rate = f"{ex.GPS_FIX_RATE:g}"
    assert f"**Exercise 03.1 — fixes at {rate} Hz.** With a 200 Hz IMU and a {rate} Hz GPS" in text
    assert f"steps = 200 // {rate}\n" in text and f"$200/{rate} = " in text
    assert f"{rate} Hz" in EXERCISES["03.1"].praise and f"({rate} Hz)" in EXERCISES["03.1"].hints["rate"]


def test_06_3_numbers_are_the_package_s_family_and_the_source_notebook_agrees():
    """06.3's family is the seven checks judged together: the entries it counts are those run_monte_carlo's
    checks() split alpha over, and the exercise text and worked solution say so."""
    from pathlib import Path

    from kfcal_helpers.calibration import CHECK_NAMES, run_monte_carlo

    mc = run_monte_carlo(CalibrationParams(), 5, seed=0)
    assert ex.SIMULTANEOUS_NEES_ENTRIES == sum(c.statistic.size for c in mc.checks().values()) == sum(
        mc.entries(n) for n in CHECK_NAMES)
    text = (Path(__file__).parents[1] / "notebooks" / "source" / "06_monte_carlo_validation.md").read_text(encoding="utf-8")
    n = ex.SIMULTANEOUS_NEES_ENTRIES
    assert f"entries, {n:,} at the 151 fixes" in text and f"0.05 / {n}\n" in text and f"0.05/{n}$" in text
    assert f"{n:,}" in EXERCISES["06.3"].praise and f"{n:,}" in EXERCISES["06.3"].hints["per_check"]


@pytest.mark.parametrize("factor", [10.0, 100.0, 1000.0, 0.1, 0.01, 0.001])
def test_a_units_slip_is_named(factor):
    right = np.array([4521.37, 103.412]) - np.array([4518.90, 103.47])
    fb = ex.check_gps_dz(right * factor)
    assert not fb.correct and f"{factor:g} times the right one: check the units" in fb.message, str(fb)


def test_a_reversed_band_gets_the_order_hint():
    right = CASES["02.3"][1] if "02.3" in CASES else None
    if right is None:
        pytest.skip("no band case")
    fb = ex.check_imu_std_band(np.asarray(right)[::-1])
    assert not fb.correct and "reverse order" in fb.message and "[lower, upper]" in fb.message, str(fb)
