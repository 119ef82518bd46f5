"""kfcal_helpers: the reusable pieces of the Kalman-filter teaching notebooks.

Subpackages, one per course problem:

* :mod:`kfcal_helpers.calibration` -- accelerometer bias calibration with GPS
  (linear KF on an error state, 200 Hz predict, 5 Hz update).
* :mod:`kfcal_helpers.coop` -- cooperative localization of a ground and an aerial
  robot (LKF, EKF, UKF with NEES/NIS).

Each holds everything about its problem (model, simulation, filters, Monte Carlo, plots, lecture
figures, live demos, mistakes, exercises, command-line sub-command) and defines ``PROBLEM``;
:mod:`~kfcal_helpers.problems` lists them.

Shared modules: :mod:`~kfcal_helpers.consistency` (NEES/NIS, chi-square bounds, checks),
:mod:`~kfcal_helpers.validation` (argument checks), :mod:`~kfcal_helpers.registry` (what a
problem provides), :mod:`~kfcal_helpers.slides` (writing slide files), :mod:`~kfcal_helpers.figures`
(the ``figures`` command over every problem), :mod:`~kfcal_helpers.demos`
(live-demo machinery), :mod:`~kfcal_helpers.mistakes` (the mistakes table),
:mod:`~kfcal_helpers.exercises` (the exercise-check harness), :mod:`~kfcal_helpers.style`,
:mod:`~kfcal_helpers.progress` (progress bars that stay quiet under tests),
:mod:`~kfcal_helpers.output` (strict JSON, printable text, for the command line),
:mod:`~kfcal_helpers.process` (signals, streams and matplotlib's directory of the command-line process),
:mod:`~kfcal_helpers.cli` (``python -m kfcal_helpers``).
"""

__version__ = "0.1.0"
