"""Orbit determination from ground-station tracking: a satellite in a planar orbit about a point-mass
Earth, tracked by 12 stations on the equator of the rotating Earth.

Four states ``[X, Xdot, Y, Ydot]`` (km, km/s), acceleration noise on the two accelerations, per visible
station a measurement ``[rho, rhodot, phi]`` (km, km/s, rad): the measurement dimension changes from step
to step (0, 3, 6, ...).  Sampled every 10 s for 14000 s.

Modules:

* :mod:`.params` -- :class:`OrbitParams` (constants, noise covariances, the initial perturbation);
* :mod:`.model` -- dynamics, the closed-form circular nominal, station states, the visibility rule, the
  measurements and their Jacobians A and C_i, the DT model (F, Omega) and the filters' RK4 one-step map;
* :mod:`.simulation` -- the truth model (``solve_ivp``), noisy measurements of the visible stations and
  logs in the course's per-step column format (:class:`OrbitLog`);
* :mod:`.filters` -- LKF, EKF, UKF on filterpy's classes, one run, with the measurement size of each step
  (:func:`run_filter`, :class:`FilterSetup`, :class:`FilterResult`);
* :mod:`.batch` -- the same three filters on N realizations at once (the stations of each run masked
  into common slots), proven equal to the per-run filters: :func:`run_batch`, :class:`BatchResult`;
* :mod:`.montecarlo` -- truth-model tests through the shared Monte Carlo core (:class:`OrbitExperiment`,
  :func:`truth_model_test`), NEES and NIS checked per step with the dof present.
* :mod:`.exercises` -- the exercise checks of the orbit notebooks (``from kfcal_helpers.orbit.exercises
  import check_...``).

Not yet registered in :mod:`kfcal_helpers.problems` (no command line, plots or mistakes yet).
"""

from .batch import BatchResult, run_batch
from .filters import FILTERS, FilterResult, FilterSetup, OrbitEKF, run, run_ekf, run_filter, run_lkf, run_ukf
from .model import (
    PHI,
    TRANSITIONS,
    discretize,
    dynamics,
    jacobian_A,
    jacobian_C,
    measure,
    nominal_state,
    nominal_trajectory,
    propagate,
    station_angles,
    station_states,
    visible,
    wrap_phi,
)
from .montecarlo import MonteCarloResult, OrbitExperiment, truth_model_test
from .params import MAX_STATIONS, N_NOISE, N_STATES, N_STATION_MEAS, OrbitParams
from .simulation import (
    DEFAULT_LOG_SEED,
    OrbitLog,
    Simulation,
    from_columns,
    integrate,
    simulate,
    simulate_measurements,
    simulate_truth,
    to_columns,
)

__all__ = [
    "BatchResult", "run_batch", "MonteCarloResult", "OrbitExperiment", "truth_model_test",
    "FILTERS", "FilterResult", "FilterSetup", "OrbitEKF", "run", "run_ekf", "run_filter", "run_lkf", "run_ukf",
    "PHI", "TRANSITIONS", "discretize", "dynamics", "jacobian_A", "jacobian_C", "measure", "nominal_state",
    "nominal_trajectory", "propagate", "station_angles", "station_states", "visible", "wrap_phi",
    "MAX_STATIONS", "N_NOISE", "N_STATES", "N_STATION_MEAS", "OrbitParams",
    "DEFAULT_LOG_SEED", "OrbitLog", "Simulation", "from_columns", "integrate", "simulate", "simulate_measurements",
    "simulate_truth", "to_columns",
]
