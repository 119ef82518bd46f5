"""Exercise checks of notebook 22 (EKF and UKF of the orbit problem): 22.1-22.2."""

from __future__ import annotations

import numpy as np
from filterpy.kalman import MerweScaledSigmaPoints

from ...angles import angle_slice, weighted_mean, wrap_angle
from ...exercises._core import Exercise, Feedback, distinct_mistakes, matches
from ...validation import (require_covariance, require_finite, require_finite_array, require_int, require_positive,
                           require_shape)
from ..params import N_STATES, N_STATION_MEAS
from ..model import jacobian_C, measure
from ._shared import (PARAMS, in_km, NUM_ATOL, NUM_RTOL, UKF_ALPHA, UKF_BETA, UKF_KAPPA, UKF_PHI, UPD_P, UPD_STATIONS,
                      UPD_T, UPD_X, UPD_Y)

__all__ = ["UKF_PHI_MEAN", "STACKED_UPDATE", "RECORDS", "check_ukf_phi_mean", "check_stacked_update"]

_P = PARAMS

UKF_PHI_MEAN = Exercise(
    "22.1",
    praise="atan2 of the Wm-weighted sines and cosines: the sigma points' mean phi across +-pi, as z_mean takes it",
    hints={
        "plain": "that is an arithmetic mean of the phi values: angles just above -pi and just below +pi average to "
                 "about 0; take atan2 of the Wm-weighted sines and cosines, as the notebook's z_mean does",
        "unweighted": "every sigma point weighs the same in your mean: weight them by the mean weights Wm of the "
                      "sigma points",
        "wc": "those are the covariance weights Wc: the mean of the sigma points takes the mean weights Wm",
        "wrap_2pi": "your phi lies in [0, 2 pi): the exercise asks for (-pi, pi], as atan2 returns it",
        "shifted": "shifting the phi values into [0, 2 pi) (or np.unwrap) before a weighted arithmetic mean is not "
                   "the circular mean: take atan2 of the Wm-weighted sines and cosines",
        "arctan": "arctan of the ratio of the sums loses the quadrant (the cosine sum is negative near +-pi): use "
                  "atan2(sine sum, cosine sum)",
    },
    angles=True,
)


_AT_PI = 1e-9  # an angle this close to -pi is pi: (-pi, pi] or [-pi, pi) is a convention, not a mistake


def _pi_for_minus_pi(v: float) -> float:
    return float(np.pi) if abs(float(v) + np.pi) < _AT_PI else float(v)


def _circular(phi: np.ndarray, w: np.ndarray) -> float:
    """The weighted circular mean of the angles ``phi`` (m,) (rad), in (-pi, pi]."""
    return float(weighted_mean(phi[:, None], w, angle_slice([0]))[0])


def check_ukf_phi_mean(answer, *, phi=UKF_PHI, alpha: float = UKF_ALPHA, beta: float = UKF_BETA,
                       kappa: float = UKF_KAPPA) -> Feedback:
    """22.1: the UKF's predicted phi (rad, one float in (-pi, pi]) of one station: the circular mean, with the
    mean weights ``Wm`` of ``MerweScaledSigmaPoints(4, alpha, beta, kappa)``, of the ``phi`` entries (9,) (rad)
    of the nine measurement sigma points (the centre point first).

    answer : float, rad
    """
    phi = require_finite_array("phi", phi, (2 * N_STATES + 1,))
    alpha, beta, kappa = require_positive("alpha", alpha), require_finite("beta", beta), require_finite("kappa", kappa)
    if abs(alpha**2 * (N_STATES + kappa)) < 1e-12:
        raise ValueError("alpha and kappa must give n + lambda = alpha^2 (n + kappa) != 0")
    points = MerweScaledSigmaPoints(N_STATES, alpha=alpha, beta=beta, kappa=kappa)
    wm, wc = points.Wm, points.Wc
    sin_sum, cos_sum = wm @ np.sin(phi), wm @ np.cos(phi)
    if np.hypot(sin_sum, cos_sum) < 1e-9:
        raise ValueError("phi has no mean direction: its Wm-weighted sines and cosines sum to 0")
    expected = _pi_for_minus_pi(_circular(phi, wm))
    if matches(answer, -np.pi, rtol=0, atol=_AT_PI):
        answer = np.pi
    shifted = float(wm @ np.mod(phi, 2 * np.pi))
    wrong = [(wm @ phi, "plain"), (np.mean(phi), "plain"), (_circular(phi, np.full(phi.size, 1.0 / phi.size)), "unweighted"),
             (_circular(phi, wc), "wc"), (np.mod(expected, 2 * np.pi), "wrap_2pi"), (shifted, "shifted"),
             (wrap_angle(shifted), "shifted")]
    if cos_sum != 0:
        wrong.append((np.arctan(sin_sum / cos_sum), "arctan"))
    wrong = [(_pi_for_minus_pi(v), key) for v, key in wrong]
    return in_km(UKF_PHI_MEAN.judge(answer, expected, distinct_mistakes(wrong, expected, 1e-9), rtol=NUM_RTOL,
                                    atol=NUM_ATOL))


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
RECORDS = (UKF_PHI_MEAN, STACKED_UPDATE)
