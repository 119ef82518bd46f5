"""Exercise checks of notebook 10 (the linearized Kalman filter): 10.1-10.2."""

from __future__ import annotations


import math
from dataclasses import replace

import numpy as np
from scipy import stats

from ...consistency import chi2_bounds
from ..model import (
    MEAS_ANGLES,
    N_MEAS,
    N_STATES,
    jacobian_C,
    measure,
    wrap_angle,
    wrap_measurement,
)
from ...exercises._core import (Exercise, Feedback, chi2_average_bounds)
from ...validation import require_int, require_probability
from ._shared import BOUNDS_RTOL, FN_ATOL, FN_RESULT, FN_RTOL, MC_RUNS, MEAS_NAMES, call_checked, pi_for_minus_pi


def mod_2pi(d):
    """``d`` (..., 5) with its bearings wrapped to [0, 2 pi) (a common wrong answer)."""
    d = np.array(d, dtype=float)
    d[..., list(MEAS_ANGLES)] = np.mod(d[..., list(MEAS_ANGLES)], 2 * np.pi)
    return d


def normal_bounds(dim, n, alpha, z=None):
    """The normal approximation dim ± z sqrt(2 dim / n) (a common wrong answer); z defaults to the exact quantile."""
    z = stats.norm.ppf(1 - alpha / 2) if z is None else z
    return np.array([dim - z * math.sqrt(2 * dim / n), dim + z * math.sqrt(2 * dim / n)])


MC_BOUNDS = Exercise(
    "10.1",
    praise="chi-square with N n degrees of freedom, divided by N = {N}, alpha/2 in each tail",
    hints={
        "one_sided": "a two-sided test puts alpha/2 in each tail: use the alpha/2 and 1 - alpha/2 quantiles",
        "swapped_dims": "the dimensions are swapped: NEES has the state's dimension, NIS the measurement's",
        "not_divided": "the bounds are for the run average: divide the chi-square quantiles by N",
        "dof_N": "the sum over N runs of an n-dimensional statistic has N*n degrees of freedom, not N",
        "N_minus_1": "the N runs are independent with known covariance: N*n degrees of freedom, not (N-1)*n",
        "order": "give the lower bound first, then the upper one",
        "normal": "close, but that is the normal approximation: use the chi-square quantiles",
        "notebook_N": "those are the bounds for the notebook's N = 50: use this exercise's number of runs",
        "one_run": "those are the bounds of a single run: the average of N runs has N*n degrees of freedom (not n), "
                   "and its quantiles are divided by N",
        "dim6": "the NIS has the dimension of the measurement, not of the state",
    },
    components=("the NEES lower bound", "the NEES upper bound", "the NIS lower bound", "the NIS upper bound"),
)


def check_mc_bounds(answer, *, n_runs: int = MC_RUNS, alpha: float = 0.05) -> Feedback:
    """10.1: the two-sided bounds of the run-averaged NEES and NIS for ``n_runs`` Monte Carlo runs.

    answer : array (2, 2) -- [[NEES lower, NEES upper], [NIS lower, NIS upper]] (dimensionless),
        the computed values (no rounding)
    """
    N = require_int("n_runs", n_runs, minimum=2)
    alpha = require_probability("alpha", alpha)
    expected = np.array([chi2_bounds(N_STATES, N, alpha), chi2_bounds(N_MEAS, N, alpha)])

    def both(**kw):
        return np.array([chi2_average_bounds(N_STATES, N, alpha, **kw), chi2_average_bounds(N_MEAS, N, alpha, **kw)])

    pairs = [(both(one_sided=True), "one_sided"), (expected[::-1], "swapped_dims"), (both(divide_by=1), "not_divided"),
             (np.array([chi2_average_bounds(N_STATES, N, alpha, dof=N), chi2_average_bounds(N_MEAS, N, alpha, dof=N)]),
              "dof_N"),
             (np.array([chi2_average_bounds(N_STATES, N - 1, alpha), chi2_average_bounds(N_MEAS, N - 1, alpha)]),
              "N_minus_1"),
             (expected[:, ::-1], "order"),
             (np.array([chi2_average_bounds(N_STATES, N, alpha, dof=N_STATES, divide_by=1),
                        chi2_average_bounds(N_MEAS, N, alpha, dof=N_MEAS, divide_by=1)]), "one_run"),
             (np.array([normal_bounds(N_STATES, N, alpha), normal_bounds(N_MEAS, N, alpha)]), "normal")]
    if abs(alpha - 0.05) < 1e-12:  # the same with the usual 1.96, or the two-sigma rule
        for z in (1.96, 2.0):
            pairs.append((np.array([normal_bounds(N_STATES, N, alpha, z), normal_bounds(N_MEAS, N, alpha, z)]), "normal"))
    pairs.append((np.array([expected[0], chi2_bounds(N_STATES, N, alpha)]), "dim6"))  # the NIS with the state's 6
    if N != 50:
        pairs.append((np.array([chi2_bounds(N_STATES, 50, alpha), chi2_bounds(N_MEAS, 50, alpha)]), "notebook_N"))
    return replace(MC_BOUNDS, praise=MC_BOUNDS.praise.format(N=N)).judge(answer, expected, pairs, rtol=BOUNDS_RTOL,
                                                                      atol=0.0)


def _lkf_cases():
    """(y, y_nom, H, dx_prior) test inputs of 10.2: bearings near +-pi, a large range innovation."""
    cases = []
    for x_lin, dx, nu in (
        ((0.0, 0.0, 0.0, -50.0, -8.0, 0.4), (0.5, -0.3, 0.05, 1.0, 0.4, -0.02), (-0.3, 4.0, 0.1, -2.0, 5.5)),
        ((10.0, 5.0, 1.0, 40.0, -20.0, 2.5), (-0.4, 0.8, 0.1, -1.5, 0.6, -0.6), (0.2, -6.0, 2.9, 4.5, -3.5)),
        ((-3.0, 2.0, -2.0, 60.0, 30.0, 0.0), (0.0, 0.0, 0.0, 0.0, 0.0, 0.0), (0.05, 1.0, -0.1, 0.5, -0.5)),
    ):
        y_nom = measure(np.array(x_lin))
        H = jacobian_C(np.array(x_lin))
        y = wrap_measurement(y_nom + H @ np.array(dx) + np.array(nu))
        cases.append((y, y_nom, H, np.array(dx)))
    return cases


LKF_INNOVATION = Exercise(
    "10.2",
    praise="perturbation innovation with the bearings wrapped after the subtraction",
    hints={
        "no_wrap": "the bearing components jump by 2 pi across +-pi: wrap them",
        "no_nominal": "the LKF works with perturbations: the measurement perturbation is y - y_nom",
        "plus": "the predicted measurement perturbation H dx is subtracted, not added",
        "wrap_all": "wrap only the bearings (components 0 and 2): range and GPS are not angles",
        "wrap_early": "wrap the whole innovation after subtracting H dx (it can cross +-pi again)",
        "no_H": "subtract the predicted measurement perturbation H dx",
        "wrap_2pi": "the bearings are wrapped to [0, 2 pi): wrap them to (-pi, pi] instead",
    },
    components=MEAS_NAMES,
    angles=MEAS_ANGLES,
)


def check_lkf_innovation(fn) -> Feedback:
    """10.2: the student's ``fn(y, y_nom, H, dx_prior)`` -> LKF innovation (5,), called on fixed cases.

    y, y_nom : (5,) measurement and nominal measurement (rad, m, rad, m, m); H : (5, 6);
    dx_prior : (6,) predicted perturbation.  Right: ``(y - y_nom) - H dx_prior``, bearings wrapped.
    """
    cases = _lkf_cases()
    outs, fb = call_checked(LKF_INNOVATION, fn, cases, (N_MEAS,), "lkf_innovation(y, y_nom, H, dx_prior)")
    if fb is not None:
        return fb
    answer = pi_for_minus_pi(np.array([o.reshape(N_MEAS) for o in outs]), MEAS_ANGLES)

    def each(f):
        return pi_for_minus_pi(np.array([f(y, yn, H, dx) for y, yn, H, dx in cases]), MEAS_ANGLES)

    def wrap_early(y, yn, H, dx):
        return wrap_measurement(y - yn) - H @ dx

    expected = each(lambda y, yn, H, dx: wrap_measurement((y - yn) - H @ dx))
    wrong = [
        (each(lambda y, yn, H, dx: (y - yn) - H @ dx), "no_wrap"),
        (each(lambda y, yn, H, dx: wrap_measurement(y - H @ dx)), "no_nominal"),
        (each(lambda y, yn, H, dx: wrap_measurement((y - yn) + H @ dx)), "plus"),
        (each(lambda y, yn, H, dx: wrap_angle((y - yn) - H @ dx)), "wrap_all"),
        (each(wrap_early), "wrap_early"),
        (each(lambda y, yn, H, dx: wrap_measurement(y - yn)), "no_H"),
        (each(lambda y, yn, H, dx: mod_2pi((y - yn) - H @ dx)), "wrap_2pi"),
    ]
    return LKF_INNOVATION.judge(answer, expected, wrong, rtol=FN_RTOL, atol=FN_ATOL, what=FN_RESULT)


#: the exercise records of this lesson, in notebook order
RECORDS = (MC_BOUNDS, LKF_INNOVATION)
