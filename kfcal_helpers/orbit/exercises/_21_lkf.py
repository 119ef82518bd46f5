"""Exercise checks of notebook 21 (the LKF about the nominal orbit): 21.1-21.2."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy import stats

from ...exercises._core import Exercise, Feedback
from ...validation import require_probability
from ..model import nominal_state, stacked_jacobian, visible
from ..params import N_STATES, N_STATION_MEAS, OrbitParams

__all__ = ["STEP_STATIONS", "STEP_ALPHA", "S_TIME", "S_PRIOR", "nis_step_band", "step_stations_visible",
           "check_nis_step_band", "check_two_station_S", "RECORDS"]

#: 21.1: how many stations each of 20 runs of a truth-model test had at one step (0: predict only)
STEP_STATIONS = (1, 2, 1, 1, 0, 2, 1, 1, 2, 1, 0, 1, 1, 2, 1, 1, 1, 0, 2, 1)
#: 21.1: significance of the band
STEP_ALPHA = 0.05
#: 21.2: the time (s) of the step whose innovation covariance is asked: two stations see the nominal
S_TIME = 240.0
#: 21.2: the prior covariance M (4, 4) at that step, [km^2, (km/s)^2, ...] (diagonal: 50 m and 0.5 m/s)
S_PRIOR = np.diag([2.5e-3, 2.5e-7, 2.5e-3, 2.5e-7])


def nis_step_band(stations, alpha: float = STEP_ALPHA, dim: int | None = None, *, divide_all: bool = False,
                  one_sided: bool = False) -> np.ndarray:
    """``[lower, upper]`` of one step's NIS averaged over the runs with a station: chi-square with the dof
    present (3 per station, summed over the runs) over the number of those runs.  The keywords build the
    common wrong answers: ``dim`` (a fixed dof per run), ``divide_all`` (over all runs), ``one_sided``."""
    m = np.asarray(stations, dtype=int)
    present = m > 0
    n = int(present.sum())
    dof = N_STATION_MEAS * int(m.sum()) if dim is None else dim * n
    lo, hi = (alpha, 1 - alpha) if one_sided else (alpha / 2, 1 - alpha / 2)
    return np.array([stats.chi2.ppf(lo, dof), stats.chi2.ppf(hi, dof)]) / (m.size if divide_all else n)


NIS_STEP_BAND = Exercise(
    "21.1",
    praise="the dof present at the step ({dof} = 3 x {stations} stations) over the {n} runs with a measurement",
    hints={
        "fixed3": "that band gives every run one station (3 dof): add up 3 dof for each station each run had",
        "fixed6": "that band gives every run two stations (6 dof): add up 3 dof for each station each run had",
        "all_runs": "a run without a station has no NIS at this step: average over the runs with one, "
                    "and divide by their number",
        "one_sided": "a two-sided test puts alpha/2 in each tail: use the alpha/2 and 1 - alpha/2 quantiles",
        "state_dim": "the NIS has the dimension of the measurements present, not the state's 4",
        "not_divided": "the band is for the run average: divide the chi-square quantiles by the number of runs "
                       "with a measurement",
    },
)


def check_nis_step_band(answer, *, stations=STEP_STATIONS, alpha: float = STEP_ALPHA) -> Feedback:
    """21.1: the two-sided band of one step's run-averaged NIS, the runs having had ``stations`` stations
    (0: no measurement) at that step, at significance ``alpha``.

    answer : array (2,) -- [lower, upper] (dimensionless), the computed values (no rounding)
    """
    alpha = require_probability("alpha", alpha)
    m = np.asarray(stations, dtype=int)
    if m.ndim != 1 or np.any(m < 0) or not np.any(m > 0):
        raise ValueError("stations must be a 1-D sequence of counts >= 0 with at least one run > 0")
    n = int((m > 0).sum())
    expected = nis_step_band(m, alpha)
    wrong = [(nis_step_band(m, alpha, 3), "fixed3"), (nis_step_band(m, alpha, 6), "fixed6"),
             (nis_step_band(m, alpha, divide_all=True), "all_runs"),
             (nis_step_band(m, alpha, 3, divide_all=True), "all_runs"),
             (nis_step_band(m, alpha, one_sided=True), "one_sided"),
             (nis_step_band(m, alpha, N_STATES), "state_dim"),
             (nis_step_band(m, alpha) * n, "not_divided")]
    E = replace(NIS_STEP_BAND, praise=NIS_STEP_BAND.praise.format(dof=N_STATION_MEAS * int(m.sum()),
                                                                  stations=int(m.sum()), n=n))
    return E.judge(answer, expected, wrong, rtol=1e-6, atol=0.0)


def step_stations_visible(t: float = S_TIME, params: OrbitParams | None = None) -> np.ndarray:
    """The stations (0-based, increasing) that see the nominal satellite at time ``t`` (s)."""
    p = OrbitParams() if params is None else params
    return np.flatnonzero(visible(nominal_state(t, p), t, p))


TWO_STATION_S = Exercise(
    "21.2",
    praise="S = H M H^T + R_k, R_k = blockdiag(R, R): one R block per station, in the stations' order",
    hints={
        "kron_order": "R_k repeats R's 3x3 block once per station (np.kron(np.eye(m), R)); np.kron(R, np.eye(m)) "
                      "interleaves the stations' components",
        "one_R": "each station's measurement has its own noise: R_k holds R once per station, not only for the first",
        "no_R": "S is the covariance of the innovation: add the measurement noise R_k",
    },
)


def check_two_station_S(answer, *, t: float = S_TIME, M=None) -> Feedback:
    """21.2: the innovation covariance S (6, 6) of the LKF at time ``t`` (s), where two stations see the
    nominal: ``H M H^T + blockdiag(R, R)`` with ``H`` the stacked ``C_i`` at the nominal and ``M`` the prior
    covariance (default :data:`S_PRIOR`), R the course's ``Rtrue``.

    answer : array (6, 6) (km^2, km^2/s, ...), the computed values (no rounding)
    """
    p = OrbitParams()
    M = S_PRIOR if M is None else np.asarray(M, dtype=float)
    ids = step_stations_visible(t, p)
    H = stacked_jacobian(nominal_state(t, p), t, ids, p)
    m = ids.size
    HMH = H @ M @ H.T
    R_k = np.kron(np.eye(m), p.Rtrue)
    one_R = np.zeros_like(R_k)
    one_R[:N_STATION_MEAS, :N_STATION_MEAS] = p.Rtrue
    wrong = [(HMH + np.kron(p.Rtrue, np.eye(m)), "kron_order"), (HMH + one_R, "one_R"), (HMH, "no_R")]
    return TWO_STATION_S.judge(answer, HMH + R_k, wrong, rtol=1e-9, atol=1e-15)


RECORDS = (NIS_STEP_BAND, TWO_STATION_S)
