"""Exercise checks of notebook 07 (model mismatch): 07.1-07.3."""

from __future__ import annotations


from dataclasses import replace
from functools import lru_cache

import numpy as np

from ...exercises._core import (Exercise, Feedback, as_array, unanswered)
from ...validation import (require_int, require_positive)
from ..error_model import error_state_model
from ..montecarlo import CHECK_NAMES, run_monte_carlo
from ..params import CalibrationParams
from ._shared import call_once, close, numeric


_APPARENT_BIAS = Exercise(
    "07.1",
    praise="the apparent bias is Δt/2 times ȧ, the rate of change of the acceleration, and grows with ω",
    hint="the apparent bias is the rate of change of the velocity mismatch (Δt/2)(a(t) - a(0))",
    hints={
        "velocity": "that is the velocity mismatch itself; the apparent bias is its rate of change",
        "hertz": "ω = 2π·0.1 rad/s here: keep the 2π",
        "no_half": "the factor is Δt/2, from the velocity mismatch (Δt/2)(a(t) - a(0))",
        "second_derivative": "differentiate (Δt/2)(a(t) - a(0)) once: one factor ω, not two",
        "omega": "use the exercise's ω = 2π·0.1 rad/s, not the notebook's 0.2 rad/s",
    },
)


def check_apparent_bias(answer, *, omega: float = 2 * np.pi * 0.1) -> Feedback:
    """Exercise 07.1: the largest magnitude (m/s²) of the apparent bias (Δt/2)·da/dt that the
    left-Riemann mismatch feeds the filter, A = 10 m/s², 200 Hz, for ``omega`` (rad/s)."""
    omega = require_positive("omega", omega)
    p = CalibrationParams(omega=omega)
    dt, A = p.dt, p.A
    right = dt / 2 * A * omega
    wrong = [("velocity", dt / 2 * A), ("hertz", dt / 2 * A * omega / (2 * np.pi)), ("no_half", dt * A * omega),
             ("second_derivative", dt / 2 * A * omega**2), ("omega", dt / 2 * A * 0.2)]
    # rtol 1e-4: differencing the sampled acceleration is off by about (ωΔt)²/6 (1.6e-6 at 0.1 Hz)
    return numeric(_APPARENT_BIAS, answer, right, wrong, rtol=1e-4)


#: test input of the trapezoid exercise (m/s², m/s, s)
_TRAPEZOID_TEST = (np.array([0.3, 1.2, -0.7, 2.5, 0.0, -1.1, 0.8, 1.9]), 100.0, 0.005)


_TRAPEZOID_VELOCITY = Exercise(
    "07.2",
    praise="the trapezoidal mechanization",
    hint="each step adds the area under a_c between two samples: the trapezoid uses both end samples",
    hints={
        "left": "that is the left Riemann sum again: the trapezoid averages a_c(t_j) and a_c(t_{j+1})",
        "right": "that is the right Riemann sum: the trapezoid averages a_c(t_j) and a_c(t_{j+1})",
        "no_half": "the trapezoid is Δt/2 (a_j + a_{j+1}): check the 1/2",
        "length": "return one velocity per sample of a_c, starting with v[0] = v0",
    },
)


def check_trapezoid_velocity(func) -> Feedback:
    """Exercise 07.2: ``func(a_c, v0, dt) -> v``, the trapezoidal velocity mechanization,
    shape (len(a_c),), v[0] = v0. Called on an 8-sample test input (m/s², m/s, s)."""
    ex = _TRAPEZOID_VELOCITY
    a, v0, dt = _TRAPEZOID_TEST
    out, fb = call_once(ex, func, "trapezoid_velocity(a_c, v0, dt)", (a.copy(), v0, dt))
    if fb is not None:
        return fb
    v = as_array(out) if not isinstance(out, (str, bytes)) else None
    if v is None:
        return ex.feedback(False, f"expected an array of velocities, got {type(out).__name__}")
    if v.size != len(a):
        return ex.mistake("length")
    steps = {"right": np.concatenate([[0.0], np.cumsum((a[:-1] + a[1:]) * dt / 2)])}
    steps["left"] = np.concatenate([[0.0], np.cumsum(a[:-1] * dt)])
    right_sum = np.concatenate([[0.0], np.cumsum(a[1:] * dt)])
    no_half = np.concatenate([[0.0], np.cumsum((a[:-1] + a[1:]) * dt)])
    if close(v, v0 + steps["right"]):
        return ex.feedback(True)
    for key, w in (("left", v0 + steps["left"]), ("right", v0 + right_sum), ("no_half", v0 + no_half)):
        if close(v, w):
            return ex.mistake(key)
    slip = ex.output_slip([v], [v0 + steps["right"]], ("v",))
    return ex.feedback(False) if slip is None else slip


@lru_cache(maxsize=4)
def _mismatch_failures(w_factor: float, n_runs: int, seed: int) -> frozenset:
    params = CalibrationParams()
    m = error_state_model(params)
    wrong_model = replace(m, W=m.W * w_factor, Q=m.Q * w_factor)
    mc = run_monte_carlo(params, n_runs=n_runs, seed=seed, model=wrong_model)
    return frozenset(name for name, c in mc.checks().items() if not c.passed)


_MISMATCH_FAILURES = Exercise(
    "07.3",
    praise="a filter that believes its IMU is quieter than it is claims too small a P",
    hint="run the Monte Carlo of the exercise and read the verdict column",
    hints={
        "extra": "at least one check in your set passes in that run: for each, ask whether a filter that believes "
                 "its IMU is quieter than it is changes what the check compares (a mean, a spread against P, the "
                 "residuals against S), and by enough for 1000 runs to see",
        "missing": "something is missing: a filter that believes its IMU is quieter than it is claims too small a "
                   "P; which checks compare the error's spread with P?",
        "mixed": "your set holds a check that passes and misses one that fails: run the Monte Carlo of the exercise "
                 "and read the verdict column",
        "unknown": "use the names of CHECK_NAMES (kfcal_helpers.calibration.CHECK_NAMES)",
        "type": "give a set of check names (strings), e.g. {'name_1', 'name_2'}",
    },
)


def check_mismatch_failures(answer, *, w_factor: float = 0.01, n_runs: int = 1000, seed: int = 77) -> Feedback:
    """Exercise 07.3: the set of check names (from ``CHECK_NAMES``) that fail when the filter
    assumes an IMU noise variance ``w_factor`` times the true W, Euler truth,
    ``run_monte_carlo(params, n_runs, seed, model=...)`` with the defaults."""
    ex = _MISMATCH_FAILURES
    w_factor = require_positive("w_factor", w_factor)
    n_runs = require_int("n_runs", n_runs, minimum=2)
    seed = require_int("seed", seed, minimum=0)
    if unanswered(answer):
        return ex.unanswered("replace ... with a set of check names")
    if isinstance(answer, (str, bytes)) or not isinstance(answer, (set, frozenset, list, tuple)):
        return ex.feedback(False, f"{ex.hints['type']}; got {type(answer).__name__}")
    if not all(isinstance(x, str) for x in answer):
        return ex.mistake("type")
    names = set(answer)
    unknown = sorted(names - set(CHECK_NAMES))
    if unknown:
        return ex.feedback(False, f"not a check name: {unknown[0]!r}; {ex.hints['unknown']}")
    expected = _mismatch_failures(w_factor, n_runs, seed)
    if names == expected:
        return ex.feedback(True)
    # never name which check is wrong (that would solve the exercise by elimination)
    extra, missing = names - expected, expected - names
    return ex.mistake("mixed" if extra and missing else "extra" if extra else "missing")


#: the exercise records of this lesson, in notebook order
RECORDS = (_APPARENT_BIAS, _TRAPEZOID_VELOCITY, _MISMATCH_FAILURES)
