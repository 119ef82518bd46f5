"""The shared exercise harness: Exercise records, judge's tolerance for rounded copies, call_student."""

import numpy as np
import pytest

from kfcal_helpers.exercises import (ROUNDED_HINT, Exercise, Feedback, call_student, distinct_mistakes, judge)

EX = Exercise("99.1", praise="right", hint="generic", hints={"sign": "check the sign"})


def test_exact_right_and_known_mistake():
    assert EX.judge(2.0, 2.0) == Feedback("99.1", True, "right")
    assert EX.judge(-2.0, 2.0, [(-2.0, "sign")]).message == "check the sign"
    assert EX.judge(3.0, 2.0, [(-2.0, "sign")]).message == "generic"
    assert not EX.judge(..., 2.0).answered


def test_a_rounded_copy_of_the_right_value_is_told_so_not_given_a_method_hint():
    right = np.array([0.103283, 0.0089443])
    rounded = np.array([float(f"{x:.4g}") for x in right])  # 4 significant digits: off by up to 5e-4 relative
    fb = EX.judge(rounded, right)
    assert not fb.correct and fb.message == ROUNDED_HINT
    assert EX.judge(right * (1 + 2e-3), right).message == "generic"  # farther than 1e-3: not a rounding
    # a rounded copy of a known mistake's value gets that mistake's hint
    assert EX.judge(-rounded, right, [(-right, "sign")]).message == "check the sign"
    # a check that already accepts 1e-3 has no separate "rounded" band
    assert judge("99.2", 1.0005, 1.0, rtol=1e-3).correct


def test_call_student_never_raises():
    outs, fb = call_student("99.3", lambda x: x + 1, [(1,), (2,)])
    assert outs == [2, 3] and fb is None
    outs, fb = call_student("99.3", lambda x: 1 / 0, [(1,)])
    assert outs is None and "ZeroDivisionError" in fb.message
    assert call_student("99.3", ..., [(1,)])[1].answered is False
    assert "pass the function itself" in call_student("99.3", 3.0, [(1,)])[1].message
    assert call_student("99.3", lambda x: None, [(1,)])[1].answered is False


def test_distinct_mistakes_drops_mistakes_equal_to_the_answer():
    pairs = [(1.0, "same"), (2.0, "other")]
    assert [k for _, k in distinct_mistakes(pairs, 1.0, 1e-9)] == ["other"]


def test_unknown_mistake_key_is_a_programming_error():
    with pytest.raises(KeyError):
        EX.judge(1.0, 2.0, [(1.0, "nope")])


def test_the_nearest_of_right_value_and_mistakes_decides_for_a_rounded_answer():
    right, off_by_one = 1.0, 1.0008   # a mistake within 1e-3 of the right value
    ex = Exercise("99.4", praise="right", hint="generic", hints={"count": "count the steps again"})
    assert ex.judge(1.0007, right, [(off_by_one, "count")]).message == "count the steps again"
    assert ex.judge(1.0001, right, [(off_by_one, "count")]).message == ROUNDED_HINT


def test_a_matrix_rounded_to_fixed_decimals_counts_as_close():
    K = np.array([[0.0975, 1.2e-4], [3.3e-3, 0.91], [-7.1e-8, 2.5e-5]])
    fb = EX.judge(np.round(K, 4), K)  # small entries lose all their digits, the matrix is still close
    assert not fb.correct and fb.message == ROUNDED_HINT
