"""Accelerometer bias calibration with GPS.

A 1-D vehicle with ``a(t) = A sin(omega t)``; a 200 Hz IMU with bias and white
noise; 5 Hz GPS position and velocity.  A Kalman filter on the error state
``[dp, dv, b]`` predicts at 200 Hz and updates at every fix.

Modules: :mod:`.params` (the problem's parameters), :mod:`.simulation` (truth,
IMU, GPS), :mod:`.error_model` (Phi, Gamma, H, Q, V, M0), :mod:`.filters`
(filterpy wrapper and the batch path), :mod:`.montecarlo` (the Monte Carlo checks),
:mod:`.outages`, :mod:`.batch_estimate` (the batch estimate and the smoother); the lecture
material in :mod:`.plots`, :mod:`.figures` (the lecture figures), :mod:`.demos` (notebook 17),
:mod:`.mistakes` (the mistakes of notebook 14) and :mod:`.exercises` (the exercise checks);
the command line in :mod:`.cli`.

:data:`PROBLEM` is the problem's entry of :mod:`kfcal_helpers.problems`: its sub-command, lecture
figures and mistakes.  matplotlib is imported only when a figure is drawn.
"""

from .. import registry
from . import cli, figures, mistakes

from .error_model import ErrorStateModel, error_state_model, phi_power
from .filters import FilterResult, batch_filter, between_fixes, covariance_sequence, make_kalman_filter, run_filterpy
from .montecarlo import ASSIGNMENT_CHECKS, CHECK_NAMES, ENGINES, FILTERS, Check, MonteCarloResult, run_monte_carlo
from .params import CalibrationParams
from .outages import outage_mask, parse_outage
from .batch_estimate import (batch_conditioning, batch_conditioning_covariance, prior_covariances_at_fixes,
                             rts_smooth_fixes)
from .simulation import TRUTH_MODELS, Simulation, acceleration, analytic_truth, integrate_left, simulate

__all__ = [
    "CalibrationParams", "Simulation", "simulate", "acceleration", "analytic_truth", "integrate_left",
    "TRUTH_MODELS", "ErrorStateModel", "error_state_model", "phi_power", "FilterResult",
    "make_kalman_filter", "run_filterpy", "between_fixes", "covariance_sequence", "batch_filter", "Check",
    "MonteCarloResult", "run_monte_carlo", "CHECK_NAMES", "ASSIGNMENT_CHECKS", "ENGINES", "FILTERS",
    "outage_mask", "parse_outage", "batch_conditioning", "batch_conditioning_covariance", "prior_covariances_at_fixes",
    "rts_smooth_fixes", "PROBLEM",
]

#: the calibration problem as the command line, ``figures`` and the mistakes table see it
PROBLEM = registry.Problem(name="calibration", title="accelerometer bias calibration with GPS (notebooks 01-07, 15-17)",
                           add_cli=cli.add_parser, figures=figures.FIGURES, figure_data=figures.figure_data,
                           mistakes=mistakes.MISTAKES, mistake_row=mistakes.mistake_row)
