"""The machinery every exercise check shares: a one-line verdict and matching against
the right answer and the common wrong ones.

A check function takes the student's answer and returns a :class:`Feedback`, whose
repr is one line, so a notebook check cell shows exactly that line::

    check_phi_10hz(Phi)     # -> ✔ 04.1 correct: ...   or   ✘ 04.1 not yet: <hint>

An answer that is still the placeholder (``None`` or ``...``) gives "not answered yet"
rather than an error, so the student notebooks run top to bottom unchanged.

The one answer-format rule of every exercise (:data:`FORMAT_RULE`): pass the value you computed
(a variable or an expression), with no rounding; the checks compare at full precision.  An answer
that is that value rounded (to some number of decimals or significant figures, within float error)
is told so (:data:`ROUNDED_HINT`); an answer near the right value that is *not* a rounding of it gets
the hint of the mistake it matches, or the exercise's hint: a small physical error is a method error.

Whatever the answer is (a complex number, an integer too large for a float, 1e308, NaN, a string,
an object), a check answers with a one-line hint and lets no exception or warning through:
:func:`judge`, :func:`as_array` and :func:`call_student` screen it (:func:`answer_problem`).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from ._limits import (TIME_LIMIT, TimeLimitExceeded, can_interrupt, changed_input, copies, run_limited, time_limit,
                      time_limit_hint)
from ._slips import ANSWER, component_hint, output_slip_hint, slip_hint

__all__ = ["Feedback", "Exercise", "unanswered", "as_array", "answer_problem", "matches", "is_rounding", "judge",
           "call_student", "answer_shape", "shape_hint", "too_large", "TIME_LIMIT", "MAX_OUTPUT_ENTRIES", "first_line", "chi2_average_bounds", "distinct_mistakes", "GENERIC_HINT", "PLACEHOLDER",
           "PLACEHOLDER_FUNC", "FORMAT_RULE", "BAND_NAMES", "ROUNDED_HINT", "NON_FINITE_HINT"]

#: the answer-format rule of every exercise, stated once (exercise texts and feedback repeat it)
FORMAT_RULE = "pass the value you computed (a variable or an expression), with no rounding"
GENERIC_HINT = "compare your answer with the formula in the notebook, term by term"
#: the entries of a band [lower, upper], for the hint that names the wrong one
BAND_NAMES = ("the lower bound", "the upper bound")
PLACEHOLDER = "replace ... with your answer"
#: the message for an answer that is the expected value rounded (to some decimals or significant figures)
ROUNDED_HINT = f"close, but these digits look rounded: {FORMAT_RULE}; the checks compare at full precision"
PLACEHOLDER_FUNC = "write the body of your function (replace ... with your code), then pass the function to the check"
#: the hint for an answer that holds a NaN or an infinity
NON_FINITE_HINT = "your answer contains NaN or inf: look for a division by zero or an overflow"
#: a student function's output with more entries than this (and than 10 times its test input's) is judged
#: wrong from its shape alone, before any conversion (a broadcast view of 10**8 entries costs no memory
#: until it is converted)
MAX_OUTPUT_ENTRIES = 10**6


@dataclass(frozen=True)
class Feedback:
    """Verdict of one exercise check.

    exercise : the exercise id, "NN.k" (notebook number, exercise number)
    correct : True when the answer is right
    message : one line: what was right, or a hint at the likely mistake
    answered : False while the answer is still the placeholder
    """

    exercise: str
    correct: bool
    message: str
    answered: bool = True

    def __str__(self) -> str:
        mark = "✔" if self.correct else "✘"
        verdict = "correct" if self.correct else ("not answered yet" if not self.answered else "not yet")
        return f"{mark} {self.exercise} {verdict}: {self.message}"

    __repr__ = __str__

    def __bool__(self) -> bool:
        return self.correct

    def assert_correct(self) -> None:
        """For graded notebooks (nbgrader's test cells): print the one line to stdout and return when the
        answer is right; otherwise raise ``AssertionError(str(self))``, so that the hint is the last line of
        the traceback a grader shows.  Nothing is written to stderr."""
        if not self.correct:
            raise AssertionError(str(self))
        print(str(self))


@dataclass(frozen=True)
class Exercise:
    """One exercise's feedback, kept next to its check.

    id : "NN.k" (notebook number, exercise number)
    praise : the line shown with a correct answer (what the answer teaches)
    hint : the hint when the answer is wrong in no recognised way
    hints : ``{mistake key: hint}`` for the common mistakes the check recognises (never the answer)
    components : names of the answer's entries (flattened), or of the entries along its last axis (a
        function's outputs stacked over the test cases), for the hint that names the one or two wrong
        ones ("the heading of the UAV"); empty: no per-component hint
    angles : which entries are angles in radians (indices along the last axis, or True for all), for the
        degree slip
    units : False for an answer without units (indices, counts, ranks, a mask): no units slip is tried
    """

    id: str
    praise: str
    hint: str = GENERIC_HINT
    hints: dict = field(default_factory=dict)
    components: tuple = ()
    angles: object = None
    units: bool = True

    def feedback(self, correct: bool, message: str | None = None, answered: bool = True) -> Feedback:
        """A Feedback of this exercise: ``message`` defaults to the praise (correct) or the hint."""
        if message is None:
            message = self.praise if correct else self.hint
        return Feedback(self.id, correct, message, answered)

    def mistake(self, key: str) -> Feedback:
        """The Feedback for the recognised mistake ``key``."""
        return Feedback(self.id, False, self.hints[key])

    def unanswered(self, placeholder: str = PLACEHOLDER) -> Feedback:
        """The Feedback while the answer is still the placeholder."""
        return Feedback(self.id, False, placeholder, answered=False)

    def judge(self, answer, expected, wrong=(), *, rtol: float = 1e-6, atol: float = 1e-12,
              placeholder: str = PLACEHOLDER, what: str = ANSWER) -> Feedback:
        """:func:`judge` with this exercise's praise and hint; ``wrong`` holds ``(value, mistake key)`` pairs;
        ``what``: what a slip's hint calls the answer ("your function's result" for a function's outputs)."""
        pairs = [(value, self.hints[key]) for value, key in wrong]
        return judge(self.id, answer, expected, pairs, rtol=rtol, atol=atol, praise=self.praise, hint=self.hint,
                     placeholder=placeholder, components=self.components, angles=self.angles, what=what,
                     units=self.units)

    def output_slip(self, outputs, expected, names, *, rtol: float = 1e-9, atol: float = 1e-12,
                    components=None) -> Feedback | None:
        """For a function exercise: the Feedback naming the slip (:func:`output_slip_hint`: ×10, ×100,
        ×1000 and inverses, degrees where this exercise's ``angles`` are radians, reversed, transposed;
        or the one or two wrong ``components``) when the function's ``outputs`` (a sequence of arrays
        called ``names``) are the ``expected`` ones but for it, else None.  A check calls it after its
        listed mistakes, before its own hint."""
        hint = output_slip_hint(outputs, expected, names, rtol=rtol, atol=atol, angles=self.angles,
                                components=components, units=self.units)
        return None if hint is None else Feedback(self.id, False, hint)


def first_line(exc: BaseException, limit: int = 100) -> str:
    """The first line of an exception's message, cut to ``limit`` characters."""
    text = str(exc).strip().splitlines()
    text = text[0] if text else ""
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _screen_function_output(out, depth: int = 0, cap: int = MAX_OUTPUT_ENTRIES) -> str | None:
    """Why a student function's output ``out`` cannot be judged as real finite numbers (one line), or
    None.  Looks into tuples and lists (two levels); leaves non-numeric outputs to the check.  An output
    of more than ``cap`` entries is judged from its shape, before any conversion."""
    size = _cheap_size(out)
    if size is not None and size > cap:
        shape = answer_shape(out)
        return (f"your function returned {'an array of shape ' + str(shape) if shape is not None else 'a result'} "
                f"with {size} entries, far more than the test input calls for: check the shapes of your result")
    if isinstance(out, (tuple, list)) and depth < 2:
        for item in out:
            why = _screen_function_output(item, depth + 1, cap)
            if why is not None:
                return why
        return None
    if isinstance(out, (str, bytes)) or unanswered(out) or callable(out):
        return None
    arr, why = _to_float(out)
    if why is None:
        if np.all(np.isfinite(arr)):
            return None
        return "your function returned NaN or inf on the test input: look for a division by zero or an overflow"
    if why.startswith("your answer is complex"):
        return "your function returned a complex number on the test input: the result is real"
    if "overflow" in why:
        return "your function returned a number too large for a float (overflow) on the test input"
    return None  # not numbers at all: the check says what it expected


def answer_shape(answer) -> tuple | None:
    """The shape of an array answer (an ndarray, a numpy scalar, anything with a tuple of ints as
    ``shape``), read without converting it, or None.  Never raises (but for Ctrl-C)."""
    if isinstance(answer, (np.ndarray, np.generic)):
        return tuple(answer.shape)
    if isinstance(answer, (int, float, complex, str, bytes, list, tuple, dict)) or answer is None:
        return None
    try:
        shape = getattr(answer, "shape", None)
        if isinstance(shape, tuple) and all(isinstance(n, (int, np.integer)) and n >= 0 for n in shape):
            return tuple(int(n) for n in shape)
    except KeyboardInterrupt:
        raise
    except BaseException:  # a student's object whose shape property fails
        pass
    return None


def _cheap_size(answer, depth: int = 0) -> int | None:
    """The number of entries of ``answer`` as far as it can be read without converting anything: an
    array's size, and the sum over a list's or tuple's items (two levels; a long list counts its length,
    its entries already exist in memory).  None when nothing tells."""
    shape = answer_shape(answer)
    if shape is not None:
        return math.prod(shape)
    if isinstance(answer, (list, tuple)) and depth < 2:
        if len(answer) > 10_000:
            return len(answer)
        sizes = [_cheap_size(item, depth + 1) for item in answer]
        return sum(1 if n is None else n for n in sizes)
    return None


def _kind(ndim: int) -> str:
    """What an answer of ``ndim`` dimensions is called in a hint (never its size)."""
    return {0: "a single number", 1: "a vector (a 1-D array)", 2: "a matrix (a 2-D array)"}.get(ndim, f"a {ndim}-D array")


def shape_hint(got, expected, what: str = "your answer") -> str:
    """One line on an answer of shape ``got`` where shape ``expected`` is asked, never revealing the
    expected number of entries: a transposed matrix is called transposed, an answer of the right size in
    another arrangement is told the kind of array asked (number, vector, matrix), any other is told only
    that its shape is not the one asked."""
    got, expected = tuple(got), tuple(expected)
    if len(got) == 2 and len(expected) == 2 and got == expected[::-1] and got != expected:
        return (f"{what} is transposed (shape {got}): rows and columns are swapped; check which quantity runs "
                "along the rows and which along the columns")
    if math.prod(got) == math.prod(expected):
        return (f"{what} has shape {got}: the exercise asks for {_kind(len(expected))} with these entries arranged "
                "differently")
    return f"{what} has shape {got}, not the shape the exercise asks for: check how many entries you computed"


def too_large(answer, *expected) -> str | None:
    """The shape hint (:func:`shape_hint`) when ``answer`` holds more entries than every one of the
    ``expected`` arrays (the right value, the mistakes' values), read before any conversion; else None.
    Call it first: converting a broadcast view of 10**8 entries would allocate gigabytes."""
    size = _cheap_size(answer)
    if size is None or not expected or (answer_shape(answer) is None and size <= MAX_OUTPUT_ENTRIES):
        return None  # a list's entries exist already: converting it is cheap, and judge() says more about it
    shapes = [np.shape(e) for e in expected]
    if size <= max(math.prod(sh) for sh in shapes):
        return None
    got = answer_shape(answer)
    return shape_hint(got if got is not None else (size,), shapes[0])


def _exception_hint(exc: BaseException) -> str:
    """The one-line verdict on an exception raised by the student's code (any BaseException but Ctrl-C)."""
    if isinstance(exc, TimeLimitExceeded):
        return time_limit_hint(time_limit(), can_interrupt())
    if isinstance(exc, SystemExit):
        return ("your function called exit() or sys.exit() (SystemExit) on the test input: a function returns its "
                "result, it never ends the program")
    try:
        text = first_line(exc)
    except KeyboardInterrupt:
        raise
    except BaseException:  # an exception whose message itself fails (with anything, SystemExit included)
        text = ""
    return f"your function raised {type(exc).__name__} on the test input" + (f": {text}" if text else "")


def call_student(exercise: str, func, cases, what: str = "your function", convert=None):
    """Call the student's ``func`` once per argument tuple in ``cases``, safely.

    Returns ``(outputs, None)`` with one output per case, or ``(None, Feedback)`` when the function
    is still the placeholder, is not callable, raises anything but ``KeyboardInterrupt`` (``SystemExit``
    included: the exception's name and first line become the hint), runs past the time limit
    (:data:`TIME_LIMIT`; :func:`~kfcal_helpers.exercises.run_limited`), modifies one of its inputs
    (the hint names it), returns the placeholder (None or ...), or returns numbers that cannot be judged
    (far more entries than the test input calls for, read before any conversion; complex, too large for
    a float, NaN or inf; :func:`answer_problem`).  Each call gets deep copies of the case's arguments, so
    the check's own data never changes.  ``convert`` (optional) maps each argument before the call (e.g.
    ``np.asarray``).  Warnings inside the student's code are silenced: a bad result is judged by the
    check, never shown as a warning.
    """
    if unanswered(func):
        return None, Feedback(exercise, False, PLACEHOLDER_FUNC, answered=False)
    if not callable(func):
        return None, Feedback(exercise, False, f"expected a function {what}, got {type(func).__name__}: "
                                               "pass the function itself, without calling it")
    outs = []
    for args in cases:
        if convert is not None:
            args = tuple(convert(a) for a in args)
        kept, given = copies(args), copies(args)
        cap = max(MAX_OUTPUT_ENTRIES, 10 * sum(_cheap_size(a) or 1 for a in args))
        report = (f"{exercise}: your function has run for more than {time_limit():g} s on a small test input "
                  "and this platform cannot stop it: interrupt the kernel and look for a loop that never ends")
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            out, exc = run_limited(func, given, report=report)
            why = None
            if exc is None:  # the screening converts the output: a student's class may run (and fail) there too
                why, exc = run_limited(lambda o: _screen_function_output(o, cap=cap), (out,))
        if exc is not None:  # a half-written function: name the exception, never crash
            return None, Feedback(exercise, False, _exception_hint(exc))
        name = changed_input(func, kept, given)
        if name is not None:
            return None, Feedback(exercise, False, f"don't modify your inputs: your function changed {name}; work on "
                                                   f"a copy ({name} = {name}.copy()) or build a new array")
        if unanswered(out):
            return None, Feedback(exercise, False, f"your function returns {out!r}: {PLACEHOLDER_FUNC}",
                                  answered=False)
        if why is not None:
            return None, Feedback(exercise, False, why)
        outs.append(out)
    return outs, None


def distinct_mistakes(pairs, expected, rtol: float):
    """The ``(value, key)`` pairs whose value differs from ``expected`` (within ``rtol``): a mistake
    that gives the right answer for these settings is not a mistake."""
    out = []
    for value, key in pairs:
        value = np.asarray(value, dtype=float)
        if value.shape == np.shape(expected) and np.allclose(value, expected, rtol=rtol, atol=0):
            continue
        out.append((value, key))
    return out


def unanswered(answer) -> bool:
    """True for the placeholders ``None`` and ``...`` (Ellipsis)."""
    return answer is None or answer is Ellipsis


def _to_float(answer):
    """``(float ndarray, None)`` or ``(None, reason)``; never raises, never warns, and never converts an
    answer of more than :data:`MAX_OUTPUT_ENTRIES` entries (its size is read first)."""
    if isinstance(answer, (str, bytes)):
        return None, f"expected numbers, got {type(answer).__name__}"
    if callable(answer) and not isinstance(answer, np.ndarray):
        return None, "expected numbers, got a function: pass the value it computes"
    size = _cheap_size(answer)
    if size is not None and size > MAX_OUTPUT_ENTRIES:  # read before converting: a broadcast view costs nothing yet
        return None, f"your answer has {size} entries, far more than the exercise asks for: check its shape"
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        try:
            raw = np.asarray(answer)
        except KeyboardInterrupt:
            raise
        except BaseException:  # ragged nesting and other unconvertible objects (a student's class may raise anything)
            return None, f"expected numbers, got {type(answer).__name__}"
        if np.iscomplexobj(raw) or (raw.dtype == object and any(isinstance(v, complex) for v in raw.flat)):
            return None, ("your answer is complex: the answer is real; keep the real part only where the imaginary "
                          "part is zero by construction")
        if raw.dtype == object and any(v is None or v is Ellipsis for v in raw.flat):
            return None, "your answer still holds None or ...: replace every placeholder with a number"
        if raw.dtype.kind in "USVMm" or (raw.dtype == object and any(isinstance(v, (str, bytes)) for v in raw.flat)):
            return None, f"expected numbers, got {type(answer).__name__}"
        try:
            arr = raw.astype(float)
        except OverflowError:
            return None, "your answer holds a number too large for a float (overflow): " + FORMAT_RULE
        except KeyboardInterrupt:
            raise
        except BaseException:
            return None, f"expected numbers, got {type(answer).__name__}"
    return arr, None


def answer_problem(answer) -> str | None:
    """Why ``answer`` cannot be judged as real finite numbers, as one line, or None when it can.

    Catches strings, functions, objects, ragged lists, complex numbers (never silently dropping the
    imaginary part), integers too large for a float (``10**400``) and NaN or inf; finite huge values
    such as 1e308 are numbers (judged wrong by comparison, without a warning)."""
    arr, why = _to_float(answer)
    if why is not None:
        return why
    if not np.all(np.isfinite(arr)):
        return NON_FINITE_HINT
    return None


def as_array(answer):
    """``answer`` as a float ndarray, or None when it cannot be one (a string, a function, ragged lists,
    a complex number, an integer too large for a float...).  NaN and inf stay (the check judges them).
    Never raises, never warns."""
    return _to_float(answer)[0]


def matches(answer, expected, rtol: float = 1e-6, atol: float = 1e-12) -> bool:
    """True when ``answer`` has the shape of ``expected`` (after squeezing) and equals it
    within ``rtol``/``atol`` entry by entry; never raises or warns for a malformed answer."""
    a, e = as_array(answer), np.asarray(expected, dtype=float)
    if a is None or a.size != e.size:
        return False
    a = a.reshape(e.shape)
    with np.errstate(all="ignore"):
        return bool(np.all(np.isfinite(a)) and np.allclose(a, e, rtol=rtol, atol=atol))


def _entry_is_rounding(a: float, v: float, q: float) -> bool:
    """True when ``a`` is ``v`` rounded (or cut) to a multiple of the quantum ``q`` (a power of ten),
    within float error."""
    d = v - a
    slack = q * 1e-6
    if not abs(d) < q + slack:
        return False  # farther than one quantum (or not finite)
    k = a / q
    if abs(k - round(k)) > 1e-6 + 1e-12 * abs(k):
        return False  # a holds digits below q
    if abs(d) <= 0.5 * q + slack:
        return True  # rounded to nearest (either way at a tie)
    return abs(d) < q - slack and abs(a) <= abs(v) and (a == 0 or math.copysign(1, a) == math.copysign(1, v))  # cut


def is_rounding(answer, value, min_figures: int = 2) -> bool:
    """True when ``answer`` is ``value`` rounded, as a printout or a hand copy rounds it: every entry
    rounded (or cut) to a common number of decimals, or each entry to its own number of significant
    figures; at least ``min_figures`` significant figures of the largest entry (of each entry, for
    significant figures) are kept.  An entry equal to the value's (to 1e-12) fits any rounding.
    False when the shapes differ or anything is not finite.  Never raises or warns."""
    a, v = as_array(answer), np.asarray(value, dtype=float).ravel()
    if a is None or a.size != v.size or v.size == 0:
        return False
    a = a.ravel()
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(v))):
        return False
    with np.errstate(all="ignore"):
        exact = np.abs(a - v) <= 1e-12 * np.maximum(np.abs(v), np.abs(a))
        if np.all(exact):
            return False  # not rounded: equal
        top = float(np.max(np.abs(v)))
        if top == 0.0 or top > 1e300:
            return False
        e_top = math.floor(math.log10(top))
        own = np.zeros(v.size, bool)  # each entry rounded to >= min_figures significant figures of its own
        for i, (ai, vi) in enumerate(zip(a, v)):
            if exact[i] or vi == 0.0:
                own[i] = exact[i]
                continue
            e = math.floor(math.log10(abs(vi)))
            own[i] = any(_entry_is_rounding(ai, vi, 10.0 ** (e - s + 1)) for s in range(min_figures, 16))
        if np.all(own):
            return True
        for k in range(e_top - min_figures + 1, e_top - 15, -1):  # a common number of decimals
            q = 10.0 ** k
            if all(exact[i] or own[i] or _entry_is_rounding(ai, vi, q) for i, (ai, vi) in enumerate(zip(a, v))):
                return True
    return False


def _distance(a: np.ndarray, v: np.ndarray) -> float:
    """Largest relative difference entry by entry (each entry in its own scale)."""
    with np.errstate(all="ignore"):
        scale = np.maximum(np.abs(a), np.abs(v))
        d = np.where(scale > 0, np.abs(a - v) / np.where(scale > 0, scale, 1.0), 0.0)
    return float(np.max(d))


def judge(exercise: str, answer, expected, wrong=(), *, rtol: float = 1e-6, atol: float = 1e-12,
          praise: str = "well done", hint: str = GENERIC_HINT, placeholder: str = "replace ... with your answer",
          components=(), angles=None, slips: bool = True, what: str = ANSWER, units: bool = True) -> Feedback:
    """The verdict on ``answer`` against ``expected`` and the common mistakes.

    wrong : sequence of ``(value, hint)`` pairs: the value a common mistake gives and the
        hint that points at that mistake (never the answer itself)
    hint : the hint when the answer is neither right nor a known mistake
    Closeness is entry by entry (``rtol`` relative to each entry, plus ``atol``).  An answer that
    cannot be judged as real finite numbers (:func:`answer_problem`) or has another shape gets its own
    hint.  An answer that is a rounding of the expected value (:func:`is_rounding`) gets
    :data:`ROUNDED_HINT`, also when it is a rounding of a mistake's value too (at that precision
    nobody can tell them apart); a rounding of a mistake's value only gets that mistake's hint.  An
    answer that is none of these but the right one with a slip (:mod:`~kfcal_helpers.exercises._slips`:
    scaled by a power of ten, in degrees where ``angles`` are radians, reversed, transposed) gets that
    slip's hint, calling the answer ``what`` (``slips=False``: not tried; ``units=False``: no units slip); one right in all but one or two
    entries gets a hint naming them by ``components`` (one name per entry, or per entry of the last axis
    of a stack of a function's outputs).  An answer larger than every expected value is judged from its shape alone,
    before any conversion (:func:`too_large`).
    """
    if unanswered(answer):
        return Feedback(exercise, False, placeholder, answered=False)
    e = np.asarray(expected, dtype=float)
    big = too_large(answer, e, *(value for value, _ in wrong))
    if big is not None:
        return Feedback(exercise, False, big)
    a, why = _to_float(answer)
    if why is not None:
        if why.startswith("expected numbers"):
            why = f"expected numbers ({_kind(e.ndim)}), got {type(answer).__name__}"   # never the size
        return Feedback(exercise, False, why)
    if not np.all(np.isfinite(a)):
        return Feedback(exercise, False, NON_FINITE_HINT)
    if matches(a, e, rtol, atol):
        return Feedback(exercise, True, praise)
    rounded_right = is_rounding(a, e)
    for value, why in wrong:  # a mistake may have another shape (one entry missing...)
        if matches(a, value, rtol, atol) and not (rounded_right and not matches(a, value, 1e-12, 0.0)):
            return Feedback(exercise, False, why)
    if a.size != e.size:
        return Feedback(exercise, False, shape_hint(a.shape, e.shape))
    if rounded_right:
        return Feedback(exercise, False, ROUNDED_HINT)
    near = [(_distance(a.ravel(), np.asarray(v, dtype=float).ravel()), why) for v, why in wrong if is_rounding(a, v)]
    if near:
        return Feedback(exercise, False, min(near, key=lambda t: t[0])[1])
    slip = slip_hint(a, e, rtol=rtol, atol=atol, angles=angles, what=what, scales=units) if slips else None
    if slip is None and components:
        slip = component_hint(a, e, components, rtol=rtol, atol=atol, angles=angles, units=units)
    return Feedback(exercise, False, slip if slip is not None else hint)


def chi2_average_bounds(dim: int, n: int, alpha: float, *, dof: int | None = None, divide_by: float | None = None,
                        one_sided: bool = False) -> np.ndarray:
    """``[lower, upper]`` of the average of ``n`` chi-square(``dim``) variables at level ``alpha``:
    ``chi2.ppf((alpha/2, 1 - alpha/2), dim n) / n`` (as :func:`kfcal_helpers.consistency.chi2_bounds`).

    The keywords build the common wrong answers the checks recognise: ``dof`` (other degrees of
    freedom), ``divide_by`` (another divisor; 1 = not divided), ``one_sided`` (quantiles
    ``alpha`` and ``1 - alpha``).
    """
    dof = dim * n if dof is None else dof
    lo, hi = (alpha, 1 - alpha) if one_sided else (alpha / 2, 1 - alpha / 2)
    return np.array([stats.chi2.ppf(lo, dof), stats.chi2.ppf(hi, dof)]) / (n if divide_by is None else divide_by)
