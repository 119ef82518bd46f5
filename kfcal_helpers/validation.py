"""Argument checks shared by every public function.

Each check raises ``ValueError`` whose message names the argument and what is
allowed, so a student sees at once which input was wrong.  The command line
turns these errors into one line on stderr and exit status 2.

A public function lists its checks in one place, the :func:`checked` decorator above it::

    @checked(x=partial(require_finite_array, shape=(..., 6)), dt=require_positive)
    def step(x, u, dt=0.1): ...
"""

from __future__ import annotations

import functools
import inspect
import math
import os
from collections.abc import Hashable, Iterable
from numbers import Integral, Real

import numpy as np

__all__ = [
    "check_every_option",
    "require_finite",
    "require_positive",
    "require_int",
    "require_choice",
    "require_shape",
    "require_array",
    "require_finite_array",
    "require_bool",
    "require_text",
    "require_mapping",
    "require_sequence",
    "require_nonnegative",
    "require_path",
    "require_stream",
    "require_iterable",
    "describe",
    "checked",
    "optional",
    "require_covariance",
    "require_seed",
    "require_instance",
    "require_probability",
    "require_significance",
    "MIN_ALPHA",
    "MIN_BAND_ALPHA",
    "MAX_COUNT",
    "require_mask",
    "as_generator",
    "require_seed_or_generator",
    "require_workers",
    "cli_int",
    "cli_float",
]

#: the smallest significance level a user may ask for (``alpha`` of a Monte Carlo, a log summary, the CLI's
#: ``--alpha``).  Every band is a two-sided quantile ``ppf(1 - a/2)``, finite only while ``a/2`` is above
#: the float spacing below 1 (1.1e-16).  A simultaneous (Bonferroni) band splits ``alpha`` over its
#: entries; an accepted run keeps fewer than 500e6 / 8 = 6.25e7 float64 entries (the memory limit), so
#: every split level stays at or above ``MIN_ALPHA / 1e8 = MIN_BAND_ALPHA``.
MIN_ALPHA = 1e-6
#: the smallest per-entry significance a band computation takes (``chi2_bounds``): ``1 - a/2`` then
#: still differs from 1 by about 45 float spacings, so the quantiles are finite
MIN_BAND_ALPHA = 1e-14

#: the largest count of realizations a Monte Carlo takes before its estimate refuses it (with the hours
#: and megabytes it would need); beyond it an int has no float to estimate with (10**400 does not fit)
MAX_COUNT = 10**300

#: the largest seed accepted (numpy.random.default_rng takes any integer >= 0; 2**63 - 1 keeps it an int64)
MAX_SEED = 2**63 - 1


def describe(value) -> str:
    """``value`` for a one-line message: its repr when short, else its type (and an array's shape)."""
    text = repr(value)
    if len(text) <= 60 and "\n" not in text:
        return text
    if isinstance(value, np.ndarray):
        return f"an array of shape {value.shape}"
    if isinstance(value, int):
        return f"an int of {len(str(abs(value)))} digits"
    return f"a {type(value).__name__}"


def checked(**checks):
    """Decorator: before ``fn`` runs, each argument named in ``checks`` that the caller passed goes through
    its check, ``check(name, value) -> value`` (a ``require_*`` of this module, or one made with
    :func:`functools.partial` or :func:`optional`), and ``fn`` receives what the check returns.  Defaults are
    not checked.  The one place a public function lists what its arguments must be::

        @checked(x=require_state, dt=require_positive, n=partial(require_int, minimum=1))
        def step(x, dt=0.1, n=1): ...
    """
    def decorate(fn):
        params = inspect.signature(fn).parameters
        unknown = sorted(set(checks) - set(params))
        if unknown:
            raise TypeError(f"checked: {fn.__qualname__} has no argument {', '.join(unknown)}")
        positional = {p.name: i for i, p in enumerate(params.values())
                      if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)}
        order = [(name, check, positional.get(name)) for name, check in checks.items()]

        @functools.wraps(fn)
        def wrapper(*args, **kwargs):
            if args and any(i is not None and i < len(args) for _, _, i in order):
                args = list(args)
            for name, check, i in order:
                if i is not None and i < len(args):
                    args[i] = check(name, args[i])
                elif name in kwargs:
                    kwargs[name] = check(name, kwargs[name])
            return fn(*args, **kwargs)

        return wrapper
    return decorate


def optional(check):
    """``check`` that lets ``None`` through (for an argument whose default is None)."""
    def check_or_none(name, value):
        return None if value is None else check(name, value)
    return check_or_none


def require_finite_array(name: str, value, shape: tuple | None = None, allow_nan: bool = False) -> np.ndarray:
    """Return ``value`` as a float ndarray of finite numbers (or NaN, a missing value, when ``allow_nan``);
    raise naming ``name`` unless it is one, of ``shape`` when given (``None`` for an axis of any length; a
    leading ``...`` for any leading axes)."""
    arr = require_array(name, value)
    if shape is not None:
        tail = shape[1:] if shape and shape[0] is Ellipsis else shape
        ok = (arr.ndim >= len(tail) if tail is not shape else arr.ndim == len(shape)) and all(
            s is None or s == n for s, n in zip(tail, arr.shape[arr.ndim - len(tail):]))
        if not ok:
            want = ", ".join("..." if s is Ellipsis else "any" if s is None else str(s) for s in shape)
            raise ValueError(f"{name} must have shape ({want}{',' if len(shape) == 1 else ''}), got {arr.shape}")
    if not np.all(np.isfinite(arr) | np.isnan(arr) if allow_nan else np.isfinite(arr)):
        raise ValueError(f"{name} must hold only finite numbers{' or NaN' if allow_nan else ''}")
    return arr


def require_bool(name: str, value) -> bool:
    """Return ``value``; raise unless it is True or False."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False, got {describe(value)}")
    return bool(value)


def require_text(name: str, value) -> str:
    """Return ``value``; raise unless it is a str."""
    if not isinstance(value, str):
        raise ValueError(f"{name} must be a text (str), got {describe(value)}")
    return value


def require_mapping(name: str, value) -> dict:
    """Return ``value``; raise unless it is a non-empty dict."""
    if not isinstance(value, dict) or not value:
        raise ValueError(f"{name} must be a non-empty dict, got {describe(value)}")
    return value


def require_sequence(name: str, value) -> list:
    """Return ``value``'s items as a list; raise unless it is a list, a tuple or an array of at least one
    axis (text, a number, None or a mapping is not)."""
    if not isinstance(value, (list, tuple, np.ndarray)) or (isinstance(value, np.ndarray) and value.ndim == 0):
        raise ValueError(f"{name} must be a sequence (list, tuple or array), got {describe(value)}")
    return list(value)


def require_path(name: str, value):
    """Return ``value``; raise unless it is a file path: a str, bytes or an ``os.PathLike``."""
    if not isinstance(value, (str, bytes, os.PathLike)):
        raise ValueError(f"{name} must be a path (str or pathlib.Path), got {describe(value)}")
    return value


def require_stream(name: str, value):
    """Return ``value``; raise unless it is a writable text stream (has ``write``, like ``sys.stdout``)."""
    if not callable(getattr(value, "write", None)):
        raise ValueError(f"{name} must be a text stream with a write method (such as sys.stdout), got {describe(value)}")
    return value


def require_iterable(name: str, value):
    """Return ``value``; raise unless it can be iterated over (a list, a range, an array, ...)."""
    if not isinstance(value, Iterable) or (isinstance(value, np.ndarray) and value.ndim == 0):
        raise ValueError(f"{name} must be iterable (a list, a range, an array, ...), got {describe(value)}")
    return value


def require_finite(name: str, value) -> float:
    """Return ``value`` as a float; raise if it is not a finite real number (an int beyond the float
    range, such as 10**400, included)."""
    if isinstance(value, bool) or not isinstance(value, (Real, np.floating, np.integer)):
        raise ValueError(f"{name} must be a finite real number, got {describe(value)}")
    try:
        value = float(value)
    except OverflowError:
        raise ValueError(f"{name} must be a finite real number, got {describe(value)}") from None
    if not math.isfinite(value):
        raise ValueError(f"{name} must be a finite real number, got {describe(value)}")
    return value


def require_nonnegative(name: str, value) -> float:
    """Return ``value`` as a float; raise unless it is finite and >= 0."""
    value = require_finite(name, value)
    if value < 0:
        raise ValueError(f"{name} must be >= 0, got {describe(value)}")
    return value


def require_positive(name: str, value) -> float:
    """Return ``value`` as a float; raise unless it is finite and > 0."""
    value = require_finite(name, value)
    if value <= 0:
        raise ValueError(f"{name} must be > 0, got {describe(value)}")
    return value


def require_int(name: str, value, minimum: int | None = None, maximum: int | None = None) -> int:
    """Return ``value`` as an int; raise unless it is an integer >= ``minimum`` (and <= ``maximum``)."""
    if isinstance(value, bool) or not isinstance(value, (Integral, np.integer)):
        raise ValueError(f"{name} must be an integer, got {describe(value)}")
    value = int(value)
    if minimum is not None and value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {describe(value)}")
    if maximum is not None and value > maximum:
        top = "2**63 - 1" if maximum == MAX_SEED else f"{maximum:.6g}"
        allowed = f"from {minimum} to {top}" if minimum is not None else f"<= {top}"
        raise ValueError(f"{name} must be an integer {allowed}, got {describe(value)}")
    return value


def require_choice(name: str, value, choices) -> str:
    """Return ``value``; raise unless it is one of ``choices``."""
    if isinstance(value, np.ndarray) or not isinstance(value, Hashable) or value not in choices:
        allowed = ", ".join(repr(c) for c in choices)
        raise ValueError(f"{name} must be one of {allowed}, got {describe(value)}")
    return value


def require_array(name: str, value) -> np.ndarray:
    """Return ``value`` as a float ndarray (any shape, NaN allowed); raise naming ``name`` for what is not
    numbers (None, text, an object) or does not fit a float (an int of 10**400)."""
    try:
        if value is None:  # np.asarray(None, dtype=float) would be NaN
            raise TypeError
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be an array of real numbers, got {describe(value)}") from None




def require_shape(name: str, array, shape: tuple) -> np.ndarray:
    """Return ``array`` as a float ndarray; raise unless its shape matches.

    ``shape`` may hold ``None`` for an axis of any length.
    """
    arr = require_array(name, array)
    ok = arr.ndim == len(shape) and all(s is None or s == n for s, n in zip(shape, arr.shape))
    if not ok:
        want = "(" + ", ".join("any" if s is None else str(s) for s in shape) + ")"
        raise ValueError(f"{name} must have shape {want}, got {arr.shape}")
    return arr


def require_covariance(name: str, matrix, n: int | None = None, max_variance: float | None = None) -> np.ndarray:
    """Return ``matrix`` as a float array; raise unless it is a finite, symmetric,
    positive-definite square matrix (of size ``n`` when given), whose variances (diagonal) are at most
    ``max_variance`` when given."""
    arr = require_array(name, matrix)
    if arr.ndim != 2 or arr.shape[0] != arr.shape[1] or (n is not None and arr.shape[0] != n):
        size = f"{n}x{n}" if n is not None else "square"
        raise ValueError(f"{name} must be a {size} matrix, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must hold only finite numbers")
    if not np.allclose(arr, arr.T, rtol=1e-10, atol=1e-12 * max(1.0, float(np.abs(arr).max()))):
        raise ValueError(f"{name} must be symmetric")
    if max_variance is not None and np.diag(arr).max() > max_variance:
        raise ValueError(f"{name} variances must be at most {max_variance:g} (a standard deviation of "
                         f"{math.sqrt(max_variance):g}), got {np.diag(arr).max():.3g}")
    try:
        np.linalg.cholesky(arr)
    except np.linalg.LinAlgError:
        raise ValueError(f"{name} must be positive definite") from None
    return arr


def require_seed(name: str, value, allow_none: bool = True):
    """Return ``value`` (an int, or None when ``allow_none``); raise unless it is an integer in
    [0, 2**63 - 1], the seeds of ``numpy.random.default_rng`` this package accepts."""
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, (Integral, np.integer)) or not 0 <= value <= MAX_SEED:
        none = "None or " if allow_none else ""
        raise ValueError(f"{name} must be {none}an integer in [0, 2**63 - 1], got {describe(value)}")
    return int(value)


def require_instance(name: str, value, cls, allow_none: bool = False):
    """Return ``value``; raise unless it is an instance of ``cls`` (or None when ``allow_none``),
    naming the type that was given: ``params must be a CalibrationParams, got dict``."""
    if value is None and allow_none:
        return None
    if not isinstance(value, cls):
        none = " or None" if allow_none else ""
        raise ValueError(f"{name} must be a {cls.__name__}{none}, got {type(value).__name__}")
    return value


def require_probability(name: str, value, closed_upper: bool = False) -> float:
    """Return ``value`` as a float; raise unless it is a real number in (0, 1) (in (0, 1] when
    ``closed_upper``), e.g. a significance level ``alpha``."""
    upper = "]" if closed_upper else ")"
    ok = isinstance(value, (Real, np.floating, np.integer)) and not isinstance(value, bool)
    if ok:
        v = float(value) if abs(value) < 2.0 else 2.0  # (an int of 10**400 has no float)
        ok = math.isfinite(v) and 0.0 < v and (v <= 1.0 if closed_upper else v < 1.0)
    if not ok:
        raise ValueError(f"{name} must be a number in (0, 1{upper}, got {describe(value)}")
    return v


def require_significance(name: str, value, minimum: float = MIN_ALPHA) -> float:
    """Return ``value`` as a float; raise unless it is a significance level in [``minimum``, 1).

    ``minimum`` defaults to :data:`MIN_ALPHA` (1e-6), the limit for the levels users pass: with it every
    band derived from ``alpha``, the Bonferroni-split ones included, stays finite (see :data:`MIN_ALPHA`).
    Band computations that receive an already split level pass :data:`MIN_BAND_ALPHA` (1e-14)."""
    ok = isinstance(value, (Real, np.floating, np.integer)) and not isinstance(value, bool)
    if ok:
        v = float(value) if abs(value) < 2.0 else 2.0  # (an int of 10**400 has no float)
        ok = math.isfinite(v) and minimum <= v < 1.0
    if not ok:
        raise ValueError(f"{name} must be a number in [{minimum:g}, 1) (a significance level), got {describe(value)}")
    return v


def require_mask(name: str, value, size: int, allow_none: bool = True):
    """Return ``value`` as a bool array of shape (size,) (None stays None when ``allow_none``);
    raise unless it is a bool array-like of exactly that shape."""
    if value is None and allow_none:
        return None
    arr = np.asarray(value) if not isinstance(value, (str, bytes)) else np.asarray(None)
    if arr.dtype != bool or arr.shape != (size,):
        none = "None or " if allow_none else ""
        got = f"shape {arr.shape}, dtype {arr.dtype}" if arr.dtype != object else type(value).__name__
        raise ValueError(f"{name} must be {none}a bool array of shape ({size},), got {got}")
    return arr


def require_seed_or_generator(name: str, seed):
    """Return ``seed`` unchanged; raise naming ``name`` unless it is an int in [0, 2**63 - 1] or a
    numpy.random.Generator (what :func:`as_generator` takes)."""
    as_generator(name, seed)
    return seed


#: the most worker threads a caller may ask for
MAX_WORKERS = 1024


def require_workers(name: str, value) -> int:
    """Return ``value``; raise unless it is an integer from 1 to :data:`MAX_WORKERS` (threads)."""
    return require_int(name, value, minimum=1, maximum=MAX_WORKERS)


def as_generator(name: str, seed) -> np.random.Generator:
    """``numpy.random.default_rng(seed)`` for an int seed in [0, 2**63 - 1]; a Generator is returned
    as is (and advanced by the caller's draws).  Raise naming ``name`` otherwise.  The one way this
    package turns "a seed or a Generator" into a Generator."""
    if isinstance(seed, np.random.Generator):
        return seed
    if seed is None or isinstance(seed, bool) or not isinstance(seed, (Integral, np.integer)) \
            or not 0 <= seed <= MAX_SEED:
        raise ValueError(f"{name} must be an integer in [0, 2**63 - 1] or a numpy.random.Generator, got {describe(seed)}")
    return np.random.default_rng(int(seed))


# ---------------------------------------------------------------------------
# argparse ``type=`` functions: the error names the option, e.g. "argument --seed: must be ..."
def cli_int(minimum: int | None = None, maximum: int | None = None):
    """An argparse ``type`` for an integer option in ``[minimum, maximum]`` (either end open if None)."""
    import argparse

    if minimum is not None and maximum is not None:
        allowed = f"an integer from {minimum} to {'2**63 - 1' if maximum == MAX_SEED else maximum}"
    elif minimum is not None:
        allowed = f"an integer >= {minimum}"
    else:
        allowed = "an integer"

    def parse(text: str) -> int:
        try:
            value = int(text.strip().replace("_", ""))
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be {allowed}, got {text!r}") from None
        if (minimum is not None and value < minimum) or (maximum is not None and value > maximum):
            shown = text if len(text) <= 30 else text[:27] + "..."
            raise argparse.ArgumentTypeError(f"must be {allowed}, got {shown}")
        return value

    parse.__name__ = "integer"
    return parse


def cli_float(lower: float | None = None, upper: float | None = None, lower_open: bool = True,
              unit: str = ""):
    """An argparse ``type`` for a finite float option in the interval from ``lower`` (excluded
    when ``lower_open``) to ``upper`` (included); ``unit`` is shown in the message."""
    import argparse

    unit_txt = f" {unit}" if unit else ""
    if lower is not None and upper is not None:
        allowed = f"a number in {'(' if lower_open else '['}{lower:g}, {upper:g}]{unit_txt}"
    elif lower is not None:
        allowed = f"a number {'>' if lower_open else '>='} {lower:g}{unit_txt}"
    else:
        allowed = f"a finite number{unit_txt}"

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be {allowed}, got {text!r}") from None
        bad_low = lower is not None and (value <= lower if lower_open else value < lower)
        bad_high = upper is not None and value > upper
        if not math.isfinite(value) or bad_low or bad_high:
            raise argparse.ArgumentTypeError(f"must be {allowed}, got {text}")
        return value

    parse.__name__ = "number"
    return parse


def check_every_option(every: int, n_steps: int, what: str) -> None:
    """``--every M`` keeps steps 0, M, 2M, ...: it must keep one after step 0 (which has no measurement).
    ValueError naming ``--every``; ``what`` says whose steps ("the log has")."""
    if every > n_steps - 1:
        raise ValueError(f"--every must be at most {n_steps - 1} ({what} {n_steps} steps; every M-th step "
                         f"must keep a measurement after step 0), got {every}")
