"""Exercise checks of notebook 19 (the nonlinear orbit model): 19.1-19.3."""

from __future__ import annotations

import math

import numpy as np

from ...exercises._core import Exercise, Feedback, as_array, distinct_mistakes, judge, unanswered
from ...validation import require_finite, require_shape
from ..model import measure_relative, station_states, visible
from ..params import N_STATES
from ._shared import PARAMS, in_km, station_setting, MEAS_STATION, MEAS_T, MEAS_X, NUM_ATOL, NUM_RTOL, PERIOD_DX0, VIS_T, VIS_X

__all__ = ["STATION_MEASUREMENT", "VISIBLE_STATIONS", "PERTURBED_PERIOD", "RECORDS", "check_station_measurement",
           "check_visible_stations", "check_perturbed_period"]

_P = PARAMS


def _station_variant(t, station, mistake):
    """The state [Xi, Xidot, Yi, Yidot] of station ``station`` (1..12) at ``t`` with one mistake."""
    i = station - 1
    if mistake == "zero_based":
        i = station
    if mistake == "no_rotation":
        t = 0.0
    st = station_states(t, _P)[i % _P.n_stations].copy()
    if mistake == "fixed_station":
        st[[1, 3]] = 0.0
    return st


STATION_MEASUREMENT = Exercise(
    "19.1",
    praise="range, range rate and angle of the line of sight from the rotating station",
    hints={
        "zero_based": "that is the next station's measurement: station i sits at omegaE t + (i - 1) pi/6 (the "
                      "course counts from 1)",
        "no_rotation": "the stations turn with the Earth: theta_i(t) = omegaE t + (i - 1) pi/6, not its value at t = 0",
        "fixed_station": "the station moves with the Earth's rotation: its velocity (-RE omegaE sin theta_i, "
                         "RE omegaE cos theta_i) enters the range rate",
        "reversed": "phi is the direction from the station to the satellite: atan2(Y - Yi, X - Xi)",
        "atan2_order": "atan2 takes the Y difference first: atan2(Y - Yi, X - Xi)",
    },
    components=("the range rho", "the range rate rhodot", "the angle phi"),
    angles=(2,),
)


def check_station_measurement(answer, *, x=MEAS_X, t: float = MEAS_T, station: int = MEAS_STATION) -> Feedback:
    """19.1: the noise-free measurement ``[rho, rhodot, phi]`` (km, km/s, rad; phi in (-pi, pi]) of station
    ``station`` (1..12, the course's numbering) at time ``t`` (s) of the satellite state ``x`` (4,)
    [X, Xdot, Y, Ydot] (km, km/s).

    answer : array (3,)
    """
    x, t, station = station_setting(x, t, station)
    E = STATION_MEASUREMENT
    expected = measure_relative(x - _station_variant(t, station, "right"))
    d = x - _station_variant(t, station, "right")
    reversed_phi = expected.copy()
    reversed_phi[2] = math.atan2(-d[2], -d[0])
    swapped = expected.copy()
    swapped[2] = math.atan2(d[0], d[2])
    wrong = [(measure_relative(x - _station_variant(t, station, m)), m) for m in ("zero_based", "no_rotation", "fixed_station")]
    wrong += [(reversed_phi, "reversed"), (swapped, "atan2_order")]
    return in_km(E.judge(answer, expected, distinct_mistakes(wrong, expected, 1e-9), rtol=NUM_RTOL, atol=NUM_ATOL))


VISIBLE_STATIONS = Exercise(
    "19.2",
    praise="the stations whose horizon the line of sight clears, (r - r_i) . r_i > 0",
    hints={
        "zero_based": "those are 0-based indices: give the course's station ids 1..12",
        "position_rule": "(r . r_i > 0) only says the satellite is over the station's half of the Earth: the line of "
                         "sight r - r_i must be above the horizon, (r - r_i) . r_i > 0",
        "no_rotation": "the stations turn with the Earth: theta_i(t) = omegaE t + (i - 1) pi/6, not its value at t = 0",
        "unwrapped": "no station at all? theta_i(t) grows past 2 pi: wrap phi_i - theta_i to (-pi, pi] before "
                     "comparing it with pi/2 (or use (r - r_i) . r_i > 0)",
        "order": "give the ids in increasing order",
        "whole": "station ids are whole numbers 1..12",
    },
)


def _visible_ids(x, t, *, rule="horizon", rotate=True):
    st = station_states(t if rotate else 0.0, _P)
    r_i = st[:, [0, 2]]
    r = np.asarray(x, dtype=float)[[0, 2]]
    lhs = (r - r_i) @ r_i.T if rule == "horizon" else r_i @ r
    lhs = np.diag(lhs) if lhs.ndim == 2 else lhs
    return np.flatnonzero(lhs > 0) + 1.0


def check_visible_stations(answer, *, x=VIS_X, t: float = VIS_T) -> Feedback:
    """19.2: the ids (1..12, increasing) of the stations that see the satellite at state ``x`` (4,) and time
    ``t`` (s).

    answer : integer array (m,) -- the visible stations' ids
    """
    x = require_shape("x", x, (N_STATES,))
    t = require_finite("t", t)
    E = VISIBLE_STATIONS
    expected = np.flatnonzero(visible(x, t, _P)) + 1.0
    a = as_array(answer)
    if not unanswered(answer) and a is not None and np.all(np.isfinite(a)):
        if a.size == 0 and expected.size:
            return E.mistake("unwrapped")
        if not np.allclose(a, np.round(a)):
            return E.mistake("whole")
        if a.size == expected.size and a.size > 1 and np.array_equal(np.sort(a.ravel()), expected) \
                and not np.array_equal(a.ravel(), expected):
            return E.mistake("order")
    wrong = [(expected - 1.0, "zero_based"), (_visible_ids(x, t, rule="position"), "position_rule"),
             (_visible_ids(x, t, rotate=False), "no_rotation")]
    wrong = [(v, k) for v, k in wrong if not (v.shape == expected.shape and np.array_equal(v, expected))]
    # ids are whole numbers without units: no units, degree or order slip is tried (the order is told above)
    pairs = [(value, E.hints[key]) for value, key in wrong]
    return judge(E.id, answer, expected, pairs, rtol=0.0, atol=1e-9, praise=E.praise, hint=E.hint, slips=False)


PERTURBED_PERIOD = Exercise(
    "19.3",
    praise="the energy fixes the semi-major axis a = -mu / (2 E), and a the period 2 pi sqrt(a^3 / mu)",
    hints={
        "nominal": "that is the nominal's period: the perturbation changes the speed, hence the energy and a",
        "no_half": "the specific energy is v^2 / 2 - mu / r: the kinetic term has a factor 1/2",
        "circular_speed": "mu / v^2 is the radius of a circular orbit at that speed: the orbit is not circular any "
                          "more; take a from the energy, a = -mu / (2 E)",
        "minutes": "the period is asked in seconds",
        "radius_a": "a is not the initial radius r0: take it from the energy, a = -mu / (2 E)",
    },
)


def _period(x0, *, half=True, a_from="energy"):
    mu = _P.mu
    r = math.hypot(x0[0], x0[2])
    v2 = x0[1] ** 2 + x0[3] ** 2
    if a_from == "speed":
        a = mu / v2
    elif a_from == "radius":
        a = r
    else:
        energy = (0.5 if half else 1.0) * v2 - mu / r
        if energy >= 0:
            return float("nan")
        a = -mu / (2.0 * energy)
    return 2.0 * math.pi * math.sqrt(a ** 3 / mu)


def check_perturbed_period(answer, *, dx0=PERIOD_DX0) -> Feedback:
    """19.3: the period (s) of the orbit that starts at ``x_nom(0) + dx0`` (``dx0`` (4,), km and km/s) about
    the point-mass Earth (mu = 398600 km^3/s^2), from its specific energy.

    answer : a float, s
    """
    dx0 = require_shape("dx0", dx0, (N_STATES,))
    x0 = np.array([_P.r0, 0.0, 0.0, _P.r0 * _P.n]) + dx0
    expected = _period(x0)
    if not math.isfinite(expected):
        raise ValueError("dx0 must leave the orbit bound (negative energy)")
    wrong = [(_P.period, "nominal"), (_period(x0, half=False), "no_half"), (_period(x0, a_from="speed"), "circular_speed"),
             (expected / 60.0, "minutes"), (_period(x0, a_from="radius"), "radius_a")]
    wrong = [(v, k) for v, k in wrong if math.isfinite(v)]
    return in_km(PERTURBED_PERIOD.judge(answer, expected, distinct_mistakes(wrong, expected, 1e-9), rtol=NUM_RTOL,
                                        atol=NUM_ATOL))


#: the exercise records of this lesson, in notebook order
RECORDS = (STATION_MEASUREMENT, VISIBLE_STATIONS, PERTURBED_PERIOD)
