"""The calibration mistakes of the course reports, each a one-line variant of the correct
filter, for the mistakes table of notebook 14.

The filter assumes a wrong error-state model; the truth is the correct one (1000 realizations,
batch path, seed 1):

* ``no_propagation`` -- estimate and P not carried through the 39 predict-only steps
  between fixes (the filter's Phi = I and Q = 0: both are held from fix to fix);
* ``phi02_sign`` -- Phi[0, 2] = +dt^2/2 instead of -dt^2/2;
* ``m0_swapped`` -- M0 with the position and velocity variances swapped;
* ``w_is_gps_velocity_var`` -- W = 0.0016 (the GPS velocity variance) instead of 0.0004;
* ``gps_interval_0_02`` -- the GPS interval taken as 0.02 s: the filter propagates over
  0.02 s between fixes (its per-step Phi and Q are those of dt / 10);
* ``v0_zero`` -- the filter's prior mean of the initial velocity 0 instead of 100 m/s: its
  prior mean of ``dv = v - v_c`` is ``0 - 100`` m/s (the IMU dead reckoning starts at 100 m/s).

The first entry of :data:`MISTAKES` is the correct filter, which passes all its checks.
:func:`mistake_row` is the problem's ``mistake_row`` of :class:`kfcal_helpers.registry.Problem`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..registry import MistakeRow
from ..validation import require_choice, require_instance, require_int
from .error_model import ErrorStateModel, error_state_model
from .montecarlo import run_monte_carlo
from .params import CalibrationParams

__all__ = ["MISTAKES", "N_RUNS", "SEED", "mistaken_model", "mistake_row"]

#: calibration mistakes, the correct filter first: name -> what the report did
MISTAKES = {
    "correct": "the correct calibration filter",
    "no_propagation": "estimate and P not carried through the 39 predict-only steps",
    "phi02_sign": "Phi[0,2] = +dt^2/2 (sign flipped)",
    "m0_swapped": "M0 with position and velocity variances swapped",
    "w_is_gps_velocity_var": "W = 0.0016, the GPS velocity variance",
    "gps_interval_0_02": "GPS interval taken as 0.02 s",
    "v0_zero": "prior mean of the initial velocity 0 instead of 100 m/s",
}

N_RUNS = 1000  #: realizations of a row's Monte Carlo by default
SEED = 1  #: seed of every row by default: the rows differ only by the mistake


def mistaken_model(params: CalibrationParams, mistake: str) -> ErrorStateModel:
    """The error-state model a calibration filter with ``mistake`` assumes (each a one-liner)."""
    require_instance("params", params, CalibrationParams)
    mistake = require_choice("mistake", mistake, tuple(MISTAKES))
    m = error_state_model(params)
    if mistake == "no_propagation":
        return replace(m, Phi=np.eye(3), Q=np.zeros((3, 3)))
    if mistake == "phi02_sign":
        return replace(m, Phi=m.Phi * np.array([[1, 1, -1], [1, 1, 1], [1, 1, 1]]))
    if mistake == "m0_swapped":
        return error_state_model(replace(params, p0_var=params.v0_var, v0_var=params.p0_var))
    if mistake == "w_is_gps_velocity_var":
        return error_state_model(replace(params, W=params.gps_vel_var))
    if mistake == "gps_interval_0_02":
        return error_state_model(replace(params, imu_rate=10 * params.imu_rate))
    if mistake == "v0_zero":
        return replace(m, x0=m.x0 + np.array([0.0, 0.0 - params.v0_mean, 0.0]))
    return m


def mistake_row(mistake: str, n_runs: int | None = None, params: CalibrationParams | None = None,
                alpha: float = 0.05, seed: int = SEED) -> MistakeRow:
    """Monte Carlo (batch path) of the calibration filter with ``mistake`` against the correct truth.

    n_runs : realizations, >= 2 (None: :data:`N_RUNS`); params : CalibrationParams (None: the defaults);
    alpha : family-wise level of the checks, in (0, 1); seed : int >= 0.
    Returns a :class:`~kfcal_helpers.registry.MistakeRow` whose ``checks`` are ``mc.checks()``.
    """
    mistake = require_choice("mistake", mistake, tuple(MISTAKES))
    n_runs = N_RUNS if n_runs is None else require_int("n_runs", n_runs, minimum=2)
    p = require_instance("params", params, CalibrationParams, allow_none=True) or CalibrationParams()
    mc = run_monte_carlo(p, n_runs, seed=seed, alpha=alpha, model=mistaken_model(p, mistake), progress=False)
    return MistakeRow("calibration", mistake, MISTAKES[mistake], mc.checks(), mc)
