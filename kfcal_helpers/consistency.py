"""Consistency statistics shared by both problems: NEES, NIS and their chi-square bounds.

With N Monte Carlo runs and a statistic of dimension n, the run-averaged NEES
(or NIS) of a consistent filter is chi-square with N*n degrees of freedom,
divided by N.  The two-sided acceptance region at significance ``alpha`` is
``[chi2.ppf(alpha/2, N*n)/N, chi2.ppf(1 - alpha/2, N*n)/N]``.

The same formula with N replaced by the number of time steps K bounds the time average of one run's
NIS, and only the NIS: the innovations of a consistent filter are white, so its K NIS values are
independent.  The estimation errors are not: the error at step k+1 carries most of the error at step
k, so one run's K NEES values are correlated and their time average scatters far more than
chi-square(n*K)/K allows.  No time-average band is given for the NEES (a run-averaged NEES at one
step, over independent runs, keeps its band); ``tests/test_consistency.py`` shows both by Monte Carlo.

The sampling bands of Monte Carlo statistics, at per-entry significance ``level`` (two-sided), for
``n`` independent realizations: :func:`t_band` (a mean, with the ensemble standard deviation),
:func:`normal_band` (a mean of terms of known variance), :func:`variance_band` (a variance, chi-square),
:func:`correlation_band` (a centred correlation, Fisher's z), :func:`uncentred_correlation_band` (the
correlation of two zero-mean vectors, Student t) and :func:`chi2_bounds` (an average of chi-square
statistics).  Each takes arrays and returns the half-width or the ``(lower, upper)`` bounds.

The Monte Carlo results of every problem share one interface (:class:`MonteCarloSummary`):
``n_runs``, ``alpha`` and ``checks() -> {name: Check}``, printed by :func:`format_checks`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial
from typing import Protocol, runtime_checkable

import numpy as np
from scipy import stats

from .validation import (MAX_SEED, MIN_BAND_ALPHA, checked, describe, require_array, require_finite_array,
                         require_int, require_significance, require_text)

__all__ = ["chi2_bounds", "chi2_sum_bounds", "step_checks", "t_band", "normal_band", "variance_band", "correlation_band", "uncentred_correlation_band",
           "normalized_squares", "nees", "nis", "inside_fraction", "Check", "MonteCarloSummary", "format_checks"]

#: argument checks (validation.checked): counts that fit an int64, finite arrays of any shape
_COUNT = partial(require_int, minimum=1, maximum=MAX_SEED)
_FINITE = require_finite_array


@checked(dim=_COUNT, n_samples=_COUNT)
def chi2_bounds(dim: int, n_samples: int, alpha: float = 0.05) -> tuple[float, float]:
    """Bounds for the average of ``n_samples`` independent chi-square(dim) variables.

    Parameters
    ----------
    dim : int, >= 1
        Dimension of the state (NEES) or measurement (NIS).
    n_samples : int, >= 1
        Number of independent chi-square terms averaged: Monte Carlo runs (NEES or NIS at one step), or
        the time steps of one run's NIS (its innovations are white; one run's NEES values are not
        independent, so no time average of the NEES has this band).
    alpha : float in [1e-14, 1) (:data:`~kfcal_helpers.validation.MIN_BAND_ALPHA`)
        Significance level of the two-sided test (a Bonferroni-split level included); below the
        limit the upper quantile ``ppf(1 - alpha/2)`` would be infinite.

    Returns
    -------
    (lower, upper) : floats, in the units of the averaged statistic (dimensionless).
    """
    dim = require_int("dim", dim, minimum=1)
    n_samples = require_int("n_samples", n_samples, minimum=1)
    alpha = require_significance("alpha", alpha, minimum=MIN_BAND_ALPHA)
    dof = dim * n_samples
    lower = stats.chi2.ppf(alpha / 2, dof) / n_samples
    upper = stats.chi2.ppf(1 - alpha / 2, dof) / n_samples
    return float(lower), float(upper)


def chi2_sum_bounds(dof, n, alpha: float = 0.05):
    """Two-sided bounds of an average of ``n`` independent chi-square variables whose degrees of freedom
    add up to ``dof``: ``chi2.ppf(alpha/2, dof) / n`` and ``chi2.ppf(1 - alpha/2, dof) / n``, elementwise.

    dof : array of ints >= 1 (e.g. per step, the sum over the runs of the measurement dimension present);
    n : array of ints >= 1 broadcast with ``dof`` (how many variables are averaged); alpha as in
    :func:`chi2_bounds`.  Returns ``(lower, upper)`` arrays (dimensionless).  With a fixed dimension d,
    ``dof = N d`` and ``n = N`` give :func:`chi2_bounds`.
    """
    alpha = require_significance("alpha", alpha, minimum=MIN_BAND_ALPHA)
    dof, n = np.asarray(dof), np.asarray(n)
    for name, v in (("dof", dof), ("n", n)):
        if v.dtype.kind not in "iu" or np.any(v < 1):
            raise ValueError(f"{name} must hold integers >= 1, got {describe(v)}")
    return stats.chi2.ppf(alpha / 2, dof) / n, stats.chi2.ppf(1 - alpha / 2, dof) / n


def _step_dof(name: str, value):
    """``dof`` of :func:`step_checks`: one int >= 1, or a (runs, steps) array of finite numbers."""
    if np.ndim(value) == 0:
        return require_int(name, value, minimum=1, maximum=10**6)
    return require_finite_array(name, value, shape=(None, None))


@checked(nees=partial(require_finite_array, shape=(None, None)),
         nis=partial(require_finite_array, shape=(None, None), allow_nan=True), dof=_step_dof)
def step_checks(nees, nis, dof, n_states: int, alpha: float = 0.05, extra_entries: int = 0) -> dict:
    """Per-step NEES and NIS checks of N runs whose measurement dimension changes from step to step.

    nees : (N, K) NEES of a state of ``n_states`` components; nis : (N, K) NIS, NaN where a run had no
    measurement; dof : (N, K) ints, the NIS's degrees of freedom (the measurement dimension present,
    0 without one), or one int >= 1 when every NIS present has that dimension (then a NaN NIS is what
    marks a run without a measurement).  At step k the run-averaged NEES is chi-square with
    ``N n_states`` dof over N; the NIS averaged over the ``n_k`` runs with a measurement is chi-square
    with ``sum_r dof[r, k]`` dof (the dimensions actually present, which may differ between runs) over
    ``n_k``; a step where no run has a measurement is left out.  The pointwise band is at ``alpha``, the
    simultaneous (Bonferroni) one at ``alpha / (entries of both checks + extra_entries)``
    (``extra_entries``: those of other checks judged with them).

    Returns ``{"nees": Check, "nis": Check}`` (:class:`Check`; ``expected`` is ``n_states`` and the mean
    dof per step).
    """
    fixed = np.ndim(dof) == 0
    if nees.ndim != 2 or nis.shape != nees.shape or not (fixed or dof.shape == nees.shape):
        raise ValueError(f"nees, nis and dof must have the same shape (n_runs, K), got {nees.shape}, {nis.shape}, "
                         f"{np.shape(dof)}")
    n_states = require_int("n_states", n_states, minimum=1, maximum=10**6)
    alpha = require_significance("alpha", alpha)
    extra_entries = require_int("extra_entries", extra_entries, minimum=0, maximum=10**12)
    if fixed:
        present = np.isfinite(nis)
    else:
        if np.any(dof < 0) or np.any(dof != np.round(dof)):
            raise ValueError("dof must hold integers >= 0")
        dof = dof.astype(int)
        present = dof > 0
        if np.any(np.isfinite(nis) != present) or not np.isfinite(nees).all():
            raise ValueError("nis must be finite exactly where dof > 0, and nees finite everywhere")
    n_runs = nees.shape[0]
    count = present.sum(axis=0)
    has = count > 0
    total = dof * count[has] if fixed else dof.sum(axis=0)[has]
    nis_mean = np.where(present, nis, 0.0)[:, has].sum(axis=0) / count[has]
    a_sim = Check.bonferroni(alpha, nees.shape[1] + int(has.sum()) + extra_entries)
    out = {}
    for name, values, d, n, what in (
            ("nees", nees.mean(axis=0), np.full(nees.shape[1], n_states * n_runs), np.full(nees.shape[1], n_runs),
             f"run-averaged NEES per step ({n_states} dof per run)"),
            ("nis", nis_mean, total, count[has], "run-averaged NIS per step (the dof present at each step)")):
        out[name] = Check.from_band(name, what, values, d / n, partial(chi2_sum_bounds, d, n), alpha, a_sim)
    return out


def _level(level) -> float:
    return require_significance("level", level, minimum=MIN_BAND_ALPHA)


def _runs(n, minimum: int = 2, name: str = "n") -> int:
    return require_int(name, n, minimum=minimum, maximum=MAX_SEED)



@checked(sd=_FINITE)
def t_band(sd, n: int, level: float):
    """Half-width of the band of an ensemble mean: ``t_{n-1}(1 - level/2) sd / sqrt(n)``.

    sd : array (any shape), the ensemble standard deviation of the averaged quantity (its units)
    n : int >= 2, realizations averaged; level : per-entry significance in (0, 1).
    Exact for independent Gaussian realizations (``sqrt(n) mean / sd`` is Student t, n - 1 dof).
    Returns an array shaped like ``sd`` (the band is ``[-half, +half]`` around 0).
    """
    n, level = _runs(n), _level(level)
    return stats.t.ppf(1 - level / 2, n - 1) * np.asarray(sd, dtype=float) / np.sqrt(n)


@checked(var=_FINITE)
def normal_band(var, n: int, level: float):
    """Half-width of the band of a mean of ``n`` independent terms of known variance ``var``:
    ``z sqrt(var / n)``, ``z = norm.ppf(1 - level/2)`` (normal approximation).

    var : array, the variance of one term (its units squared); n : int >= 1; level in (0, 1).
    Returns an array shaped like ``var``, in the units of the term.
    """
    n, level = _runs(n, 1), _level(level)
    return stats.norm.ppf(1 - level / 2) * np.sqrt(np.asarray(var, dtype=float) / n)


@checked(expected=_FINITE)
def variance_band(expected, dof: int, level: float):
    """The chi-square interval of a variance estimate: ``expected chi2_dof(level/2) / dof`` to
    ``expected chi2_dof(1 - level/2) / dof``.

    expected : array, the true variance (its units); dof : int >= 1, ``n - 1`` for the centred ensemble
    variance of n realizations, ``n`` for the uncentred mean square of zero-mean ones; level in (0, 1).
    Returns ``(lower, upper)``, arrays shaped like ``expected``.
    """
    dof, level = _runs(dof, 1, "dof"), _level(level)
    expected = np.asarray(expected, dtype=float)
    return (expected * stats.chi2.ppf(level / 2, dof) / dof,
            expected * stats.chi2.ppf(1 - level / 2, dof) / dof)


@checked(rho=_FINITE)
def correlation_band(rho, n: int, level: float):
    """Fisher's band of an ensemble correlation around the true one, ``rho``:
    ``tanh(atanh(rho) -+ z / sqrt(n - 3))``, ``z = norm.ppf(1 - level/2)``.

    rho : array in [-1, 1] (clipped); a true correlation of exactly +-1 has the band [+-1, +-1].
    n : int >= 2 realizations; for n <= 3 (too few for Fisher's interval) the band is [-1, 1].
    Returns ``(lower, upper)``, arrays shaped like ``rho`` (dimensionless).
    """
    n, level = _runs(n), _level(level)
    rho = np.asarray(rho, dtype=float)
    if n <= 3:
        return np.full_like(rho, -1.0), np.full_like(rho, 1.0)
    fisher = stats.norm.ppf(1 - level / 2) / np.sqrt(n - 3)
    with np.errstate(divide="ignore"):  # atanh(+-1) = +-inf, tanh(+-inf) = +-1
        z_rho = np.arctanh(np.clip(rho, -1.0, 1.0))
    return np.tanh(z_rho - fisher), np.tanh(z_rho + fisher)


def uncentred_correlation_band(n: int, level: float) -> float:
    """Half-width of the band of ``sum a_l b_l / sqrt(sum a_l^2 sum b_l^2)`` over ``n`` realizations of
    two independent zero-mean Gaussians: ``q / sqrt(n - 1 + q^2)``, ``q = t_{n-1}(1 - level/2)``.

    Exact: the correlation is the cosine of the angle between two vectors in R^n, and
    ``rho sqrt((n - 1) / (1 - rho^2))`` is Student t with n - 1 degrees of freedom.  n >= 2.
    """
    n, level = _runs(n), _level(level)
    q = stats.t.ppf(1 - level / 2, n - 1)
    return q / np.sqrt(n - 1 + q**2)


@checked(err=require_array, cov=require_array)
def normalized_squares(err: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """Return ``err^T cov^{-1} err`` over leading axes.

    Parameters
    ----------
    err : array (..., n)
        Errors or innovations.
    cov : array (..., n, n)
        Their covariances; broadcast against ``err``'s leading axes.

    Returns
    -------
    array (...,) of the normalized squared errors (dimensionless).

    Raises
    ------
    ValueError if the shapes do not match, an entry is not finite, or a covariance is singular.
    """
    err = np.asarray(err, dtype=float)
    cov = np.asarray(cov, dtype=float)
    if err.ndim < 1 or cov.ndim < 2 or cov.shape[-1] != cov.shape[-2] or cov.shape[-1] != err.shape[-1]:
        raise ValueError(
            f"err must have shape (..., n) and cov (..., n, n) with the same n; got {err.shape} and {cov.shape}"
        )
    if not (np.all(np.isfinite(err)) and np.all(np.isfinite(cov))):
        raise ValueError("err and cov must hold only finite numbers")
    try:
        sol = np.linalg.solve(cov, err[..., None])[..., 0]
    except np.linalg.LinAlgError:
        raise ValueError("cov must be non-singular (positive definite)") from None
    return np.einsum("...i,...i->...", err, sol)


nees = normalized_squares
nis = normalized_squares


@checked(values=require_array, lower=_FINITE, upper=_FINITE)
def inside_fraction(values, lower, upper) -> float:
    """Share of the finite entries of ``values`` that lie in ``[lower, upper]``."""
    try:
        lower = np.broadcast_to(lower, values.shape)
        upper = np.broadcast_to(upper, values.shape)
    except ValueError:
        raise ValueError(f"lower and upper must broadcast to the shape of values {values.shape}, got "
                         f"{np.shape(lower)} and {np.shape(upper)}") from None
    ok = np.isfinite(values)
    if not ok.any():
        raise ValueError("values must hold at least one finite entry")
    inside = (values >= lower) & (values <= upper)
    return float(inside[ok].mean())


@dataclass
class Check:
    """One statistical check.

    statistic, expected : 1-D arrays, one entry per judged quantity (see the module docstring)
    lower, upper : the pointwise band at significance ``alpha`` (about ``1 - alpha``
        of the entries of a consistent filter fall inside)
    sim_lower, sim_upper : the simultaneous band (Bonferroni: significance ``alpha / entries``
        per entry, ``entries`` the total over the checks judged together, :meth:`bonferroni`),
        which a consistent filter leaves nowhere, in all those checks together, with probability
        at least ``1 - alpha`` whatever the correlation between entries
    inside_fraction : share of entries inside the pointwise band
    worst : largest ``|statistic - expected|`` as a multiple of the distance from
        ``expected`` to the simultaneous bound on that side (> 1 means outside)
    """

    name: str
    description: str
    statistic: np.ndarray
    expected: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    sim_lower: np.ndarray
    sim_upper: np.ndarray
    inside_fraction: float = field(init=False)
    worst: float = field(init=False)

    def __post_init__(self):
        require_text("name", self.name)
        require_text("description", self.description)
        names = ("statistic", "expected", "lower", "upper", "sim_lower", "sim_upper")
        arrays = [np.ravel(require_finite_array(n, getattr(self, n))) for n in names]
        for n, a in zip(names[1:], arrays[1:]):
            if a.size != arrays[0].size:
                raise ValueError(f"{n} must have one entry per entry of statistic ({arrays[0].size}), got {a.size}")
        self.statistic, self.expected, self.lower, self.upper, self.sim_lower, self.sim_upper = arrays
        s, c, lo, hi, slo, shi = arrays
        self.inside_fraction = float(np.mean((s >= lo) & (s <= hi)))
        dev = s - c
        half = np.where(dev >= 0, shi - c, c - slo)
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = np.where(dev == 0, 0.0, np.abs(dev) / half)
        self.worst = float(np.max(ratio))

    @property
    def passed(self) -> bool:
        """Pass when every entry is inside the simultaneous band (``worst <= 1``)."""
        return self.worst <= 1.0

    @classmethod
    def from_band(cls, name: str, description: str, statistic, expected, band, alpha: float,
                  sim_alpha: float) -> "Check":
        """The one way a problem builds a check: ``statistic`` against ``expected`` with its bands
        ``band(level) -> (lower, upper)`` (one of this module's bands) at ``alpha`` (pointwise) and at
        ``sim_alpha`` (simultaneous, from :meth:`bonferroni`); ``expected`` and the bounds are
        broadcast to the statistic's shape, as float64."""
        shape = np.shape(statistic)
        lo, hi = band(alpha)
        slo, shi = band(sim_alpha)
        full = [np.broadcast_to(np.asarray(v, dtype=float), shape) for v in (expected, lo, hi, slo, shi)]
        return cls(name, description, statistic, *full)

    @staticmethod
    def bonferroni(alpha: float, entries: int) -> float:
        """Per-entry significance of a simultaneous band: ``alpha / entries``, so that a consistent
        filter leaves some entry outside with probability at most ``alpha`` (union bound).

        The course's one policy, in every problem: the checks judged together in one verdict are one
        family, and ``entries`` is their total number of entries (coop, orbit, :func:`step_checks`, and
        calibration's seven checks, or the subset of them asked for).
        """
        return alpha / entries


@runtime_checkable
class MonteCarloSummary(Protocol):
    """What every problem's Monte Carlo result offers (:func:`kfcal_helpers.montecarlo.run` makes
    them): ``n_runs`` (realizations), ``alpha`` (significance of the bands), ``filter`` (the algorithm
    that ran: "kf" in the calibration, "lkf", "ekf" or "ukf" in coop and orbit), ``seconds`` (wall time of the run) and ``checks()``, the checks by name."""

    n_runs: int
    alpha: float
    filter: str
    seconds: float

    def checks(self) -> dict: ...


def format_checks(checks) -> str:
    """A fixed-precision text table of checks, one line each: name, share inside the pointwise
    band, worst deviation / simultaneous bound (> 1 fails), verdict.

    checks : ``{name: Check}``, or an object with ``checks()`` (a Monte Carlo result)."""
    if hasattr(checks, "checks"):
        checks = checks.checks()
    if not isinstance(checks, dict) or not all(isinstance(c, Check) for c in checks.values()):
        raise ValueError("checks must be a dict name -> Check, or a Monte Carlo result with checks()")
    width = max([22, *(len(n) for n in checks)])
    lines = [f"{'check':<{width}} {'inside':>7} {'worst':>7}  verdict",
             f"{'-' * width} {'-' * 7} {'-' * 7}  -------"]
    for name, c in checks.items():
        verdict = "pass" if c.passed else "FAIL"
        lines.append(f"{name:<{width}} {c.inside_fraction:7.3f} {c.worst:7.2f}  {verdict}")
    return "\n".join(lines)
