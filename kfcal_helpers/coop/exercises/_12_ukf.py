"""Exercise checks of notebook 12 (the unscented Kalman filter): 12.1-12.2."""

from __future__ import annotations


import math
from dataclasses import replace

import numpy as np

from ..model import (
    wrap_angle,
)
from ...exercises._core import (GENERIC_HINT, Exercise, Feedback, distinct_mistakes)
from ...validation import require_finite, require_int, require_positive
from ._shared import (FN_ATOL, FN_RESULT, FN_RTOL, MERWE, NUM_ATOL, NUM_RTOL, call_checked, finite_of_size,
                      pi_for_minus_pi)


def _merwe(n, alpha, beta, kappa, *, lam=None, wc_extra=None, wi_den=None):
    """[lambda, Wm0, Wc0, Wi]; the keywords make one mistake (inf/NaN where it divides by zero)."""
    lam = np.float64(alpha ** 2 * (n + kappa) - n if lam is None else lam)
    with np.errstate(divide="ignore", invalid="ignore"):
        wm0 = lam / (n + lam)
        wc0 = wm0 + (1 - alpha ** 2 + beta if wc_extra is None else wc_extra)
        wi = np.float64(1.0) / (2 * (n + lam) if wi_den is None else np.float64(wi_den))
    return np.array([lam, wm0, wc0, wi])


MERWE_WEIGHTS = Exercise(
    "12.1",
    praise="the mean weights sum to 1",
    hints={
        "alpha_not_squared": "lambda uses alpha squared",
        "wc0_equals_wm0": "the covariance weight of the centre point has an extra term (1 - alpha^2 + beta)",
        "wc0_alpha": "the extra term of Wc0 uses alpha squared",
        "wc0_beta_only": "the extra term of Wc0 is 1 - alpha^2 + beta, not beta alone",
        "wi_lambda": "the outer weights divide by 2 (n + lambda), not by 2 lambda",
        "n_points": "n is the state dimension (6), not the number of sigma points",
        "no_kappa": "kappa is missing from lambda",
        "no_minus_n": "lambda is missing its - n term",
        "sum": "your mean weights do not sum to 1 (Wm0 + 2n Wi): recheck lambda and the weights",
    },
    components=("lambda", "Wm0", "Wc0", "Wi"),
)
#: the praise of 12.1 when the centre weight is negative
NEGATIVE_WM0_PRAISE = "note the negative centre weight Wm0: the weights still sum to 1"


def check_merwe_weights(answer, *, n: int = MERWE["n"], alpha: float = MERWE["alpha"],
                        beta: float = MERWE["beta"], kappa: float = MERWE["kappa"]) -> Feedback:
    """12.1: Merwe's scaled sigma-point parameter and weights.

    answer : array (4,) -- [lambda, Wm0, Wc0, Wi] (dimensionless): lambda, the mean and covariance
        weights of the centre point, and the weight of each of the 2n other points
    """
    n = require_int("n", n, minimum=1)
    alpha, beta, kappa = require_positive("alpha", alpha), require_finite("beta", beta), require_finite("kappa", kappa)
    if abs(alpha ** 2 * (n + kappa)) < 1e-12:
        raise ValueError("alpha and kappa must give n + lambda != 0")
    expected = _merwe(n, alpha, beta, kappa)
    lam = expected[0]
    pairs = [
        (_merwe(n, alpha, beta, kappa, lam=alpha * (n + kappa) - n), "alpha_not_squared"),
        (_merwe(n, alpha, beta, kappa, wc_extra=0.0), "wc0_equals_wm0"),
        (_merwe(n, alpha, beta, kappa, wc_extra=1 - alpha + beta), "wc0_alpha"),
        (_merwe(n, alpha, beta, kappa, wc_extra=beta), "wc0_beta_only"),
        (_merwe(n, alpha, beta, kappa, wi_den=2 * lam), "wi_lambda"),
        (_merwe(2 * n + 1, alpha, beta, kappa), "n_points"),
        (_merwe(n, alpha, beta, 0.0), "no_kappa"),
        (_merwe(n, alpha, beta, kappa, lam=alpha ** 2 * (n + kappa)), "no_minus_n"),
    ]
    wrong = [(v, key) for v, key in pairs if np.all(np.isfinite(v)) and not np.allclose(v, expected)]
    E = MERWE_WEIGHTS if expected[1] >= 0 else replace(MERWE_WEIGHTS, praise=NEGATIVE_WM0_PRAISE)
    fb = E.judge(answer, expected, wrong, rtol=NUM_RTOL, atol=NUM_ATOL)
    flat = finite_of_size(answer, 4)
    with np.errstate(all="ignore"):  # 1e308 entries: an overflowing sum is simply not 1
        off_sum = flat is not None and not abs(flat[1] + 2 * n * flat[3] - 1.0) <= 1e-3
    if not fb.correct and fb.answered and off_sum and fb.message not in E.hints.values() and \
            replace(E, components=()).judge(answer, expected, wrong, rtol=NUM_RTOL, atol=NUM_ATOL).message == GENERIC_HINT:
        return E.mistake("sum")   # before the hint naming the wrong entries: the sum says more
    return fb


def _circular_cases():
    """(angles, weights) test inputs of 12.2 (rad, dimensionless)."""
    return [
        (np.array([3.0, -3.0, 2.9, -3.1]), np.array([0.25, 0.25, 0.25, 0.25])),
        (np.array([0.2, -0.4, 6.0]), np.array([0.5, 0.3, 0.2])),
        (np.array([1.0, 2.0, 1.5]), np.array([-1.0, 1.0, 1.0])),
        (np.array([2.5, -2.8]), np.array([0.7, 0.3])),
    ]


CIRCULAR_MEAN = Exercise(
    "12.2",
    praise="atan2 of the weighted sine and cosine sums, right across +-pi and with a negative weight",
    hints={
        "plain": "that is the plain weighted mean: angles near +pi and -pi average to about 0 instead of pi",
        "unweighted": "use the weights: sum w_i sin(theta_i) and sum w_i cos(theta_i)",
        "atan2_order": "atan2 takes the sine sum first: atan2(sum w sin, sum w cos)",
        "shifted": "shifting the angles into [0, 2 pi) only moves the problem from pi to 0",
        "arctan": "arctan of the ratio loses the quadrant (the cosine sum can be negative): use atan2",
        "size": "the circular mean of a set of angles is one angle: return a single float",
        "wrap_2pi": "your mean lies in [0, 2 pi): the circular mean is an angle in (-pi, pi], as atan2 returns it",
    },
    angles=True,
)


def check_circular_mean(fn) -> Feedback:
    """12.2: the student's ``fn(angles, weights)`` -> weighted circular mean (rad, one float in
    (-pi, pi]), called on fixed sets of angles (m,) and weights (m,), one of them negative."""
    E = CIRCULAR_MEAN
    cases = _circular_cases()
    outs, fb = call_checked(E, fn, cases, (1,), "circular_mean(angles, weights)", size_hint=E.hints["size"])
    if fb is not None:
        return fb
    answer = pi_for_minus_pi(np.array(outs).reshape(len(cases)))

    def each(f):
        return pi_for_minus_pi(np.array([f(a, w) for a, w in cases]))

    expected = each(lambda a, w: math.atan2(np.dot(w, np.sin(a)), np.dot(w, np.cos(a))))
    wrong = [
        (each(lambda a, w: np.dot(w, a)), "plain"),
        (each(lambda a, w: math.atan2(np.sin(a).sum(), np.cos(a).sum())), "unweighted"),
        (each(lambda a, w: math.atan2(np.dot(w, np.cos(a)), np.dot(w, np.sin(a)))), "atan2_order"),
        (each(lambda a, w: float(wrap_angle(np.dot(w, np.mod(a, 2 * np.pi))))), "shifted"),
        (each(lambda a, w: math.atan(np.dot(w, np.sin(a)) / np.dot(w, np.cos(a)))), "arctan"),
        (each(lambda a, w: np.mod(math.atan2(np.dot(w, np.sin(a)), np.dot(w, np.cos(a))), 2 * np.pi)), "wrap_2pi"),
    ]
    return E.judge(answer, expected, distinct_mistakes(wrong, expected, FN_RTOL), rtol=FN_RTOL, atol=FN_ATOL,
                   what=FN_RESULT)


#: the exercise records of this lesson, in notebook order
RECORDS = (MERWE_WEIGHTS, CIRCULAR_MEAN)
