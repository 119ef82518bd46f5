"""kfcal_helpers: the reusable pieces of the Kalman-filter teaching notebooks.

Subpackages, one per course problem:

* :mod:`kfcal_helpers.calibration` -- accelerometer bias calibration with GPS
  (linear KF on an error state, 200 Hz predict, 5 Hz update).
* :mod:`kfcal_helpers.coop` -- cooperative localization of a ground and an aerial
  robot (LKF, EKF, UKF with NEES/NIS).

Shared modules: :mod:`~kfcal_helpers.consistency` (NEES/NIS and chi-square
bounds), :mod:`~kfcal_helpers.validation` (argument checks),
:mod:`~kfcal_helpers.progress` (progress bars that stay quiet under tests),
:mod:`~kfcal_helpers.output` (strict JSON and the files being written, for the command line).
"""

__version__ = "0.1.0"
