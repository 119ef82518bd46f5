"""Cooperative localization of a ground robot (UGV) and an aerial robot (UAV).

Six states (two planar poses), four constant controls, five measurements (two
bearings, a range, the UAV's GPS), sampled every 0.1 s for 100 s.

Modules:

* :mod:`.model` -- :class:`CoopParams`, dynamics, the exact closed-form one-step map,
  nominal trajectory, measurement function, angle wrapping, Jacobians A, B, C,
  F, G, H, the observability matrix over a window;
* :mod:`.simulation` -- truth model (state noise Omega w_k, w_k ~ N(0, Qtrue) a rate noise held over the step,
  Omega = dt I by default):
  :func:`simulate` returns a :class:`Simulation` (one run or many; ``.log()`` is a course-format log);
* :mod:`.filters` -- LKF, EKF, UKF on filterpy: ``run_xkf(y, setup, truth=None)`` with a
  :class:`FilterSetup` (params, Q, the :class:`MeasurementModel`, settings), :func:`run_filter` the
  short entry, a common :class:`FilterResult`;
* :mod:`.batch` -- the same three filters on N realizations at once (filterpy's equations on
  stacked arrays, proven equal to the per-run filters), for the Monte Carlo;
* :mod:`.montecarlo` -- truth-model tests (NEES/NIS with chi-square bounds) through the shared
  Monte Carlo core, and :func:`truth_model_draws` to redraw any of their runs;
* :mod:`.data` -- course log loader/writer (CSV folder or ``.mat``); :mod:`.course` -- the
  ``KFCAL_COURSE_LOG`` setting;
* :mod:`.plots` -- figures of the notebooks; :mod:`.tables` -- fixed-precision text output; :mod:`.cli` -- ``python -m kfcal_helpers coop``;
* :mod:`.figures` -- the lecture figures; :mod:`.demos` -- the live demo of notebook 18;
  :mod:`.mistakes` -- the rows of the mistakes table (notebook 14); :mod:`.exercises` -- the
  exercise checks of notebooks 08-13 and 18.

:data:`PROBLEM` is the problem's entry of :mod:`kfcal_helpers.problems`: its sub-command, lecture
figures and mistakes.  matplotlib is imported only when a figure is drawn.
"""

from .. import registry
from . import cli, figures, mistakes

from .course import COURSE_LOG_ROW_MEANS, COURSE_LOG_VARIABLE, course_log, course_log_path, is_course_log
from .data import CoopLog, load_log, write_log_csv, write_log_mat
from .filters import (
    FILTERS,
    TUNED_Q_SCALE,
    UKF_POINTS,
    CoopEKF,
    FilterResult,
    FilterSetup,
    QScaleFit,
    SigmaPoints,
    fit_q_scale,
    make_ekf,
    make_lkf,
    make_ukf,
    run,
    run_ekf,
    run_filter,
    run_lkf,
    run_ukf,
    tuned_Q,
)
from .model import (
    MEAS_ANGLES,
    MEAS_LABELS,
    N_MEAS,
    N_STATES,
    NOISE_MODELS,
    STATE,
    STATE_ANGLES,
    STATE_LABELS,
    CoopParams,
    MeasurementModel,
    StateDescriptor,
    arc,
    discretize,
    dynamics,
    jacobian_A,
    jacobian_B,
    jacobian_C,
    measure,
    measurement_mean,
    measurement_residual,
    nominal_trajectory,
    observability_matrix,
    state_add,
    state_mean,
    state_residual,
    step,
    wrap_angle,
    wrap_measurement,
    wrap_state,
)
from .batch import BatchResult, run_batch
from .montecarlo import MonteCarloResult, TruthModelExperiment, truth_model_draws, truth_model_test
from .simulation import DEFAULT_LOG_SEED, Simulation, simulate, simulate_measurements, simulate_truth
from .tables import format_matrix, format_number, format_table

__all__ = [
    "COURSE_LOG_VARIABLE", "COURSE_LOG_ROW_MEANS", "course_log", "course_log_path", "is_course_log", "CoopLog", "load_log", "write_log_csv", "write_log_mat",
    "FILTERS", "TUNED_Q_SCALE", "UKF_POINTS", "CoopEKF", "FilterResult", "FilterSetup", "QScaleFit", "SigmaPoints",
    "fit_q_scale", "make_ekf", "make_lkf", "make_ukf", "run", "run_ekf", "run_filter", "run_lkf", "run_ukf", "tuned_Q",
    "MEAS_ANGLES", "MEAS_LABELS", "N_MEAS", "N_STATES", "NOISE_MODELS", "STATE", "STATE_ANGLES", "STATE_LABELS",
    "CoopParams", "MeasurementModel", "StateDescriptor", "arc", "discretize", "dynamics", "jacobian_A", "jacobian_B", "jacobian_C", "measure", "measurement_mean",
    "measurement_residual", "nominal_trajectory", "observability_matrix", "state_add", "state_mean",
    "state_residual", "step", "wrap_angle", "wrap_measurement", "wrap_state",
    "BatchResult", "run_batch", "MonteCarloResult", "TruthModelExperiment", "truth_model_draws", "truth_model_test",
    "DEFAULT_LOG_SEED", "Simulation", "simulate", "simulate_measurements", "simulate_truth",
    "format_matrix", "format_number", "format_table", "PROBLEM",
]

#: the cooperative-localization problem as the command line, ``figures`` and the mistakes table see it
PROBLEM = registry.Problem(name="coop", title="cooperative localization of a UGV and a UAV (notebooks 08-13, 18)",
                           add_cli=cli.add_parser, figures=figures.FIGURES, figure_data=figures.figure_data,
                           mistakes=mistakes.MISTAKES, mistake_row=mistakes.mistake_row)
