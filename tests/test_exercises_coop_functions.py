"""The check of the exercise that asks the student to WRITE a piece of the coop model as a function:
08.3, the measurement function h(x) for one state (6,) or a stack of states (..., 6).

The check accepts a right function written here by another route (plain Python loops over the states,
math.atan2 and a wrapping by the complex exponential), answers each listed wrong function, built
here by making the mistake, with that mistake's hint, and answers a half-written, raising or
malformed function with a hint, never a traceback."""

import cmath
import math

import numpy as np
import pytest

from kfcal_helpers.coop import measure, wrap_angle
from kfcal_helpers.coop.exercises import EXERCISES, check_measure_function
from kfcal_helpers.exercises._core import GENERIC_HINT, Feedback

HINTS = EXERCISES["08.3"].hints


def wrap(a):
    """(-pi, pi] by the complex exponential (another route than the model's np.mod)."""
    w = cmath.phase(cmath.exp(1j * a))
    return math.pi if abs(w + math.pi) < 1e-12 else w


def h_loops(x, mistake=None):
    """h for (6,) or (..., 6), one state at a time in plain Python; ``mistake`` makes one mistake."""
    x = np.asarray(x, dtype=float)
    flat = x.reshape(-1, 6)
    out = []
    for xg, eg, tg, xa, ea, ta in flat.tolist():
        dxi, deta = xa - xg, ea - eg
        to_uav, to_ugv = math.atan2(deta, dxi), math.atan2(-deta, -dxi)
        if mistake == "atan2_order":
            to_uav, to_ugv = math.atan2(dxi, deta), math.atan2(-dxi, -deta)
        if mistake == "same_direction":
            to_ugv = to_uav
        h_g, h_a = (ta, tg) if mistake == "swapped_heading" else (tg, ta)
        b1, b2 = to_uav - h_g, to_ugv - h_a
        if mistake != "no_wrap":
            b1, b2 = wrap(b1), wrap(b2)
        if mistake == "degrees":
            b1, b2 = math.degrees(b1), math.degrees(b2)
        gps = (xg, eg) if mistake == "ugv_gps" else (xa, ea)
        out.append([b1, math.sqrt(dxi * dxi + deta * deta), b2, *gps])
    return np.array(out).reshape(x.shape[:-1] + (5,))


def test_accepts_the_right_function_written_with_loops():
    fb = check_measure_function(h_loops)
    assert isinstance(fb, Feedback) and fb.correct and fb.message == EXERCISES["08.3"].praise
    assert "\n" not in str(fb) and str(fb).startswith("✔ 08.3")


def test_accepts_the_package_measure_and_the_other_pi_convention():
    assert check_measure_function(measure).correct
    minus_pi = lambda x: np.where(np.isclose(h_loops(x), np.pi), -np.pi, h_loops(x))  # noqa: E731
    assert check_measure_function(minus_pi).correct
    assert check_measure_function(lambda x: h_loops(x).tolist()).correct        # a list is numbers too


def test_the_right_function_is_what_measure_does_along_the_nominal():
    """On states that are not the check's: the loop version equals the model's measure (the exercise is the real h)."""
    rng = np.random.default_rng(8)
    x = rng.normal(0.0, 50.0, (200, 6))
    x[:, [2, 5]] = rng.uniform(-np.pi, np.pi, (200, 2))
    d = h_loops(x) - measure(x)
    d[:, [0, 2]] = (d[:, [0, 2]] + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(d).max() < 1e-12


@pytest.mark.parametrize("mistake", ["atan2_order", "no_wrap", "swapped_heading", "same_direction", "degrees",
                                     "ugv_gps"])
def test_rejects_each_mistake_with_its_hint(mistake):
    fb = check_measure_function(lambda x: h_loops(x, mistake))
    assert not fb.correct and fb.answered and fb.message == HINTS[mistake], str(fb)


def test_a_function_for_one_state_only_is_told_to_index_the_last_axis():
    def one_state(x):
        dxi, deta = x[3] - x[0], x[4] - x[1]      # rows, not components, for a stack
        return np.array([wrap(math.atan2(deta, dxi) - x[2]), math.hypot(dxi, deta),
                         wrap(math.atan2(-deta, -dxi) - x[5]), x[3], x[4]])

    fb = check_measure_function(one_state)
    assert not fb.correct and fb.message == HINTS["one_state"]

    def loop_first_row(x):                          # handles (6,), returns one row for a stack
        return h_loops(np.asarray(x).reshape(-1, 6)[0])

    assert check_measure_function(loop_first_row).message == HINTS["one_state"]


def test_every_hint_has_a_wrong_answer_test():
    tested = {"atan2_order", "no_wrap", "swapped_heading", "same_direction", "degrees", "ugv_gps", "one_state",
              "wrap_2pi", "stack_axis"}   # the last two: test_08_3_stack_slips_get_their_own_hint
    assert tested == set(HINTS)


def test_unknown_wrong_function_gets_the_generic_hint():
    fb = check_measure_function(lambda x: h_loops(x) + np.array([0.0, 1.0, 0.0, 1.0, 1.0]))   # range and GPS off
    assert not fb.correct and fb.message == EXERCISES["08.3"].hint != GENERIC_HINT
    fb = check_measure_function(lambda x: h_loops(x) + np.array([0.0, 1.0, 0.0, 0.0, 0.0]))   # range 1 m long
    assert not fb.correct and fb.message.startswith("only the range is off, the rest is right"), str(fb)


@pytest.mark.parametrize("fn", [..., None, 3.0, "h", lambda x: None, lambda x: ..., lambda x: 1 / 0,
                                lambda x: "y", lambda x: np.full(np.shape(x)[:-1] + (5,), np.nan),
                                lambda x: np.zeros(7), lambda x: h_loops(x) * 1j, lambda x: {"y": 1}])
def test_half_written_or_malformed_functions_get_a_hint_not_a_traceback(fn):
    fb = check_measure_function(fn)
    assert isinstance(fb, Feedback) and not fb.correct
    assert "\n" not in str(fb) and str(fb).startswith("✘ 08.3")


def test_the_check_does_not_let_the_student_change_its_inputs():
    def in_place(x):
        y = h_loops(x)
        x[...] = 0.0
        return y

    fb = check_measure_function(in_place)
    assert not fb.correct and "don't modify your inputs: your function changed x;" in fb.message, str(fb)
    assert check_measure_function(h_loops).correct


def _h_vectorised(x):
    x = np.asarray(x, dtype=float)
    dxi, deta = x[..., 3] - x[..., 0], x[..., 4] - x[..., 1]
    return np.stack([wrap_angle(np.arctan2(deta, dxi) - x[..., 2]), np.hypot(dxi, deta),
                     wrap_angle(np.arctan2(-deta, -dxi) - x[..., 5]), x[..., 3], x[..., 4]], axis=-1)


def _changes_its_stack(x):
    if np.ndim(x) > 1:
        x[..., 2] += 1e-12        # changes a stack only: the hint is about the input, not about indexing
    return _h_vectorised(x)


def _rows_not_last_axis(x):
    out = _h_vectorised(x)
    return out.T if out.ndim > 1 else out


def _wrapped_to_0_2pi(x):
    out = _h_vectorised(x).copy()
    out[..., [0, 2]] = np.mod(out[..., [0, 2]], 2 * np.pi)
    return out


@pytest.mark.parametrize("fn, hint", [
    (_changes_its_stack, "don't modify your inputs: your function changed x"),
    (_rows_not_last_axis, "for a stack your function returns (5, K)"),
    (_wrapped_to_0_2pi, "wrapped to [0, 2 pi)"),
    (lambda x: _h_vectorised(x)[..., [0, 2, 1, 3, 4]], "the range and the bearing UAV->UGV are swapped"),
])
def test_08_3_stack_slips_get_their_own_hint(fn, hint):
    """A cold reading's cases: a function that changes a stack, measurements on the first axis, bearings in
    [0, 2 pi), the entries in the order of the exercise's old sentence: each told what it is, not 'index the
    last axis'."""
    assert check_measure_function(_h_vectorised).correct
    fb = check_measure_function(fn)
    assert not fb.correct and hint in fb.message and "index the last axis" not in fb.message, fb.message


def test_09_3_reversed_ranks_name_the_windows():
    from kfcal_helpers.coop.exercises import check_obs_rank

    right = [int(r) for r in np.round(np.asarray([2, 3]))]
    assert check_obs_rank(right).correct
    fb = check_obs_rank(right[::-1])
    assert not fb.correct and "window of m = 1 step" in fb.message and "band" not in fb.message
