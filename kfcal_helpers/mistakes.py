"""The mistakes of the course reports, each a one-line variant of the correct filter,
and the table of which Monte Carlo checks catch them (notebook 14).

Calibration (1000 realizations, batch path; the filter assumes a wrong error-state
model, the truth is the correct one):

* ``no_propagation`` -- estimate and P not carried through the 39 predict-only steps
  between fixes (the filter's Phi = I and Q = 0: both are held from fix to fix);
* ``phi02_sign`` -- Phi[0, 2] = +dt^2/2 instead of -dt^2/2;
* ``m0_swapped`` -- M0 with the position and velocity variances swapped;
* ``w_is_gps_velocity_var`` -- W = 0.0016 (the GPS velocity variance) instead of 0.0004;
* ``gps_interval_0_02`` -- the GPS interval taken as 0.02 s: the filter propagates over
  0.02 s between fixes (its per-step Phi and Q are those of dt / 10);
* ``v0_zero`` -- the filter's prior mean of the initial velocity 0 instead of 100 m/s: its
  prior mean of ``dv = v - v_c`` is ``0 - 100`` m/s (the IMU dead reckoning starts at 100 m/s).

Cooperative localization (50 truth-model runs):

* ``ekf_no_wrap`` -- EKF innovations without bearing wrapping (the course's truth model);
* ``ekf_omega_identity`` -- the noise entering as ``Omega = I`` (state noise Qtrue per step)
  instead of ``Omega = dT I``, in the truth model *and* the filter (Q = 1.5 Qtrue, the scale that
  notebook 11's truth-model test picks in that model; Qtrue itself is over-confident there, 2 Qtrue
  under-confident -- notebook 14): the truth-model test cannot see it (it tests the
  filter against the same wrong model); only the course log's NIS does;
* ``lkf_no_nominal`` -- LKF innovation ``y - H dx-`` without the nominal measurement
  subtracted (small-perturbation truth model, where the correct LKF is consistent).

Each problem's first row is the correct filter, which passes all its checks.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .calibration.error_model import ErrorStateModel, error_state_model
from .calibration.montecarlo import CHECK_NAMES, run_monte_carlo
from .calibration.params import CalibrationParams
from .consistency import Check
from .coop.model import CoopParams
from .coop.montecarlo import truth_model_test
from .validation import require_choice, require_int

__all__ = [
    "CALIBRATION_MISTAKES",
    "COOP_MISTAKES",
    "MISTAKES",
    "TABLE_CHECKS",
    "MistakeRow",
    "mistaken_model",
    "coop_case",
    "calibration_row",
    "coop_row",
    "mistake_table",
    "format_mistake_table",
]

#: calibration mistakes, the correct filter first: name -> what the report did
CALIBRATION_MISTAKES = {
    "correct": "the correct calibration filter",
    "no_propagation": "estimate and P not carried through the 39 predict-only steps",
    "phi02_sign": "Phi[0,2] = +dt^2/2 (sign flipped)",
    "m0_swapped": "M0 with position and velocity variances swapped",
    "w_is_gps_velocity_var": "W = 0.0016, the GPS velocity variance",
    "gps_interval_0_02": "GPS interval taken as 0.02 s",
    "v0_zero": "prior mean of the initial velocity 0 instead of 100 m/s",
}

#: cooperative-localization mistakes, each after its correct filter
COOP_MISTAKES = {
    "ekf_correct": "the correct EKF (Omega = dT I, Q = Qtrue, wrapped innovations)",
    "ekf_no_wrap": "EKF innovations without bearing wrapping",
    "ekf_omega_identity": "noise entering as Omega = I in truth model and filter (Q = 1.5 Qtrue)",
    "lkf_correct": "the correct LKF (small-perturbation truth model)",
    "lkf_no_nominal": "LKF innovation without the nominal measurement subtracted",
}

MISTAKES = (*CALIBRATION_MISTAKES, *COOP_MISTAKES)

#: the columns of the table: the calibration checks (the coop runs have mean_error, nees, nis)
TABLE_CHECKS = CHECK_NAMES


def mistaken_model(params: CalibrationParams, mistake: str) -> ErrorStateModel:
    """The error-state model a calibration filter with ``mistake`` assumes (each a one-liner)."""
    mistake = require_choice("mistake", mistake, tuple(CALIBRATION_MISTAKES))
    m = error_state_model(params)
    if mistake == "no_propagation":
        return replace(m, Phi=np.eye(3), Q=np.zeros((3, 3)))
    if mistake == "phi02_sign":
        return replace(m, Phi=m.Phi * np.array([[1, 1, -1], [1, 1, 1], [1, 1, 1]]))
    if mistake == "m0_swapped":
        return error_state_model(params.replace(p0_var=params.v0_var, v0_var=params.p0_var))
    if mistake == "w_is_gps_velocity_var":
        return error_state_model(params.replace(W=params.gps_vel_var))
    if mistake == "gps_interval_0_02":
        return error_state_model(params.replace(imu_rate=10 * params.imu_rate))
    if mistake == "v0_zero":
        return replace(m, x0=m.x0 + np.array([0.0, 0.0 - params.v0_mean, 0.0]))
    return m


def coop_case(mistake: str, params: CoopParams | None = None) -> tuple[str, CoopParams, dict]:
    """Filter name, truth-model parameters and filter keyword arguments of a coop row.

    The EKF rows use the course's truth model (``Omega = dT I``) and the tuned ``Q = Qtrue``, except
    ``ekf_omega_identity``, whose truth model and filter both use ``Omega = I`` with ``Q = 1.5 Qtrue``
    (the scale the truth-model test picks in that model: ``Qtrue`` is over-confident there); the LKF rows a truth that stays near the
    nominal (``Qtrue / 10^4``, P0 / 100), the regime where a correct LKF is consistent (notebook 10),
    with the filter's Q equal to it.
    """
    mistake = require_choice("mistake", mistake, tuple(COOP_MISTAKES))
    p = params if params is not None else CoopParams()
    if mistake == "ekf_omega_identity":
        return "ekf", p.replace(noise_model="identity"), {"Q": 1.5 * p.Qtrue}
    if mistake.startswith("ekf"):
        return "ekf", p, {"Q": p.Qtrue, "wrap_innovations": mistake == "ekf_correct"}
    near = p.replace(Qtrue=1e-4 * p.Qtrue, P0=0.01 * p.P0)
    return "lkf", near, {"Q": near.Qtrue, "subtract_nominal": mistake == "lkf_correct"}


@dataclass(frozen=True)
class MistakeRow:
    """One row of the table: the checks of one Monte Carlo.

    problem : "calibration" or "coop"; mistake : key of MISTAKES; description : str
    checks : dict check name -> :class:`~kfcal_helpers.consistency.Check` (the coop rows
        have only mean_error, nees and nis); result : the Monte Carlo result
    """

    problem: str
    mistake: str
    description: str
    checks: dict
    result: object

    @property
    def failed(self) -> tuple:
        """Names of the checks that fail (outside their simultaneous band)."""
        return tuple(name for name, c in self.checks.items() if not c.passed)

    @property
    def passed(self) -> bool:
        """True when every check of the row passes."""
        return not self.failed


def calibration_row(mistake: str, params: CalibrationParams | None = None, n_runs: int = 1000,
                    seed: int = 1, alpha: float = 0.05) -> MistakeRow:
    """Monte Carlo of the calibration filter with ``mistake`` against the correct truth."""
    p = params if params is not None else CalibrationParams()
    mc = run_monte_carlo(p, n_runs, seed=seed, alpha=alpha, model=mistaken_model(p, mistake), progress=False)
    return MistakeRow("calibration", mistake, CALIBRATION_MISTAKES[mistake], mc.checks(), mc)


def coop_row(mistake: str, params: CoopParams | None = None, n_runs: int = 50, seed: int = 11,
             alpha: float = 0.05) -> MistakeRow:
    """Truth-model test of the coop filter with ``mistake`` (see :func:`coop_case`)."""
    name, p, kwargs = coop_case(mistake, params)
    n_runs = require_int("n_runs", n_runs, minimum=2)
    mc = truth_model_test(name, n_runs, seed=seed, params=p, alpha=alpha, **kwargs)
    return MistakeRow("coop", mistake, COOP_MISTAKES[mistake], mc.checks(), mc)


def mistake_table(mistakes=MISTAKES, calibration_runs: int = 1000, coop_runs: int = 50,
                  calibration_params: CalibrationParams | None = None, coop_params: CoopParams | None = None,
                  alpha: float = 0.05) -> dict:
    """The table mistake x check: dict mistake -> :class:`MistakeRow`, in the order given.

    Every row uses the same seed of its problem, so the rows differ only by the mistake.
    """
    out = {}
    for mistake in mistakes:
        mistake = require_choice("mistakes", mistake, MISTAKES)
        if mistake in CALIBRATION_MISTAKES:
            out[mistake] = calibration_row(mistake, calibration_params, calibration_runs, alpha=alpha)
        else:
            out[mistake] = coop_row(mistake, coop_params, coop_runs, alpha=alpha)
    return out


def _cell(check: Check | None) -> str:
    if check is None:
        return "-"
    return f"{'pass' if check.passed else 'FAIL'} {check.worst:.3g}"


def format_mistake_table(rows: dict, checks=TABLE_CHECKS) -> str:
    """Fixed-width text table: one row per mistake, one column per check, each cell
    "pass w" or "FAIL w" with w = worst deviation / its simultaneous bound (> 1 fails), "-"
    where the check does not apply."""
    width = max(len(m) for m in rows)
    cols = [max(len(c), 12) for c in checks]
    lines = [f"{'mistake':<{width}}  " + "  ".join(f"{c:>{w}}" for c, w in zip(checks, cols))]
    lines.append("-" * len(lines[0]))
    for mistake, row in rows.items():
        lines.append(f"{mistake:<{width}}  " + "  ".join(f"{_cell(row.checks.get(c)):>{w}}" for c, w in zip(checks, cols)))
    return "\n".join(lines)
