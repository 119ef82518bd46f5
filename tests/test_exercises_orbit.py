"""Exercise checks of notebooks 19-20 (kfcal_helpers.orbit.exercises).

For every check: (1) it accepts the right answer, computed here by another route than the check's
(complex numbers for positions and velocities, the orbit integrated by solve_ivp, finite differences,
a Taylor series for expm); (2) it rejects each listed wrong answer, built here by making the mistake,
with that mistake's hint; (3) the placeholder gives "not answered yet"; (4) slips get their hint.
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from kfcal_helpers.exercises._core import ROUNDED_HINT
from kfcal_helpers.orbit import exercises as ex
from kfcal_helpers.orbit.exercises import _shared

MU, RE, WE, R0 = 398600.0, 6378.0, 2 * math.pi / 86400, 6678.0


def hint(exercise, key):
    return ex.EXERCISES[exercise].hints[key]


def station_c(t, i, *, offset=1, rotate=True):
    """Station i's position and velocity as complex numbers X + iY (the Earth's rotation as e^{i omegaE t})."""
    th = (WE * t if rotate else 0.0) + (i - offset) * math.pi / 6
    pos = RE * np.exp(1j * th)
    return pos, 1j * WE * pos


def measurement_c(x, t, i, **kw):
    pos, vel = station_c(t, i, **kw)
    d = complex(x[0], x[2]) - pos
    dv = complex(x[1], x[3]) - vel
    rho = abs(d)
    return np.array([rho, (d.conjugate() * dv).real / rho, np.angle(d)])


# ---------------------------------------------------------------------------
# 19.1
X1, T1, S1 = np.array(_shared.MEAS_X), _shared.MEAS_T, _shared.MEAS_STATION


def test_19_1_accepts_the_measurement_computed_with_complex_numbers():
    fb = ex.check_station_measurement(measurement_c(X1, T1, S1))
    assert fb.correct, str(fb)


@pytest.mark.parametrize("key", ["zero_based", "no_rotation", "fixed_station", "reversed", "atan2_order"])
def test_19_1_names_each_mistake(key):
    right = measurement_c(X1, T1, S1)
    if key == "zero_based":
        wrong = measurement_c(X1, T1, S1, offset=0)
    elif key == "no_rotation":
        wrong = measurement_c(X1, T1, S1, rotate=False)
    elif key == "fixed_station":
        pos, _ = station_c(T1, S1)
        d = complex(X1[0], X1[2]) - pos
        wrong = np.array([abs(d), (d.conjugate() * complex(X1[1], X1[3])).real / abs(d), np.angle(d)])
    elif key == "reversed":
        wrong = right.copy()
        wrong[2] = np.angle(-np.exp(1j * right[2]))
    else:
        pos, _ = station_c(T1, S1)
        d = complex(X1[0], X1[2]) - pos
        wrong = right.copy()
        wrong[2] = math.atan2(d.real, d.imag)
    fb = ex.check_station_measurement(wrong)
    assert not fb.correct and fb.message == hint("19.1", key), str(fb)


def test_19_1_slips_placeholder_and_rounding():
    right = measurement_c(X1, T1, S1)
    deg = right.copy()
    deg[2] = np.degrees(deg[2])
    assert "degrees" in ex.check_station_measurement(deg).message
    assert "only the range rho is off" in ex.check_station_measurement(right * [1000, 1, 1]).message  # m for km
    assert "1000 times" in ex.check_station_measurement(right * 1000).message
    assert ex.check_station_measurement(np.round(right, 2)).message == ROUNDED_HINT
    fb = ex.check_station_measurement(...)
    assert not fb.correct and not fb.answered


# ---------------------------------------------------------------------------
# 19.2
X2, T2 = np.array(_shared.VIS_X), _shared.VIS_T


def visible_c(x, t, *, rule="horizon", rotate=True):
    r = complex(x[0], x[2])
    out = []
    for i in range(1, 13):
        pos, _ = station_c(t, i, rotate=rotate)
        lhs = ((r - pos) * pos.conjugate()).real if rule == "horizon" else (r * pos.conjugate()).real
        if lhs > 0:
            out.append(i)
    return np.array(out)


def test_19_2_accepts_the_ids_of_the_horizon_rule_and_they_are_two():
    right = visible_c(X2, T2)
    assert right.tolist() == [11, 12]       # the exercise is built so that station 12's theta is past 2 pi
    assert ex.check_visible_stations(right).correct
    assert ex.check_visible_stations(right.tolist()).correct


@pytest.mark.parametrize("key", ["zero_based", "position_rule", "no_rotation", "unwrapped", "order", "whole"])
def test_19_2_names_each_mistake(key):
    right = visible_c(X2, T2)
    wrong = {"zero_based": right - 1, "position_rule": visible_c(X2, T2, rule="position"),
             "no_rotation": visible_c(X2, T2, rotate=False), "order": right[::-1], "whole": right + 0.5}
    if key == "unwrapped":     # |phi - theta| < pi/2 without wrapping: no station at all here
        th = WE * T2 + np.arange(12) * math.pi / 6
        phi = np.array([np.angle(complex(X2[0], X2[2]) - station_c(T2, i)[0]) for i in range(1, 13)])
        value = np.flatnonzero(np.abs(phi - th) < math.pi / 2) + 1
        assert value.size == 0
    else:
        value = wrong[key]
    fb = ex.check_visible_stations(value)
    assert not fb.correct and fb.message == hint("19.2", key), (key, str(fb))


# ---------------------------------------------------------------------------
# 19.3
def test_19_3_accepts_the_period_of_the_integrated_orbit():
    n = math.sqrt(MU / R0**3)
    x0 = np.array([R0, 0.0, 0.0, R0 * n]) + np.array(_shared.PERIOD_DX0)

    def f(_t, x):
        r3 = math.hypot(x[0], x[2]) ** 3
        return [x[1], -MU * x[0] / r3, x[3], -MU * x[2] / r3]

    # the period is when the orbit's angle completes one turn (an event of solve_ivp)
    def full_turn(_t, x):
        return x[2] if _t > 100 else 1.0
    full_turn.direction = 1
    sol = solve_ivp(f, (0, 7000), x0, method="DOP853", rtol=1e-13, atol=1e-10, events=full_turn)
    T = sol.t_events[0][0]
    fb = ex.check_perturbed_period(T)
    assert fb.correct, (T, str(fb))


@pytest.mark.parametrize("key", ["nominal", "no_half", "circular_speed", "minutes"])
def test_19_3_names_each_mistake(key):
    n = math.sqrt(MU / R0**3)
    x0 = np.array([R0, 0.0, 0.0, R0 * n]) + np.array(_shared.PERIOD_DX0)
    v2, r = x0[1] ** 2 + x0[3] ** 2, R0
    energy = v2 / 2 - MU / r
    period = lambda a: 2 * math.pi * math.sqrt(a**3 / MU)   # noqa: E731
    value = {"nominal": 2 * math.pi / n, "no_half": period(-MU / (2 * (v2 - MU / r))),
             "circular_speed": period(MU / v2), "minutes": period(-MU / (2 * energy)) / 60}[key]
    fb = ex.check_perturbed_period(value)
    assert not fb.correct and fb.message == hint("19.3", key), str(fb)


def test_every_listed_hint_of_19_is_tested():
    tested = {"19.1": {"zero_based", "no_rotation", "fixed_station", "reversed", "atan2_order"},
              "19.2": {"zero_based", "position_rule", "no_rotation", "unwrapped", "order", "whole"},
              "19.3": {"nominal", "no_half", "circular_speed", "minutes", "radius_a"}}
    for exercise, keys in tested.items():
        assert set(ex.EXERCISES[exercise].hints) == keys


def test_the_notebook_states_the_exercises_numbers():
    from pathlib import Path
    text = (Path(__file__).resolve().parents[1] / "notebooks" / "source" / "19_orbit_nonlinear_model.md").read_text()
    assert "$x = [-1200,\\ -7.5,\\ 6560,\\ -1.4]^T$" in text and "At $t = 3000$ s" in text and "station 4" in text
    assert _shared.MEAS_X == (-1200.0, -7.5, 6560.0, -1.4) and _shared.MEAS_T == 3000.0 and _shared.MEAS_STATION == 4
    assert "$x = [6640,\\ 1.0,\\ -880,\\ 7.7]^T$" in text and "At $t = 9000$ s" in text
    assert _shared.VIS_X == (6640.0, 1.0, -880.0, 7.7) and _shared.VIS_T == 9000.0
    assert "$\\delta x_0 = [0,\\ 0.075,\\ 0,\\ -0.021]^T$" in text and _shared.PERIOD_DX0 == (0.0, 0.075, 0.0, -0.021)


# ---------------------------------------------------------------------------
# 20.1
XA = np.array(_shared.A_X)


def f_ct(x):
    r3 = math.hypot(x[0], x[2]) ** 3
    return np.array([x[1], -MU * x[0] / r3, x[3], -MU * x[2] / r3])


def complex_step_jacobian(fun, x):
    """Jacobian by complex steps (exact to rounding): Im f(x + i h e_j) / h."""
    h = 1e-30
    cols = []
    for j in range(x.size):
        z = x.astype(complex)
        z[j] += 1j * h
        cols.append(np.imag(fun(z)) / h)
    return np.stack(cols, axis=-1)


def f_complex(x):
    r3 = np.sqrt(x[0] ** 2 + x[2] ** 2) ** 3
    return np.array([x[1], -MU * x[0] / r3, x[3], -MU * x[2] / r3])


def test_20_1_accepts_the_complex_step_jacobian():
    A = complex_step_jacobian(f_complex, XA)
    assert np.allclose(A[[0, 2]], [[0, 1, 0, 0], [0, 0, 0, 1]])
    fb = ex.check_gravity_jacobian(A)
    assert fb.correct, str(fb)


@pytest.mark.parametrize("key", ["sign", "constant_r", "no_kinematics", "swapped_xy"])
def test_20_1_names_each_mistake(key):
    A = complex_step_jacobian(f_complex, XA)
    X, Y = XA[0], XA[2]
    r = math.hypot(X, Y)
    wrong = A.copy()
    if key == "sign":
        wrong[[1, 3]] = -A[[1, 3]]
    elif key == "constant_r":          # d(-mu X / r^3)/dX with r held fixed
        wrong[1, 0], wrong[1, 2], wrong[3, 0], wrong[3, 2] = -MU / r**3, 0.0, 0.0, -MU / r**3
    elif key == "no_kinematics":
        wrong[0, 1] = wrong[2, 3] = 0.0
    else:
        wrong[1, 0], wrong[3, 2] = A[3, 2], A[1, 0]
    fb = ex.check_gravity_jacobian(wrong)
    assert not fb.correct and fb.message == hint("20.1", key), str(fb)


def test_20_1_transposed_and_rounded():
    A = complex_step_jacobian(f_complex, XA)
    assert "transposed" in ex.check_gravity_jacobian(A.T).message
    assert ex.check_gravity_jacobian(np.round(A, 8)).message == ROUNDED_HINT


# ---------------------------------------------------------------------------
# 20.2
XR, TR, SR = np.array(_shared.ROW_X), _shared.ROW_T, _shared.ROW_STATION


def rhodot_complex(x, t=TR, i=SR, **kw):
    pos, vel = station_c(t, i, **kw)
    dX, dY = x[0] - pos.real, x[2] - pos.imag
    dVX, dVY = x[1] - vel.real, x[3] - vel.imag
    return np.array([(dX * dVX + dY * dVY) / np.sqrt(dX**2 + dY**2)])


def test_20_2_accepts_the_complex_step_row():
    row = complex_step_jacobian(rhodot_complex, XR)[0]
    fb = ex.check_range_rate_row(row)
    assert fb.correct, str(fb)


@pytest.mark.parametrize("key", ["rho_constant", "station_fixed", "range_row", "velocity_only", "zero_based"])
def test_20_2_names_each_mistake(key):
    pos, vel = station_c(TR, SR)
    dX, dY = XR[0] - pos.real, XR[2] - pos.imag
    dVX, dVY = XR[1] - vel.real, XR[3] - vel.imag
    rho = math.hypot(dX, dY)
    if key == "rho_constant":
        wrong = np.array([dVX, dX, dVY, dY]) / rho
    elif key == "station_fixed":
        def fixed(x):
            ddX, ddY = x[0] - pos.real, x[2] - pos.imag
            return np.array([(ddX * x[1] + ddY * x[3]) / np.sqrt(ddX**2 + ddY**2)])
        wrong = complex_step_jacobian(fixed, XR)[0]
    elif key == "range_row":
        wrong = np.array([dX / rho, 0.0, dY / rho, 0.0])
    elif key == "velocity_only":
        wrong = np.array([0.0, dX / rho, 0.0, dY / rho])
    else:
        wrong = complex_step_jacobian(lambda x: rhodot_complex(x, offset=0), XR)[0]
    fb = ex.check_range_rate_row(wrong)
    assert not fb.correct and fb.message == hint("20.2", key), str(fb)


# ---------------------------------------------------------------------------
# 20.3
def A_nominal():
    n = math.sqrt(MU / R0**3)
    return complex_step_jacobian(f_complex, np.array([R0, 0.0, 0.0, R0 * n]))


def taylor_expm(M, terms=80):
    """exp(M) by its series, scaled and squared (another route than scipy's Pade)."""
    s = 10
    B = M / 2**s
    out, term = np.eye(len(M)), np.eye(len(M))
    for k in range(1, terms):
        term = term @ B / k
        out = out + term
    for _ in range(s):
        out = out @ out
    return out


def test_20_3_accepts_the_series_exponential():
    F = taylor_expm(_shared.EXPM_DT * A_nominal())
    fb = ex.check_expm_F(F)
    assert fb.correct, str(fb)


@pytest.mark.parametrize("key", ["euler", "elementwise", "no_dt", "dt_outside"])
def test_20_3_names_each_mistake(key):
    A, dt = A_nominal(), _shared.EXPM_DT
    with np.errstate(over="ignore"):
        wrong = {"euler": np.eye(4) + dt * A, "elementwise": np.exp(dt * A), "no_dt": taylor_expm(A),
                 "dt_outside": dt * taylor_expm(A)}[key]
    fb = ex.check_expm_F(wrong)
    assert not fb.correct and fb.message == hint("20.3", key), str(fb)


def test_every_listed_hint_of_20_is_tested_and_placeholders_are_unanswered():
    tested = {"20.1": {"sign", "constant_r", "no_kinematics", "swapped_xy"},
              "20.2": {"rho_constant", "station_fixed", "range_row", "velocity_only", "zero_based"},
              "20.3": {"euler", "elementwise", "no_dt", "dt_outside"}}
    for exercise, keys in tested.items():
        assert set(ex.EXERCISES[exercise].hints) == keys
    for check in (ex.check_gravity_jacobian, ex.check_range_rate_row, ex.check_expm_F, ex.check_visible_stations,
                  ex.check_perturbed_period):
        fb = check(...)
        assert not fb.correct and not fb.answered


def test_the_notebook_20_states_the_exercises_numbers():
    from pathlib import Path
    text = (Path(__file__).resolve().parents[1] / "notebooks" / "source" / "20_orbit_linearization.md").read_text()
    assert "$x = [5000,\\ -4.0,\\ 4400,\\ 5.0]^T$" in text and _shared.A_X == (5000.0, -4.0, 4400.0, 5.0)
    assert "station 4 at $t = 3000$ s" in text and "$x = [-1200,\\ -7.5,\\ 6560,\\ -1.4]^T$" in text
    assert (_shared.ROW_X, _shared.ROW_T, _shared.ROW_STATION) == ((-1200.0, -7.5, 6560.0, -1.4), 3000.0, 4)
    assert "$\\Delta T$ = 600 s" in text and _shared.EXPM_DT == 600.0


@pytest.mark.parametrize("check", [ex.check_station_measurement, ex.check_range_rate_row])
@pytest.mark.parametrize("setting, name", [({"station": 13}, "station"), ({"station": 0}, "station"),
                                           ({"t": float("nan")}, "t"), ({"x": [1.0, 2.0]}, "x")])
def test_bad_settings_raise_valueerror_naming_them(check, setting, name):
    with pytest.raises(ValueError, match=f"^{name} "):
        check(np.zeros(3), **setting)


# ---------------------------------------------------------------------------
# 22.1: the weights from Merwe's formulas (not filterpy's class), the mean as the angle of a sum of unit complex numbers
def merwe_formula_weights(n=4, alpha=1.0, beta=2.0, kappa=0.0):
    lam = alpha**2 * (n + kappa) - n
    wm = np.array([lam / (n + lam)] + [1 / (2 * (n + lam))] * (2 * n))
    wc = wm.copy()
    wc[0] += 1 - alpha**2 + beta
    return wm, wc


def phasor_mean(phi, w):
    return float(np.angle(np.sum(w * np.exp(1j * np.asarray(phi)))))


PHI_22_1 = np.array(_shared.UKF_PHI)
WM_22_1, WC_22_1 = merwe_formula_weights()
RIGHT_22_1 = phasor_mean(PHI_22_1, WM_22_1)


def test_22_1_accepts_the_phasor_mean_with_merwes_mean_weights():
    assert WM_22_1[0] == 0 and WC_22_1[0] == 2          # the centre point: no weight in the mean, 2 in the covariance
    fb = ex.check_ukf_phi_mean(RIGHT_22_1)
    assert fb.correct, str(fb)
    assert ex.check_ukf_phi_mean(np.float64(RIGHT_22_1)).correct and ex.check_ukf_phi_mean(np.array(RIGHT_22_1)).correct


def test_22_1_the_phi_values_straddle_pi_and_the_mean_is_near_minus_pi():
    assert PHI_22_1.min() < -2.5 and PHI_22_1.max() > 2.5 and np.all(np.abs(PHI_22_1) > 2.5)
    assert -np.pi < RIGHT_22_1 < -3.0                   # so that [0, 2 pi) differs from (-pi, pi]


def wrapped(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


@pytest.mark.parametrize("key, wrong", [
    ("plain", float(WM_22_1 @ PHI_22_1)),                                      # weighted arithmetic mean
    ("plain", float(np.sum(PHI_22_1) / PHI_22_1.size)),                        # plain arithmetic mean
    ("unweighted", phasor_mean(PHI_22_1, np.ones(9))),                         # every point alike
    ("wc", phasor_mean(PHI_22_1, WC_22_1)),                                    # the covariance weights
    ("wrap_2pi", RIGHT_22_1 + 2 * np.pi),                                      # in [0, 2 pi)
    ("shifted", float(WM_22_1 @ np.where(PHI_22_1 < 0, PHI_22_1 + 2 * np.pi, PHI_22_1))),
    ("shifted", float(wrapped(WM_22_1 @ np.unwrap(PHI_22_1)))),                # np.unwrap, then wrapped back
    ("arctan", float(np.arctan(np.sum(WM_22_1 * np.sin(PHI_22_1)) / np.sum(WM_22_1 * np.cos(PHI_22_1))))),
])
def test_22_1_names_each_mistake(key, wrong):
    fb = ex.check_ukf_phi_mean(wrong)
    assert not fb.correct and fb.answered and fb.message == hint("22.1", key), str(fb)


def test_22_1_slips_get_their_hint_and_no_hint_tells_the_answer():
    assert "in degrees" in ex.check_ukf_phi_mean(np.degrees(RIGHT_22_1)).message
    assert "1000 times the right one" in ex.check_ukf_phi_mean(1000 * RIGHT_22_1).message
    assert ex.check_ukf_phi_mean(round(RIGHT_22_1, 4)).message == ROUNDED_HINT
    for text in (*ex.EXERCISES["22.1"].hints.values(), ex.EXERCISES["22.1"].praise):
        assert f"{RIGHT_22_1:.2f}" not in text and f"{RIGHT_22_1:.1f}" not in text and "3.07" not in text


def test_22_1_minus_pi_counts_as_pi():
    phi = np.array([np.pi] + [np.pi - 0.1, -np.pi + 0.1] * 4)   # symmetric about pi: the mean is pi (or -pi)
    assert ex.check_ukf_phi_mean(np.pi, phi=phi).correct and ex.check_ukf_phi_mean(-np.pi, phi=phi).correct


def test_22_1_the_grade_is_the_fresh_process_recheck_not_the_kernels_check(monkeypatch):
    """A student's kernel where the check (or Feedback) is patched to praise anything shows ✔, but the grader's
    re-check of the recorded answer runs the genuine check in a fresh process: ✘ for a wrong answer."""
    import json
    import subprocess
    import sys

    import kfcal_helpers.orbit.exercises as package
    from kfcal_helpers.exercises import Feedback
    from kfcal_helpers.exercises.grading import make_record

    module, check = "kfcal_helpers.orbit.exercises", "check_ukf_phi_mean"
    plain = float(WM_22_1 @ PHI_22_1)
    monkeypatch.setattr(package, check, lambda answer, **kw: Feedback("22.1", True, "patched"))
    line, wrong = make_record("22.1", module, check, plain)
    assert line.startswith("✔")                          # the patched kernel praises it
    _, right = make_record("22.1", module, check, RIGHT_22_1)
    items = [{"exercise": "22.1", "module": module, "check": check, "record": r} for r in (right, wrong)]
    done = subprocess.run([sys.executable, "-P", "-m", "kfcal_helpers.exercises.grading"],
                          input=json.dumps(items).encode(), capture_output=True, check=True)
    verdicts = json.loads(done.stdout)
    assert [v["correct"] for v in verdicts] == [True, False]
    assert verdicts[1]["line"] == "✘ 22.1 not yet: " + hint("22.1", "plain")


@pytest.mark.parametrize("setting, name", [({"phi": np.zeros(8)}, "phi"), ({"phi": [np.nan] * 9}, "phi"),
                                           ({"phi": [0.0, np.pi] * 4 + [0.0]}, "phi"), ({"alpha": 0.0}, "alpha"),
                                           ({"beta": float("inf")}, "beta"), ({"kappa": -4.0}, "alpha and kappa")])
def test_22_1_bad_settings_raise_valueerror_naming_them(setting, name):
    with pytest.raises(ValueError, match=f"^{name} "):
        ex.check_ukf_phi_mean(0.0, **setting)


# ---------------------------------------------------------------------------
# 22.2: the correction in information form, x+ - x- = (P-^-1 + H^T R^-1 H)^-1 H^T R^-1 nu, with H by complex steps
# of the measurement written with analytic functions (phi as atan(dY/dX): the same derivative as atan2)
def stacked_c(x, t, stations):
    return np.concatenate([measurement_c(x, t, i) for i in stations])


def analytic_measurement(x, t, i):
    pos, vel = station_c(t, i)
    dX, dY = x[0] - pos.real, x[2] - pos.imag
    dXd, dYd = x[1] - vel.real, x[3] - vel.imag
    rho = np.sqrt(dX * dX + dY * dY)
    return np.array([rho, (dX * dXd + dY * dYd) / rho, np.arctan(dY / dX)])


def stacked_jacobian_cs(x, t, stations, h=1e-30):
    cols = [np.concatenate([analytic_measurement(x + 1j * h * e, t, i) for i in stations]).imag / h for e in np.eye(4)]
    return np.stack(cols, axis=1)


def information_correction(stations=None, *, wrap=True, t_offset=0):
    x, t = np.array(_shared.UPD_X), _shared.UPD_T
    stations = list(_shared.UPD_STATIONS) if stations is None else stations
    rows = [_shared.UPD_STATIONS.index(s) for s in stations]
    z = np.array(_shared.UPD_Y)[rows].ravel()
    ids = [(s - 1 + t_offset) % 12 + 1 for s in stations]
    H = stacked_jacobian_cs(x, t, ids)
    nu = z - stacked_c(x, t, ids)
    if wrap:
        nu[2::3] = (nu[2::3] + np.pi) % (2 * np.pi) - np.pi
    Rinv = np.kron(np.eye(len(ids)), np.diag(1 / np.array([0.01, 1.0, 0.01])))
    info = np.diag(1 / np.array(_shared.UPD_P)) + H.T @ Rinv @ H
    return np.linalg.solve(info, H.T @ Rinv @ nu)


def test_22_2_accepts_the_information_form_correction():
    fb = ex.check_stacked_update(information_correction())
    assert fb.correct, str(fb)


@pytest.mark.parametrize("key", ["no_wrap", "first_only", "second_only", "gain_R", "zero_based"])
def test_22_2_names_each_mistake(key):
    if key == "gain_R":
        x, t = np.array(_shared.UPD_X), _shared.UPD_T
        ids = list(_shared.UPD_STATIONS)
        H = stacked_jacobian_cs(x, t, ids)
        nu = np.array(_shared.UPD_Y).ravel() - stacked_c(x, t, ids)
        nu[2::3] = (nu[2::3] + np.pi) % (2 * np.pi) - np.pi
        wrong = np.diag(_shared.UPD_P) @ H.T @ np.kron(np.eye(2), np.diag([100.0, 1.0, 100.0])) @ nu
    else:
        wrong = {"no_wrap": lambda: information_correction(wrap=False),
                 "first_only": lambda: information_correction([_shared.UPD_STATIONS[0]]),
                 "second_only": lambda: information_correction([_shared.UPD_STATIONS[1]]),
                 "zero_based": lambda: information_correction(t_offset=1)}[key]()
    fb = ex.check_stacked_update(wrong)
    assert not fb.correct and fb.message == hint("22.2", key), str(fb)


def test_22_2_the_phi_residual_of_station_4_needs_the_wrap():
    x, t = np.array(_shared.UPD_X), _shared.UPD_T
    raw = _shared.UPD_Y[0][2] - measurement_c(x, t, _shared.UPD_STATIONS[0])[2]
    assert abs(raw + 2 * np.pi) < 0.01


def test_every_listed_hint_of_22_is_tested_and_placeholders_are_unanswered():
    tested = {"22.1": {"plain", "unweighted", "wc", "wrap_2pi", "shifted", "arctan"},
              "22.2": {"no_wrap", "first_only", "second_only", "gain_R", "zero_based"}}
    for exercise, keys in tested.items():
        assert set(ex.EXERCISES[exercise].hints) == keys
    for check in (ex.check_ukf_phi_mean, ex.check_stacked_update):
        fb = check(...)
        assert not fb.correct and not fb.answered


def test_the_notebook_22_states_the_exercises_numbers():
    from pathlib import Path
    text = (Path(__file__).resolve().parents[1] / "notebooks" / "source" / "22_orbit_ekf_ukf.md").read_text()
    phi = ",\\ ".join(f"{v:.4f}" for v in _shared.UKF_PHI)
    assert f"$\\phi = [{phi}]$" in text.replace("\n", " ")
    assert "MerweScaledSigmaPoints(4, alpha=1.0, beta=2.0, kappa=0.0)" in text
    from kfcal_helpers.orbit import FilterSetup
    setup = FilterSetup("ukf")
    assert (_shared.UKF_ALPHA, _shared.UKF_BETA, _shared.UKF_KAPPA) == (setup.alpha, setup.beta, setup.kappa) == (1.0, 2.0, 0.0)
    assert "At $t$ = 576 s stations 4 and 5" in text and (_shared.UPD_T, _shared.UPD_STATIONS) == (576.0, (4, 5))
    assert "$\\hat x^- = [-1991.4,\\ -7.3743,\\ 6374.2,\\ -2.3039]^T$" in text
    assert "\\operatorname{diag}(0.04,\\ 10^{-6},\\ 0.04,\\ 10^{-6})" in text and _shared.UPD_P == (0.04, 1e-6, 0.04, 1e-6)
    assert "$y_4 = [1724.40,\\ 6.60,\\ -3.1410]^T$, $y_5 = [1735.45,\\ -7.35,\\ 0.6070]^T$" in text
    assert _shared.UPD_X == (-1991.4, -7.3743, 6374.2, -2.3039)
    assert _shared.UPD_Y == ((1724.40, 6.60, -3.1410), (1735.45, -7.35, 0.6070))


@pytest.mark.parametrize("setting, name", [({"P_diag": [1.0, 1.0, 1.0, -1.0]}, "P_diag"), ({"stations": (13, 4)}, "stations"),
                                           ({"y": np.zeros((3, 3))}, "y"), ({"t": float("nan")}, "t"),
                                           ({"x": [1.0, 2.0]}, "x")])
def test_22_2_bad_settings_raise_valueerror_naming_them(setting, name):
    with pytest.raises(ValueError, match=f"^{name} "):
        ex.check_stacked_update(np.zeros(4), **setting)
