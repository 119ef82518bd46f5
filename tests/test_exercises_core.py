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


def test_only_a_rounding_is_told_it_is_rounded():
    right, off = 1.00004, 1.0008   # a mistake 8e-4 from the right value
    ex = Exercise("99.4", praise="right", hint="generic", hints={"count": "count the steps again"})
    assert ex.judge(1.001, right, [(off, "count")]).message == "count the steps again"  # the mistake, 3 decimals
    assert ex.judge(1.0, right, [(off, "count")]).message == ROUNDED_HINT                 # the right value, 4 decimals
    assert ex.judge(1.0007, right, [(off, "count")]).message == "generic"                 # near both, a rounding of neither
    # a rounding of the right value AND of a mistake: at that precision nobody can tell, so not the mistake's hint
    assert ex.judge(1.000, right, [(1.00012, "count")]).message == ROUNDED_HINT
    # truncated digits count as rounded; one more digit off does not
    assert ex.judge(0.1032, 0.103283).message == ROUNDED_HINT
    assert ex.judge(0.1034, 0.103283).message == "generic"


def test_closeness_is_per_component_not_relative_to_the_largest_entry():
    right = np.array([40.123456, 2.123456, -30.2468])   # m, rad, m
    for small_physical_error in ([0.0, 0.035, 0.0], [0.03, 0.0, 0.0], [0.0, 0.0, -0.012]):
        fb = EX.judge(right + small_physical_error, right)
        assert fb.message == "generic", (small_physical_error, str(fb))
    # near a mistake's value but not a rounding of it: the generic hint, not that mistake's
    sinc = right + [0.0, 0.0, 0.02]
    assert EX.judge(right + [0.0, 0.035, 0.02], right, [(sinc, "sign")]).message == "generic"
    assert EX.judge(np.round(right, 2), right).message == ROUNDED_HINT
    assert EX.judge([float(f"{x:.5g}") for x in right], right).message == ROUNDED_HINT


def test_a_matrix_rounded_to_fixed_decimals_counts_as_close():
    K = np.array([[0.0975, 1.2e-4], [3.3e-3, 0.91], [-7.1e-8, 2.5e-5]])
    fb = EX.judge(np.round(K, 4), K)  # small entries lose all their digits, the matrix is still close
    assert not fb.correct and fb.message == ROUNDED_HINT


# --------------------------------------------------------------------------------------------
# every check of both problems survives any answer: one line, never praise, no exception, no warning
# --------------------------------------------------------------------------------------------
def _all_checks():
    import kfcal_helpers.calibration.exercises as cal
    import kfcal_helpers.coop.exercises as coop
    import kfcal_helpers.orbit.exercises as orbit

    return [(m.__name__.split(".")[1], name, getattr(m, name)) for m in (cal, coop, orbit) for name in m.__all__
            if name.startswith("check_")]


BAD_ANSWERS = {
    "10**400": 10**400, "[10**400]*3": [10**400] * 3, "1e308": 1e308, "-1e308": -1e308, "[1e308, -1e308]": [1e308, -1e308],
    "nan": float("nan"), "inf": float("inf"), "1+2j": 1 + 2j, "complex array": np.full(3, 1 + 2j),
    "complex (2,2)": np.array([[1 + 1e-3j, 0], [0, 1]]), "abc": "abc", "None": None, "[]": [], "object()": object(),
    "fn 10**400": lambda *a, **k: 10**400, "fn [10**400]": lambda *a, **k: [10**400] * 5,
    "fn 1e308": lambda *a, **k: 1e308, "fn -1e308 array": lambda *a, **k: np.full(5, -1e308),
    "fn 1+2j": lambda *a, **k: 1 + 2j, "fn complex array": lambda *a, **k: np.full((5, 1), 1 + 2j),
    "fn nan": lambda *a, **k: float("nan"), "fn (10**400, 1e308)": lambda *a, **k: (10**400, np.full(7, 1e308)),
    "fn (complex, complex)": lambda *a, **k: (np.ones(3) * 1j, np.eye(3) * 1j), "fn abc": lambda *a, **k: "abc",
    "fn object": lambda *a, **k: object(),
    "fn 1e308 pair (7,)": lambda *a, **k: (np.full(7, 1e308), np.full(7, -1e308)),
    "fn 1e308 pair (3,), (3, 3)": lambda *a, **k: (np.full(3, 1e308), np.full((3, 3), -1e308)),
    "fn 1e308 (8,)": lambda *a, **k: np.full(8, 1e308), "fn 1e308 (5, 1)": lambda *a, **k: np.full((5, 1), -1e308),
    "fn complex pair (7,)": lambda *a, **k: (np.ones(7), np.ones(7) + 1j),
}


@pytest.mark.parametrize("module, name, check", _all_checks(), ids=lambda v: v if isinstance(v, str) else "")
def test_every_check_answers_any_answer_with_one_line_and_no_warning(module, name, check):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for label, answer in BAD_ANSWERS.items():
            fb = check(answer)
            assert isinstance(fb, Feedback), (name, label)
            text = str(fb)
            assert not fb.correct and "\n" not in text and fb.message, (name, label, text)
            assert text.startswith(f"✘ {fb.exercise} "), (name, label, text)
        # huge, NaN and complex entries in every shape an exercise asks for (so the check's own arithmetic runs)
        for shape in ((2,), (3,), (4,), (5,), (6,), (2, 2), (3, 2), (3, 3), (5, 1), (6, 6), (121,), (151,)):
            for fill in (1e308, -1e308, np.nan, 1 + 2j):
                for answer in (np.full(shape, fill), np.where(np.arange(np.prod(shape)).reshape(shape) % 2, fill, 1.0)):
                    fb = check(answer)
                    assert not fb.correct and "\n" not in str(fb) and fb.message, (name, shape, fill, str(fb))


def test_non_numbers_get_their_own_hint():
    for answer, words in ((10**400, "too large"), ([1.0, 10**400], "too large"), (1 + 2j, "complex"),
                          (np.array([1.0, 2.0]) + 0j, "complex"), (float("nan"), "NaN"), ([np.inf, 1.0], "NaN or inf"),
                          ("abc", "expected numbers"), (object(), "expected numbers"), ([[1, 2], [3]], "expected numbers"),
                          (lambda: 1.0, "expected numbers")):
        fb = EX.judge(answer, 2.0 if np.isscalar(answer) or callable(answer) else [1.0, 2.0])
        assert not fb.correct and fb.answered and words in fb.message, (answer, str(fb))
    assert EX.judge(1e308, 2.0).message == "generic"
    assert not EX.judge(2.0 + 0j, 2.0).correct  # a complex answer is never right, even with a zero imaginary part
    for out, words in ((10**400, "too large"), (1 + 2j, "complex"), ((np.ones(2), np.nan), "NaN")):
        outs, fb = call_student("99.5", lambda x, out=out: out, [(1.0,)])
        assert outs is None and words in fb.message, str(fb)


def test_a_placeholder_left_in_one_entry_is_named():
    for answer in ([1.0, None], [..., 2.0]):
        fb = EX.judge(answer, [1.0, 2.0])
        assert not fb.correct and fb.answered and "placeholder" in fb.message, str(fb)


def test_assert_correct_prints_on_success_and_raises_the_hint_otherwise(capsys):
    right, wrong, unanswered = EX.judge(2.0, 2.0), EX.judge(-2.0, 2.0, [(-2.0, "sign")]), EX.judge(..., 2.0)
    assert right.assert_correct() is None
    out = capsys.readouterr()
    assert out.out == f"{right}\n" and out.err == ""   # stderr would cost credit in nbgrader
    for fb in (wrong, unanswered):
        with pytest.raises(AssertionError) as info:
            fb.assert_correct()
        assert str(info.value) == str(fb) and fb.message in str(info.value)
    assert "check the sign" in str(EX.judge(-2.0, 2.0, [(-2.0, "sign")]))
    assert capsys.readouterr().err == ""


# --------------------------------------------------------------------------------------------
# slips every judged answer is checked for, and shape hints that never reveal the size (issue 32)
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("factor", [10.0, 100.0, 1000.0, 0.1, 0.01, 0.001])
def test_a_units_slip_is_named_by_its_factor(factor):
    right = np.array([0.7, -2.5, 3.25])
    fb = EX.judge(right * factor, right)
    assert not fb.correct and fb.message.startswith(f"your answer is {factor:g} times the right one"), str(fb)


def test_reversed_transposed_and_degrees_are_named():
    band = np.array([0.61, 1.52])
    assert "reverse order" in EX.judge(band[::-1], band).message
    M = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.5]])
    assert "transposed" in EX.judge(M.T, M).message
    angles = Exercise("99.6", praise="right", angles=(1,))
    assert "in degrees" in angles.judge([2.0, np.degrees(0.4)], [2.0, 0.4]).message
    assert "in degrees" not in EX.judge([2.0, np.degrees(0.4)], [2.0, 0.4]).message  # not an angle: no such hint
    # a listed mistake wins over a slip
    assert EX.judge(-band, band, [(-band, "sign")]).message == "check the sign"


def test_shape_hints_diagnose_transposition_and_never_reveal_the_size():
    from kfcal_helpers.exercises import shape_hint

    assert "transposed" in shape_hint((5, 3), (3, 5))
    for got in ((120,), (122,), (3, 40)):
        text = shape_hint(got, (121,))
        assert "121" not in text and "not the shape the exercise asks for" in text, text
    assert "a matrix" in shape_hint((9,), (3, 3)) and "(3, 3)" not in shape_hint((9,), (3, 3))


def test_an_answer_that_is_not_numbers_is_not_told_the_size():
    from kfcal_helpers.exercises import judge

    for bad in ("abc", {"a": 1}):
        fb = judge("99.5", bad, np.arange(121.0))
        assert fb.message == f"expected numbers (a vector (a 1-D array)), got {type(bad).__name__}", str(fb)
    assert "121" not in str(judge("99.5", "abc", np.arange(121.0)))


def test_component_hint_names_one_or_two_entries():
    ex = Exercise("99.7", praise="right", hint="generic", components=("x", "y", "heading"))
    assert ex.judge([1.0, 2.0, 3.035], [1.0, 2.0, 3.0]).message.startswith("only heading is off")
    assert ex.judge([1.03, 2.03, 3.0], [1.0, 2.0, 3.0]).message.startswith("only x and y are off")
    assert ex.judge([1.03, 2.03, 3.03], [1.0, 2.0, 3.0]).message == "generic"   # all off: the method hint


def test_call_student_gives_copies_and_names_a_changed_input():
    data = np.arange(3.0)

    def appends(xs, values):
        xs.append(1.0)
        return values.sum()

    outs, fb = call_student("99.8", appends, [([], data)])
    assert outs is None and fb.message.startswith("don't modify your inputs: your function changed xs;")
    outs, fb = call_student("99.8", lambda v: v.sum(), [(data,)])
    assert fb is None and outs == [3.0]
    seen = []
    call_student("99.8", lambda v: seen.append(v) or 1.0, [(data,)])
    assert seen[0] is not data and np.array_equal(seen[0], data)   # a deep copy, never the check's own array


def test_a_functions_outputs_get_the_slips_of_a_judged_answer():
    from kfcal_helpers.exercises import output_slip_hint

    p, v = np.array([1.0, 2.5, 4.0]), np.array([2.0, 3.0, -1.0])
    assert output_slip_hint([p * 100, v], [p, v], ("p", "v")).startswith("your function's p is 100 times the right one")
    assert output_slip_hint([p, v / 1000], [p, v], ("p", "v")).startswith("your function's v is 0.001 times")
    assert "reverse order" in output_slip_hint([p[::-1], v], [p, v], ("p", "v"))
    assert output_slip_hint([p * 100, v + 1], [p, v], ("p", "v")) is None     # one output slipped, one wrong: no slip
    assert output_slip_hint([p, v], [p, v], ("p", "v")) is None
    stack = np.array([[0.5, 10.0], [-2.0, 20.0]])                               # two test cases of [angle, range]
    deg = stack * [180 / np.pi, 1.0]
    assert "in degrees" in output_slip_hint([deg], [stack], ("result",), angles=(0,))
    assert output_slip_hint([stack + [0.0, 1.0]], [stack], ("result",), components=[("the angle", "the range")]) \
        .startswith("only the range is off")


def test_components_of_a_stack_are_named_by_column_and_a_swap_is_called_swapped():
    ex = Exercise("99.9", praise="right", hint="generic", components=("a", "b", "c"))
    right = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    assert ex.judge(right + [0.0, 0.0, 0.5], right).message.startswith("only c is off")   # off in both rows: named once
    assert ex.judge(right[:, [0, 2, 1]], right).message.startswith("b and c are swapped")
    assert ex.judge(right + 0.5, right).message == "generic"
    # the wrong entries' slip is said: a units factor, or degrees where they are angles
    assert ex.judge(right * [1, 100, 1], right).message.startswith("only b is off, the rest is right: it is 100 times")
    angles = Exercise("99.9", praise="right", hint="generic", components=("a", "b", "c"), angles=(0, 1))
    assert angles.judge(right * [180 / np.pi, 180 / np.pi, 1], right).message.startswith("your answer is in degrees")
    assert "only a is off, the rest is right: it is in degrees" in angles.judge(right * [180 / np.pi, 1, 1], right).message
    assert "degrees" not in ex.judge(right * [180 / np.pi, 1, 1], right).message   # not an angle
