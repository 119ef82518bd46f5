"""Exercise checks of notebook 22 (EKF and UKF of the orbit problem): 22.1-22.2."""

from __future__ import annotations

import numpy as np
from scipy import stats

from ...exercises._core import Exercise, Feedback, distinct_mistakes
from ...validation import (require_covariance, require_finite, require_finite_array, require_int, require_shape,
                           require_significance)
from ..params import N_STATES, N_STATION_MEAS
from ..model import jacobian_C, measure
from ._shared import PARAMS, in_km, NIS_ALPHA, NIS_ONE, NIS_TWO, NUM_ATOL, NUM_RTOL, UPD_P, UPD_STATIONS, UPD_T, UPD_X, UPD_Y

__all__ = ["RUN_NIS_BAND", "STACKED_UPDATE", "RECORDS", "check_run_nis_band", "check_stacked_update"]

_P = PARAMS

RUN_NIS_BAND = Exercise(
    "22.1",
    praise="the band of the run-averaged NIS from the dof present: chi2 quantiles of sum 3 m_r, over the runs",
    hints={
        "fixed_dof": "3 dof for every run is the band of one station: the runs that see two stations bring 6 dof "
                     "each; add up the dof present",
        "max_dof": "6 dof for every run counts two stations where only one is present: add up the dof present",
        "state_dof": "the NIS has the measurement's dof (3 per station present), not the state's 4",
        "one_sided": "a two-sided test puts alpha/2 in each tail: use the alpha/2 and 1 - alpha/2 quantiles",
        "not_divided": "the band is of the run average: divide the chi-square quantiles by the number of runs",
    },
    components=("the lower bound", "the upper bound"),
    units=False,
)


def _band(dof: int, n: int, alpha: float, one_sided: bool = False) -> np.ndarray:
    q = (alpha, 1 - alpha) if one_sided else (alpha / 2, 1 - alpha / 2)
    return stats.chi2.ppf(q, dof) / n


def check_run_nis_band(answer, *, one: int = NIS_ONE, two: int = NIS_TWO, alpha: float = NIS_ALPHA) -> Feedback:
    """22.1: the two-sided band ``(lower, upper)`` at significance ``alpha`` of the NIS averaged over the runs
    that have a measurement at one step, ``one`` of them with one station (3 dof) and ``two`` with two (6 dof).

    answer : array (2,), dimensionless
    """
    one = require_int("one", one, minimum=0, maximum=10**6)
    two = require_int("two", two, minimum=0, maximum=10**6)
    if one + two < 1:
        raise ValueError("one and two: at least one run must have a station")
    alpha = require_significance("alpha", alpha)
    n = one + two
    dof = 3 * one + 6 * two
    expected = _band(dof, n, alpha)
    wrong = [(_band(3 * n, n, alpha), "fixed_dof"), (_band(6 * n, n, alpha), "max_dof"), (_band(4 * n, n, alpha), "state_dof"),
             (_band(dof, n, alpha, one_sided=True), "one_sided"), (_band(dof, n, alpha) * n, "not_divided")]
    return RUN_NIS_BAND.judge(answer, expected, distinct_mistakes(wrong, expected, 1e-9), rtol=NUM_RTOL, atol=NUM_ATOL)


STACKED_UPDATE = Exercise(
    "22.2",
    praise="the stations' rows stacked, R block diagonal and each phi residual wrapped",
    hints={
        "no_wrap": "one phi residual is close to 2 pi: wrap every phi entry of y - h(x-) to (-pi, pi] before the gain",
        "first_only": "that correction uses the first station only: stack the rows (and R blocks) of both stations",
        "second_only": "that correction uses the second station only: stack the rows (and R blocks) of both stations",
        "gain_R": "K = P- H^T S^-1 with S = H P- H^T + R; P- H^T R^-1 is the gain only with the posterior P",
        "zero_based": "those are the next stations' rows: station i sits at omegaE t + (i - 1) pi/6 (the course "
                      "counts from 1)",
    },
    components=("X", "Xdot", "Y", "Ydot"),
)


def _update(x, P, t, stations, z, *, wrap=True, gain="S"):
    ids = np.asarray(stations, dtype=int)
    H = jacobian_C(x, t, _P)[ids].reshape(-1, 4)
    nu = np.asarray(z, dtype=float)[: ids.size] - measure(x, t, _P)[ids]
    if wrap:
        nu[:, 2] = np.angle(np.exp(1j * nu[:, 2]))
    nu = nu.ravel()
    R = np.kron(np.eye(ids.size), _P.Rtrue)
    if gain == "S":
        K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
    else:
        K = P @ H.T @ np.linalg.inv(R)
    return K @ nu


def check_stacked_update(answer, *, x=UPD_X, P_diag=UPD_P, t: float = UPD_T, stations=UPD_STATIONS,
                         y=UPD_Y) -> Feedback:
    """22.2: the EKF's correction ``x+ - x- = K nu`` (4,) [X, Xdot, Y, Ydot] (km, km/s) of one update of the
    prior ``x`` (4,) with covariance ``diag(P_diag)`` (4,) by the measurements ``y`` (m, 3) [rho, rhodot, phi]
    (km, km/s, rad) of the stations ``stations`` (m ints in 1..12) at time ``t`` (s), R = Rtrue per station.

    answer : array (4,)
    """
    x = require_shape("x", x, (N_STATES,))
    P = require_covariance("P_diag", np.diag(require_finite_array("P_diag", P_diag, (N_STATES,))), N_STATES)
    t = require_finite("t", t)
    ids = np.array([require_int("stations", s, minimum=1, maximum=_P.n_stations) for s in stations]) - 1
    if ids.size < 1 or len(set(ids.tolist())) != ids.size:
        raise ValueError(f"stations must be distinct station ids in 1..{_P.n_stations}, got {stations!r}")
    z = require_shape("y", y, (ids.size, N_STATION_MEAS))
    expected = _update(x, P, t, ids, z)
    wrong = [(_update(x, P, t, ids, z, wrap=False), "no_wrap"), (_update(x, P, t, ids, z, gain="R"), "gain_R"),
             (_update(x, P, t, (ids + 1) % _P.n_stations, z), "zero_based")]
    if ids.size > 1:
        wrong += [(_update(x, P, t, ids[:1], z[:1]), "first_only"), (_update(x, P, t, ids[1:2], z[1:2]), "second_only")]
    wrong = [(v, k) for v, k in wrong if np.all(np.isfinite(v))]
    return in_km(STACKED_UPDATE.judge(answer, expected, distinct_mistakes(wrong, expected, 1e-9), rtol=NUM_RTOL,
                                      atol=NUM_ATOL))


#: the exercise records of this lesson, in notebook order
RECORDS = (RUN_NIS_BAND, STACKED_UPDATE)
