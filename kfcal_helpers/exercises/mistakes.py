"""Exercise checks of notebook 14 (the mistakes the checks catch)."""

from __future__ import annotations

import numpy as np

from ..calibration.error_model import error_state_model
from ..calibration.montecarlo import CHECK_NAMES, run_monte_carlo
from ..calibration.params import CalibrationParams
from ._core import Feedback, judge, unanswered

__all__ = ["check_failing_checks_gps_sigma", "check_phi02_coupling_change"]


def _failing_checks_gps_sigma(params: CalibrationParams) -> set:
    """The checks that fail for a filter assuming a GPS position variance of 0.25 m^2
    (1000 realizations, seed 1)."""
    model = error_state_model(params.replace(gps_pos_var=0.25))
    mc = run_monte_carlo(params, 1000, seed=1, model=model, progress=False)
    return {name for name, c in mc.checks().items() if not c.passed}


def check_failing_checks_gps_sigma(answer, params: CalibrationParams | None = None) -> Feedback:
    """14.1: the set of check names (from CHECK_NAMES) that fail when the filter assumes a GPS
    position σ of 0.5 m (V[0,0] = 0.25 m^2) while the truth has 1 m; 1000 realizations, seed 1."""
    ex = "14.1"
    if unanswered(answer):
        return Feedback(ex, False, "replace ... with the set of failing check names", answered=False)
    if isinstance(answer, str) or not all(isinstance(a, str) for a in np.ravel(list(answer))):
        return Feedback(ex, False, "give a set of check names, e.g. {'nees', 'nis'}")
    given = set(answer)
    unknown = given - set(CHECK_NAMES)
    if unknown:
        return Feedback(ex, False, f"unknown check names {sorted(unknown)}; the names are {', '.join(CHECK_NAMES)}")
    right = _failing_checks_gps_sigma(params if params is not None else CalibrationParams())
    if given == right:
        return Feedback(ex, True, "these are exactly the checks that leave their simultaneous band")
    if "mean_error" in given:
        return Feedback(ex, False, "the mean error cannot fail here: a linear filter with zero prior means "
                                   "is unbiased whatever its gains")
    if given < right:
        return Feedback(ex, False, "some failing checks are missing: list every check whose verdict is FAIL "
                                   "in your run, not only the ones you expected")
    return Feedback(ex, False, "compare with the failing checks of your own run: 1000 realizations, seed 1, "
                               "and only V[0,0] changed (params.replace(gps_pos_var=0.25))")


def check_phi02_coupling_change(answer, params: CalibrationParams | None = None) -> Feedback:
    """14.2: Phi'^40[0,2] - Phi^40[0,2] in s^2, where Phi' has Phi[0,2] = +dt^2/2 (the
    flipped sign) and 40 is the number of IMU steps between fixes."""
    p = params if params is not None else CalibrationParams()
    n, dt = p.steps_per_fix, p.dt
    right = n * dt**2
    wrong = [(-right, "check the sign: which of the two matrices has the larger [0,2] entry?"),
             (dt**2, "that is the change over one IMU step; the fix interval has several"),
             (-(n * dt) ** 2 / 2, "that is the coupling itself over a fix interval, not its change"),
             (n**2 * dt**2, "the per-step change adds up once per step (it enters Phi^k linearly in k)")]
    return judge("14.2", answer, right, wrong, rtol=1e-6,
                 praise=f"the flipped sign changes the coupling by {right:.0e} s^2 per fix interval",
                 hint="multiply out Phi'^k for k = 2 and k = 3 and look at how the [0,2] entry differs")
