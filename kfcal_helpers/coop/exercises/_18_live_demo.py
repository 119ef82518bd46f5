"""Exercise checks of notebook 18 (the cooperative-localization live demo): 18.1-18.2."""

from __future__ import annotations


from dataclasses import replace

import numpy as np
from scipy import stats

from ...consistency import chi2_bounds
from ..model import (
    N_MEAS,
    N_STATES,
    CoopParams,
    jacobian_A,
    jacobian_C,
    nominal_trajectory,
    observability_matrix,
    jacobian_step,
)
from ...exercises._core import (BAND_NAMES, Exercise, Feedback, as_array, distinct_mistakes)
from ...validation import require_instance, require_int, require_probability



_RTOL_NIS = 1e-9   # NIS bounds: the computed quantiles (K = 1000 vs 1001 differ by 3e-5)



SUBSET_NIS_BOUNDS = Exercise(
    "18.1",
    praise="{m} degrees of freedom per update, K = {K} updates, divided by K",
    hint="the time average of K independent χ²(m) values: K times it is χ²(mK)",
    hints={
        "dim5": "the NIS of an update that uses m measurements has m degrees of freedom, not always 5",
        "dim6": "the NIS has the dimension of the measurements used (m of them), not the state's 6",
        "count_nan": "count only the samples with a measurement: the log's first row (t = 0) is NaN",
        "not_divided": "these bound the SUM of the NIS values; the time average is that sum divided by K",
        "one_sided": "a two-sided test at α = 0.05 puts α/2 = 0.025 in each tail",
        "normal": "close: that is the normal approximation m ± 1.96 √(2m/K); use the chi-square quantiles (scipy.stats.chi2.ppf or chi2_bounds)",
    },
    components=BAND_NAMES,
)


def check_subset_nis_bounds(answer, *, n_meas: int = 3, n_samples: int = 1001, alpha: float = 0.05) -> Feedback:
    """Exercise 18.1: the two-sided ``1 - alpha`` bounds ``[lower, upper]`` (dimensionless),
    shape (2,), of the time-averaged NIS of one run that uses ``n_meas`` of the 5 measurements,
    on a log of ``n_samples`` samples whose first sample has no measurement."""
    m = require_int("n_meas", n_meas, minimum=1)
    if m > N_MEAS:
        raise ValueError(f"n_meas must be an integer in 1..{N_MEAS}, got {m}")
    n_samples = require_int("n_samples", n_samples, minimum=3)
    alpha = require_probability("alpha", alpha)
    K = n_samples - 1
    right = np.array(chi2_bounds(m, K, alpha))
    z = stats.norm.ppf(1 - alpha / 2)
    pairs = [
        (chi2_bounds(N_MEAS, K, alpha), "dim5"),
        (chi2_bounds(N_STATES, K, alpha), "dim6"),
        (chi2_bounds(m, K + 1, alpha), "count_nan"),
        (right * K, "not_divided"),
        (stats.chi2.ppf([alpha, 1 - alpha], m * K) / K, "one_sided"),
        (m + np.array([-1.0, 1.0]) * z * np.sqrt(2 * m / K), "normal"),
        (m + np.array([-1.0, 1.0]) * round(z, 2) * np.sqrt(2 * m / K), "normal"),  # with z rounded (1.96)
        (m + np.array([-1.0, 1.0]) * 2.0 * np.sqrt(2 * m / K), "normal"),  # the two-sigma rule
    ]
    E = replace(SUBSET_NIS_BOUNDS, praise=SUBSET_NIS_BOUNDS.praise.format(m=m, K=K))
    return E.judge(answer, right, distinct_mistakes(pairs, right, _RTOL_NIS), rtol=_RTOL_NIS, atol=0.0)


#: the measurement subsets of exercise 18.2: no bearings, no GPS north, bearings only (notebook 18
#: prints all five, no range, no GPS and GPS only before it)
LOST_SUBSETS = ((1, 3, 4), (0, 1, 2, 3), (0, 2))


def lost_directions(subsets=LOST_SUBSETS, window: int = 10, params: CoopParams | None = None,
                    exact: bool = True) -> np.ndarray:
    """6 - rank of the stacked observability matrix (``observability_matrix``, rank by
    ``np.linalg.matrix_rank``) of the linearized DT model along the nominal, over the first
    ``window`` samples, with only the rows ``subset`` of H; one integer per subset.

    ``exact=True`` uses the exact Jacobian of the one-step map (``jacobian_step``);
    ``exact=False`` the Euler ``F = I + dt A``, which makes a rotation of the whole scene look
    weakly observable (a small but non-zero singular value), because it is the Jacobian of the
    Euler step and not of the arcs that generated the nominal."""
    p = require_instance("params", params, CoopParams, allow_none=True) or CoopParams()
    window = require_int("window", window, minimum=1)
    x = nominal_trajectory(p, window)
    if window < 2:
        F = np.zeros((0, 6, 6))
    elif exact:
        F = jacobian_step(x[:-1], p.u0, p.dt, p.L)
    else:
        F = np.eye(N_STATES) + p.dt * jacobian_A(x[:-1], p.u0, p.L)
    H = jacobian_C(x)
    out = []
    for sub in subsets:
        rows = [require_int("subsets", i, minimum=0) for i in sub]
        if not rows or max(rows) >= N_MEAS or len(set(rows)) != len(rows):
            raise ValueError(f"subsets must hold distinct measurement indices 0..4, got {tuple(sub)}")
        out.append(N_STATES - np.linalg.matrix_rank(observability_matrix(F, H[:, rows])))
    return np.array(out, dtype=float)


LOST_DIRECTIONS = Exercise(
    "18.2",
    praise="without the bearings nothing is lost; without the GPS north only the common north shift (1); with the bearings alone the common translation (2) and a rotation of the whole scene (1), while the vehicles' known speeds fix the scale",
    hint="build O as in the notebook's observability cell, with the rows of each subset, F the exact jacobian_step, and count 6 - rank",
    hints={
        "ranks": "those are ranks; the exercise asks how many directions are lost: 6 - rank",
        "euler": "check which F you used: the exercise asks first for the exact Jacobian of the one-step map, jacobian_step, not the Euler F = I + ΔT A (that is the follow-up question); then compute 6 - rank again",
        "reversed": "right counts, wrong order: give them as [no bearings, no GPS north, bearings only]",
        "north_observable": "without the GPS north, move both vehicles north together: does any bearing, the range or the GPS east change?",
        "north_both_lost": "for the subset without the GPS north, test the common shifts one at a time: which of the remaining rows of H change when both vehicles move east together, and which when they move north together? Then compute the rank",
        "bearings_observable": "with the bearings alone, move both vehicles by the same vector: does either bearing change?",
        "bearings_scale_lost": "O stacks 10 samples of a moving scene, not one snapshot: what the bearings cannot see at one sample is not what they cannot see over the window; compute the rank of the stacked O",
        "no_bearings_lost": "for the subset without the bearings, count with the stacked O over all 10 samples, not from one sample's geometry: build O with rows (1, 3, 4) and compute 6 - rank",
    },
    components=("the count without the bearings", "the count without the GPS north", "the count with the bearings only"),
    units=False,
)


def check_lost_directions(answer, *, window: int = 10) -> Feedback:
    """Exercise 18.2: for the subsets no bearings ``(1, 3, 4)``, no GPS north ``(0, 1, 2, 3)`` and
    bearings only ``(0, 2)``, the number of state directions that are unobservable over the first
    ``window`` samples of the nominal (6 - rank of the stacked observability matrix of the
    linearized DT model with the exact Jacobian of the one-step map); answer: 3 integers.
    Without the GPS north the common north shift is lost (1); with the bearings alone the common
    translation (2) and a rotation of the whole scene (1); the Euler ``F = I + dt A`` makes the
    rotation look weakly observable, hence 2 there: it is the Jacobian of the Euler step, not of the
    arcs that generated the nominal (an artefact of that mismatch, not information)."""
    window = require_int("window", window, minimum=2)
    right = lost_directions(LOST_SUBSETS, window)
    a = as_array(answer)
    if a is not None and a.size == 3 and np.all(np.isfinite(a)) and not np.allclose(a, np.round(a)):
        return LOST_DIRECTIONS.feedback(False, "a number of directions is a whole number: 6 minus a rank")
    pairs = [(N_STATES - right, "ranks"), (lost_directions(LOST_SUBSETS, window, exact=False), "euler"),
             (right * np.array([1, 0, 1]), "north_observable"), (right + np.array([0, 1, 0]), "north_both_lost"),
             (right * np.array([1, 1, 0]), "bearings_observable"), (right + np.array([0, 0, 1]), "bearings_scale_lost"),
             (right[::-1], "reversed")]
    for lost in (1, 2, 3):
        pairs.append((right + np.array([lost, 0, 0]), "no_bearings_lost"))
    return LOST_DIRECTIONS.judge(answer, right, distinct_mistakes(pairs, right, 0.0), rtol=0.0, atol=1e-9)


#: the exercise records of this lesson, in notebook order
RECORDS = (SUBSET_NIS_BOUNDS, LOST_DIRECTIONS)
