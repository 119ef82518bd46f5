"""Exercise checks of notebook 14 (its calibration exercises): 14.1-14.2."""

from __future__ import annotations


from dataclasses import replace
from functools import lru_cache


from ...exercises._core import (Exercise, Feedback, distinct_mistakes,
                               unanswered)
from ...validation import (require_instance, require_int)
from ..error_model import error_state_model
from ..montecarlo import CHECK_NAMES, run_monte_carlo
from ..params import CalibrationParams



@lru_cache(maxsize=2)
def _failing_checks_gps_sigma(params: CalibrationParams) -> frozenset:
    """The checks that fail for a filter assuming a GPS position variance of 0.25 m^2
    (1000 realizations, seed 1)."""
    model = error_state_model(replace(params, gps_pos_var=0.25))
    mc = run_monte_carlo(params, 1000, seed=1, model=model, progress=False)
    return frozenset(name for name, c in mc.checks().items() if not c.passed)


_FAILING_CHECKS_GPS_SIGMA = Exercise(
    "14.1",
    praise="these are exactly the checks that leave their simultaneous band",
    hint="compare with the failing checks of your own run: 1000 realizations, seed 1, and only V[0,0] changed "
         "(dataclasses.replace(params, gps_pos_var=0.25))",
    hints={
        "type": "give a set of check names, e.g. {'nees', 'nis'}",
        "extra": "at least one check in your set passes in that run: for each, ask what a filter that believes its "
                 "GPS is twice as accurate as it is gets wrong (its gains, its P, its S) and whether that check "
                 "compares it",
        "missing": "some failing checks are missing: list every check whose verdict is FAIL in your run, not only "
                   "the ones you expected",
        "mixed": "your set holds a check that passes and misses one that fails: compare it with the verdict column "
                 "of your own run",
    },
)


def check_failing_checks_gps_sigma(answer, *, params: CalibrationParams | None = None) -> Feedback:
    """Exercise 14.1: the set of check names (from CHECK_NAMES) that fail when the filter assumes a
    GPS position σ of 0.5 m (V[0,0] = 0.25 m^2) while the truth has 1 m; 1000 realizations, seed 1."""
    ex = _FAILING_CHECKS_GPS_SIGMA
    params = require_instance("params", params, CalibrationParams, allow_none=True) or CalibrationParams()
    if unanswered(answer):
        return ex.unanswered("replace ... with the set of failing check names")
    if isinstance(answer, (str, bytes)) or not isinstance(answer, (set, frozenset, list, tuple)) \
            or not all(isinstance(a, str) for a in answer):
        return ex.mistake("type")
    given = set(answer)
    unknown = given - set(CHECK_NAMES)
    if unknown:
        return ex.feedback(False, f"unknown check names {sorted(unknown)}; the names are {', '.join(CHECK_NAMES)}")
    right = _failing_checks_gps_sigma(params)
    if given == right:
        return ex.feedback(True)
    # never name which check is wrong (that would solve the exercise by elimination)
    extra, missing = given - right, right - given
    return ex.mistake("mixed" if extra and missing else "extra" if extra else "missing")


_PHI02_COUPLING_CHANGE = Exercise(
    "14.2",
    praise="the flipped sign changes the coupling by k dt^2 over k steps",
    hint="multiply out Phi'^k for k = 2 and k = 3 and look at how the [0,2] entry differs",
    hints={
        "sign": "check the sign: which of the two matrices has the larger [0,2] entry?",
        "one_step": "that is the change over one IMU step; the interval asked for has many",
        "coupling": "that is the coupling itself over the interval, not its change",
        "squared": "the per-step change adds up once per step (it enters Phi^k linearly in k)",
        "fix_interval": "that is the change over one fix interval of the default 5 Hz GPS; the exercise asks for "
                        "a longer interval (work out how the change grows with k)",
        "half": "off by a factor of 2: recompute the one-step difference Phi'[0,2] - Phi[0,2] from "
                "Phi'[0,2] = +dt^2/2 and Phi[0,2] = -dt^2/2",
    },
)


def check_phi02_coupling_change(answer, *, steps: int = 200, params: CalibrationParams | None = None) -> Feedback:
    """Exercise 14.2: Phi'^k[0,2] - Phi^k[0,2] in s^2 for k = ``steps`` IMU steps (default 200: one
    second, the fix interval of a 1 Hz GPS), where Phi' has Phi[0,2] = +dt^2/2 (the flipped sign)."""
    ex = _PHI02_COUPLING_CHANGE
    k = require_int("steps", steps, minimum=1)
    p = require_instance("params", params, CalibrationParams, allow_none=True) or CalibrationParams()
    dt = p.dt
    right = k * dt**2
    wrong = distinct_mistakes([(-right, "sign"), (dt**2, "one_step"), (-(k * dt) ** 2 / 2, "coupling"),
                               (k**2 * dt**2, "squared"), (p.steps_per_fix * dt**2, "fix_interval"),
                               (right / 2, "half")], right, 1e-6)
    return replace(ex, praise=f"the flipped sign changes the coupling by k dt^2 = {right:.0e} s^2 over k = {k} "
                              "steps").judge(answer, right, wrong, rtol=1e-6)


#: the exercise records of this lesson, in notebook order
RECORDS = (_FAILING_CHECKS_GPS_SIGMA, _PHI02_COUPLING_CHANGE)
