"""Exercise checks of notebooks 08-13 (kfcal_helpers.exercises.coop).

For every check: (1) it accepts the right answer, computed here by another route than the
check's (radius form of the arcs, finite differences, expm, complex exponentials, filterpy's
sigma points, scipy.special.gammaincinv); (2) it rejects each listed wrong answer, built here by
making the mistake, with that mistake's hint; (3) the placeholder gives "not answered yet";
(4) a malformed answer gives a hint, never an exception.
"""

import math

import numpy as np
import pytest
from filterpy.kalman import MerweScaledSigmaPoints
from scipy.linalg import expm
from scipy.special import gammaincinv

from dataclasses import replace

import kfcal_helpers.coop.exercises as exercises
from kfcal_helpers.coop import CoopParams, simulate
from kfcal_helpers.coop import exercises as coop
from kfcal_helpers.exercises._core import GENERIC_HINT, ROUNDED_HINT, Feedback

# 18.x: tests/test_coop_demos.py; 08.3 (a function answer): tests/test_exercises_coop_functions.py
HINTS = {ex: e.hints for ex, e in coop.EXERCISES.items() if not ex.startswith("18.") and ex != "08.3"}
P = CoopParams()
VG, PHI, VA, WA = P.u0


def wrap(a):
    """Angles wrapped by the complex exponential (a different route from the model's np.mod)."""
    out = np.angle(np.exp(1j * np.asarray(a, dtype=float)))
    return np.where(np.isclose(out, -np.pi, rtol=0, atol=1e-12), np.pi, out)


def chi2_ppf(q, dof):
    return 2.0 * gammaincinv(dof / 2.0, q)


def avg_bounds(dim, n, alpha, tails=None):
    lo, hi = tails if tails is not None else (alpha / 2, 1 - alpha / 2)
    return np.array([chi2_ppf(lo, dim * n), chi2_ppf(hi, dim * n)]) / n


# ---------------------------------------------------------------------------
# Model written out independently: the arcs in radius form, the CT dynamics by hand.
def arc_radius(x, u, dt, L=0.5):
    """Exact one-step map: xi + v/w (sin(th + w dt) - sin th), eta + v/w (cos th - cos(th + w dt))."""
    x = np.asarray(x, dtype=float)
    vg, phi, va, wa = u
    out = np.empty(6)
    for i, v, w in ((0, vg, vg * math.tan(phi) / L), (3, va, wa)):
        th = x[i + 2]
        if w == 0:
            out[i:i + 3] = x[i] + v * dt * math.cos(th), x[i + 1] + v * dt * math.sin(th), th
        else:
            out[i:i + 3] = (x[i] + v / w * (math.sin(th + w * dt) - math.sin(th)),
                            x[i + 1] + v / w * (math.cos(th) - math.cos(th + w * dt)), th + w * dt)
    out[[2, 5]] = wrap(out[[2, 5]])
    return out


def f_ct(x, u=tuple(P.u0), L=0.5):
    vg, phi, va, wa = u
    return np.array([vg * math.cos(x[2]), vg * math.sin(x[2]), vg * math.tan(phi) / L,
                     va * math.cos(x[5]), va * math.sin(x[5]), wa])


def fd(fun, x, eps=1e-6, angles=()):
    x = np.asarray(x, dtype=float)
    cols = []
    for i in range(x.size):
        d = np.zeros_like(x)
        d[i] = eps
        diff = np.asarray(fun(x + d)) - np.asarray(fun(x - d))
        for j in angles:
            diff[j] = wrap(diff[j])
        cols.append(diff / (2 * eps))
    return np.stack(cols, axis=-1)


def bearing_g(x):
    return math.atan2(x[4] - x[1], x[3] - x[0]) - x[2]


def h_by_hand(x):
    dxi, deta = x[3] - x[0], x[4] - x[1]
    return np.array([wrap(math.atan2(deta, dxi) - x[2]), math.sqrt(dxi ** 2 + deta ** 2),
                     wrap(math.atan2(-deta, -dxi) - x[5]), x[3], x[4]])


# ---------------------------------------------------------------------------
# Right answers (independent) and wrong answers (the mistake made here), by exercise.
def right_08_1():
    return arc_radius(coop.STEP_X, coop.STEP_U, coop.STEP_DT)


def chord(x, u, dt, L=0.5, *, length="sinc", mid=True, yaw_L=True, swap=False, wrapped=True):
    x = np.asarray(x, dtype=float)
    vg, phi, va, wa = u
    out = np.empty(6)
    for i, v, w in ((0, vg, vg * math.tan(phi) / (L if yaw_L else 1.0)), (3, va, wa)):
        th, a = x[i + 2], w * dt / 2
        d = {"sinc": v * dt * (math.sin(a) / a if a else 1.0), "np_sinc": v * dt * np.sinc(a), "none": v * dt}[length]
        direction = th + a if mid else th
        c, s = math.cos(direction), math.sin(direction)
        if swap:
            c, s = s, c
        out[i:i + 3] = x[i] + d * c, x[i + 1] + d * s, th + w * dt
    if wrapped:
        out[[2, 5]] = wrap(out[[2, 5]])
    return out


def wrong_08_1():
    x, u, dt = np.array(coop.STEP_X), coop.STEP_U, coop.STEP_DT
    euler = x + dt * f_ct(x, u)
    euler[[2, 5]] = wrap(euler[[2, 5]])
    vg, phi, va, wa = u
    wg = vg * math.tan(phi) / 0.5
    with np.errstate(all="ignore"):
        radius_form_uav = x[3] + np.float64(va) / np.float64(wa) * (math.sin(x[5] + wa * dt) - math.sin(x[5]))
    nan_answer = right_08_1()
    nan_answer[3] = radius_form_uav
    unwrapped = right_08_1()
    unwrapped[2] = x[2] + wg * dt
    return {
        "euler": euler,
        "start_heading": chord(x, u, dt, mid=False),
        "np_sinc": chord(x, u, dt, length="np_sinc"),
        "no_sinc": chord(x, u, dt, length="none"),
        "no_L": chord(x, u, dt, yaw_L=False),
        "cos_sin": chord(x, u, dt, swap=True),
        "wrap": unwrapped,
        "nan": nan_answer,
    }


def right_08_2():
    return h_by_hand(np.array(coop.MEAS_X))


def wrong_08_2():
    x = np.array(coop.MEAS_X)
    dxi, deta = x[3] - x[0], x[4] - x[1]
    right = right_08_2()

    def with_bearings(b1, b2):
        y = right.copy()
        y[0], y[2] = wrap(b1), wrap(b2)
        return y

    raw = right.copy()
    raw[0] = math.atan2(deta, dxi) - x[2]
    assert abs(raw[0]) > np.pi  # the exercise's configuration needs the wrap
    squared = right.copy()
    squared[1] = dxi ** 2 + deta ** 2
    ugv = right.copy()
    ugv[3:] = x[:2]
    return {
        "wrap": raw,
        "atan2_order": with_bearings(math.atan2(dxi, deta) - x[2], math.atan2(-dxi, -deta) - x[5]),
        "atan": with_bearings(math.atan(deta / dxi) - x[2], math.atan(deta / dxi) - x[5]),
        "no_heading": with_bearings(math.atan2(deta, dxi), math.atan2(-deta, -dxi)),
        "heading_sign": with_bearings(math.atan2(deta, dxi) + x[2], math.atan2(-deta, -dxi) + x[5]),
        "same_direction": with_bearings(math.atan2(deta, dxi) - x[2], math.atan2(deta, dxi) - x[5]),
        "range_squared": squared,
        "ugv_gps": ugv,
    }


def right_09_1():
    return fd(lambda z: np.array([bearing_g(z)]), coop.ROW_X, angles=(0,))[0]


def wrong_09_1():
    x = np.array(coop.ROW_X)
    dxi, deta = x[3] - x[0], x[4] - x[1]
    r2, r = dxi ** 2 + deta ** 2, math.hypot(dxi, deta)
    right = np.array([deta / r2, -dxi / r2, -1.0, -deta / r2, dxi / r2, 0.0])
    other = right.copy()
    other[2], other[5] = 0.0, -1.0
    plus, zero = right.copy(), right.copy()
    plus[2], zero[2] = 1.0, 0.0
    return {
        "vehicle_sign": np.array([-deta / r2, dxi / r2, -1.0, deta / r2, -dxi / r2, 0.0]),
        "over_r": np.array([deta / r, -dxi / r, -1.0, -deta / r, dxi / r, 0.0]),
        "swapped": np.array([dxi / r2, -deta / r2, -1.0, -dxi / r2, deta / r2, 0.0]),
        "heading_plus": plus,
        "heading_zero": zero,
        "other_bearing": other,
        "range_row": np.array([-dxi / r, -deta / r, 0.0, dxi / r, deta / r, 0.0]),
    }


def A_fd(x, u=tuple(P.u0)):
    return fd(lambda z: f_ct(z, u), x)


def right_09_2():
    return expm(coop.FDT_DT * A_fd(coop.FDT_X))


def wrong_09_2():
    x, dt = np.array(coop.FDT_X), coop.FDT_DT
    A = A_fd(x)
    sign = -A
    sin_cos = np.zeros((6, 6))
    sin_cos[0, 2], sin_cos[1, 2] = -VG * math.cos(x[2]), VG * math.sin(x[2])
    sin_cos[3, 5], sin_cos[4, 5] = -VA * math.cos(x[5]), VA * math.sin(x[5])
    speeds = np.zeros((6, 6))
    speeds[0, 2], speeds[1, 2] = -VA * math.sin(x[2]), VA * math.cos(x[2])
    speeds[3, 5], speeds[4, 5] = -VG * math.sin(x[5]), VG * math.cos(x[5])
    I = np.eye(6)
    return {"A_only": A, "no_dt": I + A, "notebook_dt": I + 0.1 * A, "transposed": (I + dt * A).T,
            "sign": I + dt * sign, "sin_cos": I + dt * sin_cos, "speeds": I + dt * speeds}


def obs_gps_by_hand(m):
    """O for the UAV's GPS rows over m steps from t = 0, built from the nominal UAV heading by hand."""
    H = np.zeros((2, 6))
    H[0, 3] = H[1, 4] = 1.0
    Phi, blocks = np.eye(6), []
    for k in range(m):
        blocks.append(H @ Phi)
        th = -np.pi / 2 + WA * k * P.dt  # nominal UAV heading at t_k
        F = np.eye(6)
        F[3, 5], F[4, 5] = -P.dt * VA * math.sin(th), P.dt * VA * math.cos(th)
        Phi = F @ Phi
    return np.vstack(blocks)


def right_09_3():
    ranks = []
    for m in coop.RANK_WINDOWS:
        s = np.linalg.svd(obs_gps_by_hand(m), compute_uv=False)
        ranks.append(int(np.sum(s > 1e-9 * s[0])))
    return np.array(ranks)


def wrong_09_3():
    r1, r10 = right_09_3()
    return {"no_motion": np.array([r1, r1]), "full": np.array([r1, 6]), "all_rows": np.array([5, 6]),
            "rows_count": np.array([r1, 2 * 10]), "one_step": np.array([r10, r10]), "whole": np.array([r1 + 0.5, r10]),
            "reversed": np.array([r10, r1])}


def right_10_1():
    N = coop.MC_RUNS
    return np.array([avg_bounds(6, N, 0.05), avg_bounds(5, N, 0.05)])


_Q_TRUE = np.diag([0.001, 0.001, 0.01, 0.001, 0.001, 0.01])   # the course's Qtrue, typed from the notebook


def right_09_4():
    Om = 0.05 * np.eye(6)   # Omega = dT I at the exercise's dT = 0.05 s
    return Om @ _Q_TRUE @ Om.T


def wrong_09_4():
    return {"one_dt": 0.05 * _Q_TRUE, "no_omega": _Q_TRUE, "notebook_dt": 0.01 * _Q_TRUE, "divided": _Q_TRUE / 0.05**2}


def wrong_10_1():
    N, z = coop.MC_RUNS, 1.959963984540054
    right = right_10_1()
    return {
        "one_sided": np.array([avg_bounds(6, N, 0, (0.05, 0.95)), avg_bounds(5, N, 0, (0.05, 0.95))]),
        "swapped_dims": right[::-1],
        "not_divided": right * N,
        "dof_N": np.array([[chi2_ppf(0.025, N), chi2_ppf(0.975, N)]] * 2) / N,
        "N_minus_1": np.array([avg_bounds(6, N - 1, 0.05), avg_bounds(5, N - 1, 0.05)]),
        "order": right[:, ::-1],
        "normal": np.array([[n - z * math.sqrt(2 * n / N), n + z * math.sqrt(2 * n / N)] for n in (6, 5)]),
        "notebook_N": np.array([avg_bounds(6, 50, 0.05), avg_bounds(5, 50, 0.05)]),
        "one_run": np.array([[chi2_ppf(0.025, n), chi2_ppf(0.975, n)] for n in (6, 5)]),   # chi2(n), not averaged
        "dim6": np.array([avg_bounds(6, N, 0.05), avg_bounds(6, N, 0.05)]),   # the NIS with the state's dimension
    }


def lkf_right(y, y_nom, H, dx):
    nu = (y - y_nom) - H @ dx
    nu[[0, 2]] = wrap(nu[[0, 2]])
    return nu


def _wrap_b(v):
    v = np.array(v, dtype=float)
    v[[0, 2]] = wrap(v[[0, 2]])
    return v


def wrong_10_2():
    return {
        "no_wrap": lambda y, yn, H, dx: (y - yn) - H @ dx,
        "no_nominal": lambda y, yn, H, dx: _wrap_b(y - H @ dx),
        "plus": lambda y, yn, H, dx: _wrap_b((y - yn) + H @ dx),
        "wrap_all": lambda y, yn, H, dx: wrap((y - yn) - H @ dx),
        "wrap_early": lambda y, yn, H, dx: _wrap_b(y - yn) - H @ dx,
        "no_H": lambda y, yn, H, dx: _wrap_b(y - yn),
        "wrap_2pi": lambda y, yn, H, dx: _mod_b((y - yn) - H @ dx),
    }


def _mod_b(d):
    """The bearings wrapped to [0, 2 pi) by a loop (a common wrong answer)."""
    d = np.array(d, dtype=float)
    for i in (0, 2):
        d[i] = d[i] % (2 * math.pi)
    return d


def residual_arctan2(a, b):  # gives -pi where the module's wrap gives pi: both accepted
    d = a - b
    d[[0, 2]] = np.arctan2(np.sin(d[[0, 2]]), np.cos(d[[0, 2]]))
    return d


def residual_mod(a, b):
    d = a - b
    d[[0, 2]] = (d[[0, 2]] + np.pi) % (2 * np.pi) - np.pi  # [-pi, pi)
    return d


def wrong_11_1():
    def mod(a, b):
        d = a - b
        d[[0, 2]] = np.mod(d[[0, 2]], 2 * np.pi)
        return d

    return {
        "no_wrap": np.subtract,
        "wrap_all": lambda a, b: wrap(a - b),
        "reversed": lambda a, b: residual_arctan2(b, a),
        "mod_2pi": mod,
        "shape": lambda a, b: residual_arctan2(a, b)[:, 0],
    }


def right_11_2():
    return np.eye(6) + P.dt * A_fd(coop.EKF_X)


def wrong_11_2():
    x = np.array(coop.EKF_X)
    prior = arc_radius(x, P.u0, P.dt)
    nominal = arc_radius(P.x0, P.u0, coop.EKF_T)  # the closed form over 3 s from x0
    A = A_fd(x)
    return {
        "prior": np.eye(6) + P.dt * A_fd(prior),
        "nominal": np.eye(6) + P.dt * A_fd(nominal),
        "A_only": A,
        "no_dt": np.eye(6) + A,
        "transposed": (np.eye(6) + P.dt * A).T,
        "exact_map": fd(lambda z: arc_radius(z, P.u0, P.dt), x, angles=(2, 5)),
    }


def right_12_1():
    m = coop.MERWE
    pts = MerweScaledSigmaPoints(m["n"], alpha=m["alpha"], beta=m["beta"], kappa=m["kappa"])
    lam = 1.0 / (2.0 * pts.Wm[1]) - m["n"]  # from W_i = 1 / (2 (n + lambda))
    return np.array([lam, pts.Wm[0], pts.Wc[0], pts.Wm[1]])


def wrong_12_1():
    n, a, b, k = coop.MERWE["n"], coop.MERWE["alpha"], coop.MERWE["beta"], coop.MERWE["kappa"]

    def weights(lam, n=n, extra=1 - a * a + b, wi=None):
        wm0 = lam / (n + lam)
        return np.array([lam, wm0, wm0 + extra, 1 / (2 * (n + lam)) if wi is None else wi])

    lam = a * a * (n + k) - n
    right = right_12_1()
    bad_sum = right.copy()
    bad_sum[3] *= 1.1  # Wm0 + 2 n Wi != 1
    return {
        "alpha_not_squared": weights(a * (n + k) - n),
        "wc0_equals_wm0": weights(lam, extra=0.0),
        "wc0_alpha": weights(lam, extra=1 - a + b),
        "wc0_beta_only": weights(lam, extra=b),   # the 1 - alpha^2 term left out
        "wi_lambda": weights(lam, wi=1 / (2 * lam)),
        "n_points": weights(a * a * (13 + k) - 13, n=13),
        "no_kappa": weights(a * a * n - n),
        "no_minus_n": weights(a * a * (n + k)),
        "sum": bad_sum,
    }


def circ_right(angles, weights):
    return float(np.angle(np.sum(weights * np.exp(1j * angles))))


def wrong_12_2():
    return {
        "plain": lambda a, w: float(np.dot(w, a)),
        "unweighted": lambda a, w: float(np.angle(np.exp(1j * a).sum())),
        "atan2_order": lambda a, w: math.atan2(np.dot(w, np.cos(a)), np.dot(w, np.sin(a))),
        "shifted": lambda a, w: float(wrap(np.dot(w, np.mod(a, 2 * np.pi)))),
        "arctan": lambda a, w: math.atan(np.dot(w, np.sin(a)) / np.dot(w, np.cos(a))),
        "size": lambda a, w: np.arctan2(np.sin(a), np.cos(a)),
        "wrap_2pi": lambda a, w: circ_right(a, w) % (2 * math.pi),
    }


@pytest.fixture(scope="module")
def updates_15s():
    """K of a simulated 15 s log in the course format: rows with a measurement."""
    log = simulate(replace(P, duration=15.0)).log()
    assert log.n_samples == coop.LOG_SAMPLES
    return int(np.isfinite(log.y[:, 0]).sum())


@pytest.fixture(scope="module")
def updates_every10():
    log = simulate(P).log().every(coop.SPARSE_EVERY)
    assert log.n_samples == coop.SPARSE_SAMPLES
    return int(np.isfinite(log.y[:, 0]).sum())


def wrong_13(K, alpha, notebook_alpha=True):
    z = {0.01: 2.5758293035489004, 0.05: 1.959963984540054}[alpha]
    out = {
        "count_nan": avg_bounds(5, K + 1, alpha),
        "one_sided": avg_bounds(5, K, 0, (alpha, 1 - alpha)),
        "dof_K": np.array([chi2_ppf(alpha / 2, K), chi2_ppf(1 - alpha / 2, K)]) / K,
        "not_divided": avg_bounds(5, K, alpha) * K,
        "dim6": avg_bounds(6, K, alpha),
        "normal": np.array([5 - z * math.sqrt(10 / K), 5 + z * math.sqrt(10 / K)]),
    }
    if notebook_alpha:
        out["notebook_alpha"] = avg_bounds(5, K, 0.05)
    return out


# registry: exercise -> (check, is_function_exercise)
CHECKS = {
    "08.1": (exercises.check_step_map, False),
    "08.2": (exercises.check_measurement, False),
    "09.1": (exercises.check_bearing_row, False),
    "09.2": (exercises.check_F_dt, False),
    "09.3": (exercises.check_obs_rank, False),
    "09.4": (exercises.check_omega_q, False),
    "10.1": (exercises.check_mc_bounds, False),
    "10.2": (exercises.check_lkf_innovation, True),
    "11.1": (exercises.check_ekf_residual, True),
    "11.2": (exercises.check_ekf_F, False),
    "12.1": (exercises.check_merwe_weights, False),
    "12.2": (exercises.check_circular_mean, True),
    "13.1": (exercises.check_log_nis_bounds, False),
    "13.2": (exercises.check_sparse_nis_bounds, False),
}

RIGHT = {"08.1": right_08_1, "08.2": right_08_2, "09.1": right_09_1, "09.2": right_09_2, "09.3": right_09_3,
         "09.4": right_09_4,
         "10.1": right_10_1, "10.2": lambda: lkf_right, "11.1": lambda: residual_arctan2, "11.2": right_11_2,
         "12.1": right_12_1, "12.2": lambda: circ_right}

WRONG = {"08.1": wrong_08_1, "08.2": wrong_08_2, "09.1": wrong_09_1, "09.2": wrong_09_2, "09.3": wrong_09_3,
         "09.4": wrong_09_4,
         "10.1": wrong_10_1, "10.2": wrong_10_2, "11.1": wrong_11_1, "11.2": wrong_11_2, "12.1": wrong_12_1,
         "12.2": wrong_12_2}


def _assert_one_line(fb, exercise):
    assert isinstance(fb, Feedback)
    assert fb.exercise == exercise
    assert "\n" not in str(fb) and str(fb).startswith(("✔ " if fb.correct else "✘ ") + exercise)


def test_all_checks_exported():
    checks = {name for name in coop.__all__ if name.startswith("check_")}
    assert checks == {c.__name__ for c, _ in CHECKS.values()} | {"check_subset_nis_bounds", "check_lost_directions",
                                                                "check_measure_function"}
    assert set(HINTS) == set(CHECKS)
    assert all(ex.id == key for key, ex in coop.EXERCISES.items())


@pytest.mark.parametrize("exercise", sorted(RIGHT))
def test_accepts_the_right_answer(exercise):
    check, _ = CHECKS[exercise]
    fb = check(RIGHT[exercise]())
    _assert_one_line(fb, exercise)
    assert fb.correct and fb.answered, str(fb)


def test_accepts_the_right_bounds(updates_15s, updates_every10):
    assert updates_15s == 150 and updates_every10 == 100
    fb = exercises.check_log_nis_bounds(avg_bounds(5, updates_15s, coop.LOG_ALPHA))
    assert fb.correct, str(fb)
    fb = exercises.check_sparse_nis_bounds(avg_bounds(5, updates_every10, 0.05))
    assert fb.correct, str(fb)


@pytest.mark.parametrize("exercise", ["10.1", "13.1", "13.2"])
def test_bounds_rounded_are_told_to_pass_the_computed_value(exercise, updates_15s, updates_every10):
    """One answer-format rule: the computed value, no rounding; a rounded copy is told so, at any precision."""
    right = {"10.1": right_10_1(), "13.1": avg_bounds(5, updates_15s, coop.LOG_ALPHA),
             "13.2": avg_bounds(5, updates_every10, 0.05)}[exercise]
    for decimals in (3, 4, 6):
        fb = CHECKS[exercise][0](np.round(right, decimals))
        assert not fb.correct and fb.message == ROUNDED_HINT, (decimals, str(fb))
    assert CHECKS[exercise][0](right).correct


def test_other_valid_forms_are_accepted():
    # -pi instead of pi, [-pi, pi) conventions and (5,) vs (5, 1) where the shape does not matter
    assert exercises.check_ekf_residual(residual_mod).correct
    assert exercises.check_lkf_innovation(lambda *a: lkf_right(*a).reshape(5, 1)).correct
    assert exercises.check_mc_bounds(right_10_1().ravel()).correct
    assert exercises.check_obs_rank([int(r) for r in right_09_3()]).correct
    assert exercises.check_circular_mean(lambda a, w: np.array([circ_right(a, w)])).correct
    # a function that modifies its inputs in place is told so, by the input's name (issue 32)
    def in_place(a, b):
        a -= b
        a[[0, 2]] = wrap(a[[0, 2]])
        return a

    for _ in range(2):  # the check's own inputs are unchanged: the same verdict twice
        fb = exercises.check_ekf_residual(in_place)
        assert not fb.correct and "don't modify your inputs" in fb.message and " a;" in fb.message, str(fb)


def _wrong_cases():
    cases = [(ex, key) for ex, builder in WRONG.items() for key in builder()]
    cases += [("13.1", k) for k in HINTS["13.1"]] + [("13.2", k) for k in HINTS["13.2"]]
    return cases


def test_every_hint_has_a_wrong_answer_test():
    tested = {}
    for ex, key in _wrong_cases():
        tested.setdefault(ex, set()).add(key)
    assert tested == {ex: set(h) for ex, h in HINTS.items()}


@pytest.mark.parametrize("exercise,mistake", _wrong_cases())
def test_rejects_wrong_answer_with_its_hint(exercise, mistake, updates_15s, updates_every10):
    check, _ = CHECKS[exercise]
    if exercise == "13.1":
        K, a = updates_15s, coop.LOG_ALPHA
        answer = wrong_13(K, a)[mistake]
    elif exercise == "13.2":
        K = updates_every10
        wrong = wrong_13(K, 0.05, notebook_alpha=False)
        wrong["all_steps"] = avg_bounds(5, (coop.SPARSE_SAMPLES - 1), 0.05)
        answer = wrong[mistake]
    else:
        answer = WRONG[exercise]()[mistake]
    fb = check(answer)
    _assert_one_line(fb, exercise)
    assert not fb.correct and fb.answered
    assert HINTS[exercise][mistake] in fb.message, str(fb)


def test_all_samples_counts_as_all_steps():
    fb = exercises.check_sparse_nis_bounds(avg_bounds(5, coop.SPARSE_SAMPLES, 0.05))
    assert HINTS["13.2"]["all_steps"] in fb.message


#: an unlisted mistake per exercise (12.1: one that keeps the mean weights summing to 1; 09.3: whole numbers)
#: (12.1: all four entries off, so that no entry is named, and Wm0 + 2n Wi still 1)
OFFSET = {"09.3": np.array([1.0, 1.0]), "12.1": np.array([0.37, 0.12, 0.37, -0.01])}


@pytest.mark.parametrize("exercise", sorted(RIGHT))
def test_unknown_wrong_answer_gets_the_generic_hint(exercise):
    check, is_fn = CHECKS[exercise]
    right = RIGHT[exercise]()
    offset = OFFSET.get(exercise, 0.37)
    if is_fn:
        answer = lambda *args: np.asarray(right(*args)) + offset  # noqa: E731
    else:
        answer = np.asarray(right, dtype=float) + offset
    fb = check(answer)
    assert not fb.correct and fb.answered
    assert fb.message == GENERIC_HINT, str(fb)


@pytest.mark.parametrize("exercise", sorted(CHECKS))
@pytest.mark.parametrize("placeholder", [Ellipsis, None])
def test_placeholder_is_not_answered_yet(exercise, placeholder):
    fb = CHECKS[exercise][0](placeholder)
    _assert_one_line(fb, exercise)
    assert not fb.correct and not fb.answered
    assert "not answered yet" in str(fb)


@pytest.mark.parametrize("exercise", [ex for ex, (_, is_fn) in CHECKS.items() if is_fn])
def test_function_with_an_empty_body_is_not_answered_yet(exercise):
    def todo(*args):
        ...

    fb = CHECKS[exercise][0](todo)
    assert not fb.answered and "returns None" in fb.message


def _raises(*args):
    raise ZeroDivisionError("division by zero")


@pytest.mark.parametrize("exercise", sorted(CHECKS))
@pytest.mark.parametrize("answer", ["abc", [[1.0, 2.0], [3.0]], np.zeros(7), 3.5, _raises, {"a": 1}],
                         ids=["string", "ragged", "wrong-shape", "scalar", "function", "dict"])
def test_malformed_answer_gives_a_hint(exercise, answer):
    check, is_fn = CHECKS[exercise]
    fb = check(answer)
    _assert_one_line(fb, exercise)
    assert not fb.correct and fb.answered and fb.message
    if is_fn and answer is _raises:
        assert "ZeroDivisionError" in fb.message
    elif is_fn:
        assert "expected a function" in fb.message


NAN_RESULT = {"10.2": np.full(5, np.nan), "11.1": np.full((5, 1), np.nan), "12.2": float("nan")}


@pytest.mark.parametrize("exercise", [ex for ex, (_, is_fn) in CHECKS.items() if is_fn])
@pytest.mark.parametrize("kind,words", [
    ("text", ("must return numbers",)),
    ("shape", ("shape", "single float")),
    ("nan", ("NaN",)),
    ("name", ("NameError",)),
    ("matmul", ("ValueError",)),
])
def test_broken_function_gives_a_hint(exercise, kind, words):
    bodies = {
        "text": lambda *a: "text",
        "shape": lambda *a: np.zeros(7),
        "nan": lambda *a: NAN_RESULT[exercise],
        "name": lambda *a: undefined_name,  # noqa: F821
        "matmul": lambda *a: np.ones((3, 3)) @ np.ones(2),
    }
    fb = CHECKS[exercise][0](bodies[kind])
    _assert_one_line(fb, exercise)
    assert not fb.correct and fb.answered
    assert any(w in fb.message for w in words), str(fb)



def test_hints_never_contain_the_answer(updates_15s, updates_every10):
    numbers = [right_08_1(), right_08_2(), right_09_1(), right_09_2(), right_10_1(), right_11_2(), right_12_1(),
               avg_bounds(5, updates_15s, coop.LOG_ALPHA), avg_bounds(5, updates_every10, 0.05)]
    values = [v for arr in numbers for v in np.ravel(arr) if abs(v - round(v)) > 1e-6]
    texts = [h for hints in HINTS.values() for h in hints.values()]
    for v in values:
        for digits in (2, 3, 4):
            token = f"{abs(v):.{digits}f}"
            assert not any(token in t for t in texts), (token, v)


def test_parameters_other_than_the_exercise_defaults():
    assert exercises.check_mc_bounds(np.array([avg_bounds(6, 50, 0.05), avg_bounds(5, 50, 0.05)]), n_runs=50).correct
    assert exercises.check_F_dt(expm(0.1 * A_fd(coop.FDT_X)), dt=0.1).correct
    x = np.array([1.0, 2.0, 0.3, -5.0, 7.0, 1.2])
    assert exercises.check_measurement(h_by_hand(x), x=x).correct
    assert exercises.check_step_map(arc_radius(x, P.u0, 0.1), x=x, u=P.u0, dt=0.1).correct
    assert exercises.check_sparse_nis_bounds(avg_bounds(5, 50, 0.05), every=20).correct


@pytest.mark.parametrize("call,name", [
    (lambda: exercises.check_mc_bounds(None, n_runs=1), "n_runs"),
    (lambda: exercises.check_step_map(None, dt=-0.1), "dt"),
    (lambda: exercises.check_step_map(None, x=[1.0, 2.0]), "x"),
    (lambda: exercises.check_obs_rank(None, windows=(10,)), "windows"),
    (lambda: exercises.check_ekf_F(None, t=0.05), "t"),
    (lambda: exercises.check_sparse_nis_bounds(None, every=1), "every"),
])
def test_bad_parameters_raise_value_error(call, name):
    with pytest.raises(ValueError, match=name):
        call()


def test_small_physical_errors_get_method_hints_and_only_roundings_are_told_so():
    """08.1: closeness is per component in its own units, not relative to the largest entry (40 m): a 0.035 rad
    heading error, a 3 cm position error or a sign slip is a method error, not a copied printout nor the sinc or
    mean-heading mistake; the right value (or a mistake's) rounded to a few decimals is told what it is."""
    right = right_08_1()
    x = np.array(coop.STEP_X)
    slips = [right + d for d in np.eye(6)[[2, 5]] * 0.035] + [right + d for d in np.eye(6)[[0, 3]] * 0.03]
    slip = right.copy()
    slip[1] = 2 * x[1] - right[1]  # the north displacement with the wrong sign
    names = ["theta_g", "theta_a", "xi_g", "xi_a", "eta_g"]   # issue 32: the hint names the slipped component
    for answer, name in zip([*slips, slip], names):
        fb = exercises.check_step_map(answer)
        assert not fb.correct and fb.message.startswith("only the ") and f"{name} is off" in fb.message, (answer, str(fb))
    for decimals in (2, 3, 5):
        assert exercises.check_step_map(np.round(right, decimals)).message == ROUNDED_HINT
    no_sinc = wrong_08_1()["no_sinc"]
    assert exercises.check_step_map(np.round(no_sinc, 4)).message == HINTS["08.1"]["no_sinc"]


@pytest.mark.parametrize("exercise", sorted(RIGHT))
def test_the_right_value_as_complex_is_not_right(exercise):
    """A complex answer (or a function returning one) never loses its imaginary part silently."""
    import warnings

    check, is_fn = CHECKS[exercise]
    right = RIGHT[exercise]()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        if is_fn:
            answer = lambda *a: np.asarray(right(*a), dtype=complex)  # noqa: E731
        else:
            answer = np.asarray(right, dtype=float) + 1e-3j
        fb = check(answer)
        assert not fb.correct and "complex" in fb.message, str(fb)


# --------------------------------------------------------------------------------------------
# issue 32: 08.1's small slips named by component; degrees for radians
# --------------------------------------------------------------------------------------------
def _step_right():
    from kfcal_helpers.coop.model import step

    return step(np.array(exercises.STEP_X), np.array(exercises.STEP_U), exercises.STEP_DT, 0.5)


@pytest.mark.parametrize("delta, words", [
    ((0, 0, 0.035, 0, 0, 0), "only the UGV's heading theta_g is off"),
    ((0, 0, 0, 0, 0, -0.035), "only the UAV's heading theta_a is off"),
    ((0, 0, 0, 0.03, 0.03, 0), "only the UAV's east position xi_a and the UAV's north position eta_a are off"),
    ((0.03, 0, 0, 0, 0, 0), "only the UGV's east position xi_g is off"),
])
def test_step_map_names_the_component_that_slipped(delta, words):
    fb = exercises.check_step_map(_step_right() + np.array(delta))
    assert not fb.correct and fb.message.startswith(words), str(fb)


def test_step_map_headings_in_degrees_get_the_degree_hint():
    right = _step_right()
    fb = exercises.check_step_map(np.where([0, 0, 1, 0, 0, 1], np.degrees(right), right))
    assert not fb.correct and "in degrees" in fb.message, str(fb)



def test_08_2_catches_bearings_wrapped_to_0_2pi_and_the_source_states_its_x():
    from pathlib import Path

    from kfcal_helpers.coop.model import measure

    right = measure(np.array(exercises.MEAS_X))
    assert right[0] < 0 or right[2] < 0   # a negative bearing: [0, 2pi) differs from (-pi, pi]
    fb = exercises.check_measurement(np.where([1, 0, 1, 0, 0], np.mod(right, 2 * np.pi), right))
    assert not fb.correct and fb.message == HINTS["08.2"]["wrap"], str(fb)
    text = (Path(__file__).parents[1] / "notebooks" / "source" / "08_coop_nonlinear_model.md").read_text(encoding="utf-8")
    x = exercises.MEAS_X
    assert "x = np.array([" + ", ".join(f"{v:.1f}" for v in x) + "])" in text
    assert "$x = [" + ",\\ ".join(f"{v:g}" if v != x[5] else f"{v:.1f}" for v in x) + "]^T$" in text


def test_09_4_source_states_the_exercise_dt():
    from pathlib import Path

    text = (Path(__file__).parents[1] / "notebooks" / "source" / "09_coop_linearization.md").read_text(encoding="utf-8")
    dt = f"{exercises.OMEGA_DT:g}"
    assert f"for a sample period $\\Delta T = {dt}$ s" in text and f"Omega = {dt} * np.eye(6)" in text
