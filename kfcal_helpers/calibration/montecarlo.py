"""Monte Carlo validation of the calibration filter (seven checks at the GPS fixes, and one between them).

Realizations are simulated in chunks of at most :data:`CHUNK_SIZE` (a chunk's draws are
dropped once the chunk is filtered), and only sums over realizations are kept, so memory does not
grow with the number of runs.  The chunks run on a small thread pool (``workers``, default
``min(2, os.cpu_count())``); chunk ``c`` draws from its own random stream
(``numpy.random.SeedSequence(seed).spawn``, PCG64DXSM, :func:`chunk_generators`) and the partial sums are
added in chunk order, so the result is the same, bit for bit, for any number of workers.  The chunk size follows the
size of one realization (:func:`chunk_size`, a function of the parameters only, so results
do not depend on the machine) and keeps the estimated peak memory of the process under
:data:`MEMORY_LIMIT`; a run that cannot fit even one realization at a time, or whose
estimated time exceeds :data:`MAX_SECONDS`, is refused with its estimate
(:func:`estimate_run`), before any work starts.

For realization ``l`` and fix ``i``: error ``e = dx - dx_hat`` (a posteriori),
prior error ``e_bar = dx - dx_hat_prior``, residual ``r = dz - H dx_hat_prior``.
The checks, each judged against its own sampling band at significance
``alpha`` (z = ``norm.ppf(1 - alpha/2)``, 1.96 for alpha = 0.05):

1. ``mean_error``: ensemble mean of ``e`` against ``+-t_{N-1}(1 - alpha/2) s/sqrt(N)`` (s: ensemble std).
2. ``covariance``: ensemble covariance of ``e`` against the filter's ``P``; variances
   against the chi-square interval ``P chi2_{N-1}(alpha/2, 1-alpha/2)/(N-1)``,
   correlations against the filter's, with Fisher's ``tanh(atanh(rho_P) +- z/sqrt(N-3))``.
3. ``orthogonality``: ``(1/N) sum (e - e_mean) dx_hat^T`` against
   ``+-z sqrt(P_kk mean(dx_hat_l^2)/N)`` (the spread of a product of independent factors; slightly
   conservative, as the exact spread has the centred ``mean((dx_hat_l - mean dx_hat)^2) <= mean(dx_hat_l^2)``).
4. ``residual_independence``: the correlation ``sum r_i,a r_m,b / sqrt(sum r_i,a^2 sum r_m,b^2)``
   for every pair of fixes ``i < m`` against ``+-q/sqrt(N - 1 + q^2)``, ``q = t_{N-1}(1 - alpha/2)``
   (exact for independent zero-mean Gaussian residuals: the correlation is the cosine of the
   angle between two vectors in R^N, and ``rho sqrt((N - 1)/(1 - rho^2))`` is Student-t with N - 1
   degrees of freedom).
5. ``residual_variance``: ``(1/N) sum r_i r_i^T`` diagonal against ``S_i chi2_N/N``.
6. ``nees``: run-averaged ``e^T P^-1 e`` against ``chi2_{3N}/N`` bounds.
7. ``nis``: run-averaged ``r^T S^-1 r`` against ``chi2_{2N}/N`` bounds.

``inside_fraction`` is the share of entries (fix x component, or pair x component
for check 4, fix for NEES and NIS) inside the band; about ``1 - alpha`` for a
consistent filter.

Between fixes (``run_monte_carlo(..., between_fixes=True)``): the error at every
200 Hz sample, ``e(t_j) = dx(t_j) - dx_hat(t_j)`` with the predicted estimate
``dx_hat(t_i + k dt) = Phi^k dx_hat_post(t_i)``, is summed over realizations as well
(memory independent of N), and :meth:`MonteCarloResult.between_fixes_check` compares
its ensemble variance at every sample with the filter's ``P_kk(t_j)`` against the
chi-square interval ``P_kk chi2_{N-1}(level/2, 1-level/2)/(N-1)`` (its own family of
entries at ``alpha``: the seven checks above are not changed by it, and over all eight checks a
consistent filter fails somewhere with probability at most ``2 alpha``).
"""

from __future__ import annotations

import itertools
import os
import threading
import time
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout
from dataclasses import dataclass

import numpy as np
from scipy import stats

from ..consistency import Check, chi2_bounds
from ..progress import progress_bar as _progress_bar
from ..validation import require_choice, require_instance, require_int, require_mask, require_seed, require_significance
from .engine import covariance_sequence, estimate_between_fixes, filter_estimates, filter_model
from .error_model import ErrorStateModel
from .filters import run_filterpy
from .params import CalibrationParams
from .simulation import TRUTH_MODELS, draw_realizations, error_state_at_fixes, error_state_full

__all__ = ["CHUNK_SIZE", "MEMORY_LIMIT", "MAX_SECONDS", "chunk_size", "chunk_sizes", "chunk_generators",
           "chunks_in_flight", "default_workers", "estimate_run", "FILTERS", "CHECK_NAMES", "Check",
           "MonteCarloResult", "BetweenFixes", "run_monte_carlo"]

CHUNK_SIZE = 500  #: most realizations simulated together (see chunk_size)
MEMORY_LIMIT = 500e6  #: bytes, the estimated peak memory (resident) a run may need
MAX_SECONDS = 3600.0  #: s, the longest estimated run accepted
# Cost model, measured (tracemalloc, ru_maxrss, wall time) on the 2-core reference machine and
# rounded up (tests/test_calibration_montecarlo.py checks it against tracemalloc):
# * the interpreter with numpy and scipy, and per IMU sample what the whole run keeps (the filter's P);
# * at the end, per GPS fix squared, the statistics of the checks (the pairwise residual statistics);
# * while chunks run: the sums (per fix squared, and per sample with between_fixes), and per chunk in
#   flight its realizations (per IMU sample and per fix of one realization; with between_fixes the
#   200 Hz error state, its estimate and their products) and its partial sums;
# * seconds per IMU sample of one realization on one thread, and per fix squared.
_BASE_BYTES = 130e6
_FIXED_BYTES_PER_SAMPLE = 100.0
_STATS_BYTES_PER_FIX2 = 340.0
_SUMS_BYTES_PER_FIX2, _SUMS_BYTES_PER_SAMPLE = 40.0, 200.0
_BYTES_PER_SAMPLE, _BYTES_PER_FIX = 16.0, 400.0
_BETWEEN_BYTES_PER_SAMPLE = 80.0
_PARTIAL_BYTES_PER_FIX2, _PARTIAL_BYTES_PER_SAMPLE = 72.0, 100.0
_SECONDS_PER_SAMPLE = {"batch": 1.5e-7, "filterpy": 6e-6}
_SECONDS_PER_FIX2 = 3e-6
FILTERS = ("batch", "filterpy")  #: the filter codes run_monte_carlo can run
CHECK_NAMES = ("mean_error", "covariance", "orthogonality", "residual_independence",
               "residual_variance", "nees", "nis")


@dataclass
class MonteCarloResult:
    """Ensemble statistics at the GPS fixes (n_gps fixes, N = n_runs realizations).

    t_gps (n_gps,) s; P_prior, P_post (n_gps, 3, 3) and S (n_gps, 2, 2) from the filter;
    e_mean, e_prior_mean (n_gps, 3); e_cov, e_prior_cov (n_gps, 3, 3) ensemble
    statistics of the a posteriori / a priori errors; orthogonality (n_gps, 3, 3);
    xhat_sq_mean (n_gps, 3); residual_moment (n_gps, 2, n_gps, 2) = (1/N) sum r r^T (NaN at missing
    fixes); nees (n_gps,), nis (n_gps,) run averages (NaN at missing fixes for NIS);
    filter: "batch" or "filterpy"; seconds: wall time of simulation + filtering + statistics.
    The interface shared with the coop problem: ``n_runs``, ``alpha``, ``checks()``
    (printed by ``kfcal_helpers.consistency.format_checks``).
    """

    params: CalibrationParams
    n_runs: int
    filter: str
    truth: str
    alpha: float
    seconds: float
    t_gps: np.ndarray
    missing: np.ndarray
    P_prior: np.ndarray
    P_post: np.ndarray
    S: np.ndarray
    e_mean: np.ndarray
    e_cov: np.ndarray
    e_prior_mean: np.ndarray
    e_prior_cov: np.ndarray
    orthogonality: np.ndarray
    xhat_sq_mean: np.ndarray
    residual_moment: np.ndarray
    nees: np.ndarray
    nis: np.ndarray
    between: "BetweenFixes | None" = None

    @property
    def sigma_final(self) -> np.ndarray:
        """[sigma_p, sigma_v, sigma_b] from the filter's P at the last fix (m, m/s, m/s^2)."""
        return np.sqrt(np.diag(self.P_post[-1]))

    @property
    def ensemble_sigma_final(self) -> np.ndarray:
        """The same from the ensemble covariance of the errors."""
        return np.sqrt(np.diag(self.e_cov[-1]))

    @property
    def nees_bounds(self) -> tuple[float, float]:
        return chi2_bounds(3, self.n_runs, self.alpha)

    @property
    def nis_bounds(self) -> tuple[float, float]:
        return chi2_bounds(2, self.n_runs, self.alpha)

    def residual_correlation(self) -> np.ndarray:
        """``residual_moment`` normalized by ``sqrt(S_i,aa S_m,bb)``, shape (2 n_gps, 2 n_gps);
        ordered [p_0, v_0, p_1, v_1, ...]; about N(0, 1/N) off the diagonal."""
        d = np.sqrt(np.einsum("iaa->ia", self.S)).reshape(-1)
        n = self.residual_moment.shape[0] * 2
        return self.residual_moment.reshape(n, n) / np.outer(d, d)

    def bands(self, level: float) -> dict:
        """``{check: (statistic, expected, lower, upper)}`` at per-entry significance ``level``."""
        N = self.n_runs
        out = {}
        sd = np.sqrt(np.einsum("iaa->ia", self.e_cov))
        half = stats.t.ppf(1 - level / 2, N - 1) * sd / np.sqrt(N)
        out["mean_error"] = (self.e_mean, 0 * sd, -half, half)

        z = stats.norm.ppf(1 - level / 2)
        P = self.P_post
        iu = np.triu_indices(3)
        diag = iu[0] == iu[1]
        Pkk = np.einsum("iaa->ia", P)
        Pkl = P[:, iu[0], iu[1]]
        # variances: exact chi-square interval; correlations: Fisher's z-transform
        stat = self.e_cov[:, iu[0], iu[1]].copy()
        expected = Pkl.copy()
        Ekk = np.einsum("iaa->ia", self.e_cov)
        stat[:, ~diag] /= np.sqrt(Ekk[:, iu[0][~diag]] * Ekk[:, iu[1][~diag]])
        expected[:, ~diag] /= np.sqrt(Pkk[:, iu[0][~diag]] * Pkk[:, iu[1][~diag]])
        if N > 3:
            fisher = z / np.sqrt(N - 3)
            with np.errstate(divide="ignore"):  # a filter claiming a correlation of exactly +-1: band [+-1, +-1]
                z_rho = np.arctanh(np.clip(expected, -1.0, 1.0))
            lo = np.tanh(z_rho - fisher)
            hi = np.tanh(z_rho + fisher)
        else:  # too few runs for Fisher's interval: any correlation
            lo, hi = np.full_like(expected, -1.0), np.full_like(expected, 1.0)
        lo[:, diag] = Pkk * stats.chi2.ppf(level / 2, N - 1) / (N - 1)
        hi[:, diag] = Pkk * stats.chi2.ppf(1 - level / 2, N - 1) / (N - 1)
        out["covariance"] = (stat, expected, lo, hi)

        half = z * np.sqrt(Pkk[:, :, None] * self.xhat_sq_mean[:, None, :] / N)
        out["orthogonality"] = (self.orthogonality, 0 * half, -half, half)

        ok = ~self.missing
        M = self.residual_moment[ok][:, :, ok, :]
        Sd = np.einsum("iaa->ia", self.S[ok])
        i, m = np.triu_indices(M.shape[0], k=1)
        # uncentred correlation of two independent zero-mean Gaussians (the cosine of the angle between
        # two vectors in R^N): t = rho sqrt((N - 1) / (1 - rho^2)) ~ t_{N-1}
        Md = np.einsum("iaia->ia", M)
        rho = M[i, :, m, :] / np.sqrt(Md[i][:, :, None] * Md[m][:, None, :])
        q = stats.t.ppf(1 - level / 2, N - 1)
        half = np.full_like(rho, q / np.sqrt(N - 1 + q**2))
        out["residual_independence"] = (rho, 0 * half, -half, half)
        out["residual_variance"] = (np.einsum("iaia->ia", M), Sd, Sd * stats.chi2.ppf(level / 2, N) / N,
                                    Sd * stats.chi2.ppf(1 - level / 2, N) / N)
        for name, dim, stat in (("nees", 3, self.nees), ("nis", 2, self.nis[ok])):
            lo = stats.chi2.ppf(level / 2, dim * N) / N
            hi = stats.chi2.ppf(1 - level / 2, dim * N) / N
            out[name] = (stat, np.full_like(stat, dim), np.full_like(stat, lo), np.full_like(stat, hi))
        return out

    def checks(self) -> dict[str, Check]:
        """The seven checks (see the module docstring), keyed by :data:`CHECK_NAMES`."""
        pointwise = self.bands(self.alpha)
        out = {}
        for name in CHECK_NAMES:
            stat, expected, lo, hi = pointwise[name]
            family = self.alpha / len(CHECK_NAMES) / np.size(stat)
            _, _, slo, shi = self.bands(family)[name]
            out[name] = Check(name, _DESCRIPTIONS[name], stat, expected, lo, hi, slo, shi)
        return out

    def between_fixes_check(self) -> Check:
        """The 200 Hz check between fixes (needs ``run_monte_carlo(..., between_fixes=True)``).

        Entries: every IMU sample that is not a fix x the three components; statistic the
        ensemble variance of the error, expected the filter's ``P_kk(t_j)``; pointwise band
        ``P_kk chi2_{N-1}(alpha/2, 1 - alpha/2)/(N-1)``, simultaneous band the same at
        ``alpha / entries`` (a family of its own).
        """
        if self.between is None:
            raise ValueError("between_fixes_check needs run_monte_carlo(..., between_fixes=True)")
        b = self.between
        off = np.ones(self.params.n_imu, bool)
        off[self.params.fix_indices] = False
        if not off.any():
            raise ValueError("between_fixes_check: every IMU sample is a GPS fix (GPS rate = IMU rate), "
                             "so there is nothing between fixes to check")
        var = np.einsum("jaa->ja", b.e_cov)[off]
        Pkk = np.einsum("jaa->ja", b.P)[off]
        N = self.n_runs

        def band(level):
            return (Pkk * stats.chi2.ppf(level / 2, N - 1) / (N - 1),
                    Pkk * stats.chi2.ppf(1 - level / 2, N - 1) / (N - 1))

        lo, hi = band(self.alpha)
        slo, shi = band(self.alpha / var.size)
        return Check("between_fixes", _BETWEEN_DESCRIPTION, var, Pkk, lo, hi, slo, shi)


@dataclass
class BetweenFixes:
    """Ensemble statistics of the error at every IMU sample (n_imu = 6001 for the defaults).

    t (n_imu,) s; P (n_imu, 3, 3) the filter's covariance (a posteriori at fixes, predicted
    between them); e_mean (n_imu, 3), e_cov (n_imu, 3, 3) ensemble mean and covariance
    (1/(N-1)) of ``e = dx - dx_hat``.
    """

    t: np.ndarray
    P: np.ndarray
    e_mean: np.ndarray
    e_cov: np.ndarray


_BETWEEN_DESCRIPTION = "ensemble variance of the 200 Hz error between fixes vs the filter's P"


_DESCRIPTIONS = {
    "mean_error": "ensemble mean of the error vs 0 (+-t s/sqrt(N))",
    "covariance": "ensemble covariance of the error vs the filter's P",
    "orthogonality": "(1/N) sum (e - e_mean) x_hat^T vs 0",
    "residual_independence": "correlation of r_i and r_m for fixes i < m vs 0",
    "residual_variance": "(1/N) sum r_i^2 vs the filter's S_i",
    "nees": "run-averaged NEES vs chi2_3N/N bounds",
    "nis": "run-averaged NIS vs chi2_2N/N bounds",
}



class _BetweenSums:
    """Sums of the 200 Hz error over realizations: O(n_imu) memory, whatever N."""

    def __init__(self, n_imu: int):
        self.n = 0
        self.e = np.zeros((n_imu, 3))
        self.ee = np.zeros((n_imu, 3, 3))

    def add(self, dx_full, x_full):
        e = dx_full
        e -= x_full  # in place: dx_full is not used again
        self.n += len(e)
        self.e += e.sum(0)
        et = np.ascontiguousarray(e.transpose(1, 2, 0))  # (n_imu, 3, n)
        self.ee += et @ et.transpose(0, 2, 1)

    def combine(self, other: "_BetweenSums"):
        self.n += other.n
        self.e += other.e
        self.ee += other.ee

    def result(self, params: CalibrationParams, P: np.ndarray) -> BetweenFixes:
        N = self.n
        mean = self.e / N
        cov = (self.ee - N * np.einsum("ja,jb->jab", mean, mean)) / (N - 1)
        return BetweenFixes(params.t_imu, P, mean, cov)


class _Sums:
    """Sums over realizations of everything the checks need at the GPS fixes (present fixes only for
    the residuals): uncentred moments, combined chunk by chunk in chunk order."""

    def __init__(self, n_gps: int, n_present: int):
        self.n = 0
        self.e = np.zeros((n_gps, 3))
        self.eb = np.zeros((n_gps, 3))
        self.x = np.zeros((n_gps, 3))
        self.m = np.zeros((n_gps, 9, 9))  # second moments of [e, e_bar, x_post]
        self.rr = np.zeros((2 * n_present, 2 * n_present))

    def add(self, dx, x_prior, x_post, y_present):
        n = len(dx)
        z = np.empty((dx.shape[1], 9, n))  # fix-major [e, e_bar, x_post] of the chunk
        np.subtract(dx.transpose(1, 2, 0), x_post.transpose(1, 2, 0), out=z[:, 0:3])
        np.subtract(dx.transpose(1, 2, 0), x_prior.transpose(1, 2, 0), out=z[:, 3:6])
        z[:, 6:9] = x_post.transpose(1, 2, 0)
        s = z.sum(axis=2)
        self.n += n
        self.e += s[:, 0:3]
        self.eb += s[:, 3:6]
        self.x += s[:, 6:9]
        self.m += z @ z.transpose(0, 2, 1)
        r = y_present.reshape(n, -1)
        self.rr += np.einsum("na,nb->ab", r, r)  # numpy's own loop: a threaded BLAS call here spins idle threads

    def combine(self, other: "_Sums"):
        self.n += other.n
        for name in ("e", "eb", "x", "m", "rr"):
            getattr(self, name).__iadd__(getattr(other, name))


# Memory and time --------------------------------------------------------------------------------
def _fixed_bytes(params: CalibrationParams) -> float:
    """Bytes the whole run keeps: the interpreter and the filter's covariances."""
    return _BASE_BYTES + _FIXED_BYTES_PER_SAMPLE * params.n_imu


def _sums_bytes(params: CalibrationParams, between_fixes: bool) -> float:
    return _SUMS_BYTES_PER_FIX2 * params.n_gps**2 + (_SUMS_BYTES_PER_SAMPLE * params.n_imu if between_fixes else 0.0)


def _realization_bytes(params: CalibrationParams, between_fixes: bool = False) -> float:
    """Bytes one realization of a chunk in flight needs (its draws, its filter, its statistics)."""
    per_sample = _BYTES_PER_SAMPLE + (_BETWEEN_BYTES_PER_SAMPLE if between_fixes else 0.0)
    return per_sample * params.n_imu + _BYTES_PER_FIX * params.n_gps


def _partial_bytes(params: CalibrationParams, between_fixes: bool = False) -> float:
    """Bytes of one chunk's partial sums, alive until they are added in chunk order."""
    return _PARTIAL_BYTES_PER_FIX2 * params.n_gps**2 + (_PARTIAL_BYTES_PER_SAMPLE * params.n_imu
                                                          if between_fixes else 0.0)


def default_workers() -> int:
    """Threads the Monte Carlo uses by default: ``min(2, os.cpu_count())``."""
    return max(1, min(2, os.cpu_count() or 1))


def chunk_size(params: CalibrationParams) -> int:
    """Realizations simulated together for ``params``: :data:`CHUNK_SIZE`, or fewer when the
    realizations are long, so that the estimated peak with one chunk in flight stays under
    :data:`MEMORY_LIMIT` even with ``between_fixes`` (at least 1; :func:`estimate_run` refuses runs
    where even 1 does not fit).  It depends on neither ``between_fixes`` nor ``workers``, so the random
    draws, and the seven checks, are the same with and without them."""
    room = MEMORY_LIMIT - _fixed_bytes(params) - _sums_bytes(params, True) - _partial_bytes(params, True)
    return int(max(1, min(CHUNK_SIZE, room // _realization_bytes(params, between_fixes=True))))


def chunk_sizes(params: CalibrationParams, n_runs: int) -> list[int]:
    """The sizes of the chunks of a run of ``n_runs`` realizations, in order."""
    chunk = chunk_size(params)
    return [chunk] * (n_runs // chunk) + ([n_runs % chunk] if n_runs % chunk else [])


def chunk_generators(params: CalibrationParams, n_runs: int, seed) -> list[tuple[int, np.random.Generator]]:
    """``(size, generator)`` of every chunk: chunk ``c`` draws its realizations (with
    ``simulation.draw_realizations``, the draws of ``simulate``) from its own stream,
    ``numpy.random.Generator(numpy.random.PCG64DXSM(numpy.random.SeedSequence(seed).spawn(n_chunks)[c]))``
    (PCG64DXSM, numpy's recommended successor of ``default_rng``'s PCG64, draws normals about 30 % faster
    here); for a Generator ``seed``, from ``seed.spawn(n_chunks)``.  So a chunk's numbers do not depend
    on which thread runs it."""
    sizes = chunk_sizes(params, n_runs)
    if isinstance(seed, np.random.Generator):
        gens = seed.spawn(len(sizes))
    else:
        gens = [np.random.Generator(np.random.PCG64DXSM(s)) for s in np.random.SeedSequence(seed).spawn(len(sizes))]
    return list(zip(sizes, gens))


def _chunk_bytes(params: CalibrationParams, n_runs: int, between_fixes: bool) -> float:
    """Bytes of one chunk in flight: its realizations and its partial sums."""
    return (min(n_runs, chunk_size(params)) * _realization_bytes(params, between_fixes)
            + _partial_bytes(params, between_fixes))


def chunks_in_flight(params: CalibrationParams, n_runs: int, workers: int | None = None,
                     between_fixes: bool = False) -> int:
    """How many chunks run at once: ``workers`` (default :func:`default_workers`), but no more than
    there are chunks, nor than fit in :data:`MEMORY_LIMIT` (at least 1)."""
    workers = default_workers() if workers is None else workers
    room = MEMORY_LIMIT - _fixed_bytes(params) - _sums_bytes(params, between_fixes)
    fit = int(room // _chunk_bytes(params, n_runs, between_fixes))
    n_chunks = -(-n_runs // chunk_size(params))  # without listing them: n_runs may be far too large to run
    return max(1, min(workers, n_chunks, fit))


def estimate_run(params: CalibrationParams, n_runs: int, filter: str = "batch",
                 runs_name: str = "n_runs", params_name: str = "params",
                 extra_bytes: float = 0.0, between_fixes: bool = False,
                 workers: int | None = None) -> tuple[float, float]:
    """Estimated ``(peak bytes, seconds)`` of :func:`run_monte_carlo`, with every chunk in flight
    (:func:`chunks_in_flight`) counted; ValueError, with the estimate, when the peak exceeds
    :data:`MEMORY_LIMIT` (the scenario has too many IMU samples or GPS fixes) or the time exceeds
    :data:`MAX_SECONDS` (``runs_name`` and ``params_name`` name the arguments in the message).
    ``extra_bytes``: what the caller needs after the Monte Carlo, while its result is alive (the
    command line's figures).  The time is that of one thread (a conservative bound)."""
    flying = chunks_in_flight(params, n_runs, workers, between_fixes)
    running = _sums_bytes(params, between_fixes) + flying * _chunk_bytes(params, n_runs, between_fixes)
    # the caller's extra work (figures) runs with the result alive and computes its checks again
    peak = _fixed_bytes(params) + max(running, _STATS_BYTES_PER_FIX2 * params.n_gps**2 + extra_bytes)
    if peak > MEMORY_LIMIT:
        raise ValueError(
            f"{params_name}: one realization of {params.n_imu} IMU samples and {params.n_gps} GPS fixes needs about "
            f"{peak / 1e6:.0f} MB, more than the {MEMORY_LIMIT / 1e6:.0f} MB allowed; use a shorter duration "
            f"or lower rates (at most about 1000 GPS fixes and 3 million IMU samples)")
    seconds = (_SECONDS_PER_SAMPLE[filter] * params.n_imu * float(n_runs)
               + _SECONDS_PER_FIX2 * params.n_gps**2)
    if seconds > MAX_SECONDS:
        raise ValueError(f"{runs_name}: {n_runs} realizations with filter {filter!r} would take about "
                         f"{seconds / 3600:.3g} h, more than the {MAX_SECONDS / 3600:g} h allowed; use fewer")
    return peak, seconds


# The run -----------------------------------------------------------------------------------------
@dataclass
class _Setup:
    """What every chunk shares (read only)."""

    params: CalibrationParams
    truth: str
    filter: str
    model: ErrorStateModel
    given_model: ErrorStateModel | None
    missing: np.ndarray
    K: np.ndarray
    between: bool
    cancel: threading.Event


def _chunk(setup: _Setup, size: int, rng: np.random.Generator, on_realization=None):
    """One chunk: draw, filter, and return its partial sums (and the 200 Hz ones with ``between``)."""
    if setup.cancel.is_set():
        return None
    params, missing = setup.params, setup.missing
    draws = draw_realizations(params, size, rng)
    dx = error_state_at_fixes(params, draws, setup.truth)
    dz = dx[..., :2] + draws.eta
    dz[:, missing] = np.nan
    runs = None
    if setup.filter == "batch":
        x_prior, x_post, y = filter_estimates(params, dz, setup.K, missing, setup.model)
    else:
        runs = []
        for l in range(size):  # the bar moves with every realization (about 0.03 s each)
            if setup.cancel.is_set():
                return None
            res = run_filterpy(params, dz[l], setup.given_model)
            runs.append((res.x_prior, res.x_post, res.y, res.x if setup.between else None))
            if on_realization is not None:
                on_realization()
        x_prior, x_post, y = (np.stack([run[k] for run in runs]) for k in range(3))
    sums = _Sums(params.n_gps, int((~missing).sum()))
    sums.add(dx, x_prior, x_post, y[:, ~missing])
    bsums = None
    if setup.between:
        bsums = _BetweenSums(params.n_imu)
        x_full = (estimate_between_fixes(params, x_post, setup.model) if runs is None
                  else np.stack([run[3] for run in runs]))
        bsums.add(error_state_full(params, draws, setup.truth), x_full)
    return sums, bsums


def run_monte_carlo(params: CalibrationParams, n_runs: int, seed=0, *, filter: str = "batch",
                    truth: str = "euler", alpha: float = 0.05, missing_fixes=None, progress: bool | None = False,
                    model: ErrorStateModel | None = None, between_fixes: bool = False,
                    workers: int | None = None) -> MonteCarloResult:
    """Simulate ``n_runs`` realizations, filter them, and accumulate the check statistics.

    Parameters
    ----------
    params : CalibrationParams
    n_runs : int >= 2
    seed : int (or None: fresh entropy) seeding ``numpy.random.SeedSequence``, or a numpy.random.Generator;
        chunk ``c`` draws from its own stream (:func:`chunk_generators`)
    filter : "batch" (vectorised, shared gains) or "filterpy" (one KalmanFilter per run)
    truth : "euler" or "analytic"
    alpha : significance of the bands, in (0, 1)
    missing_fixes : optional bool array (n_gps,), fixes that are missing (outages)
    progress : show a progress bar (None: unless CI/KFCAL_QUIET is set)
    model : optional ErrorStateModel the filter assumes (default: the true one); the
        truth is always simulated with ``params``
    between_fixes : also accumulate the error at every 200 Hz sample (``result.between``,
        checked by ``result.between_fixes_check()``); memory O(n_imu), independent of N
    workers : threads running chunks at once (default ``min(2, os.cpu_count())``; fewer when the
        chunks would not fit in :data:`MEMORY_LIMIT`).  The result is the same, bit for bit, for any
        number: every chunk has its own random stream and the sums are added in chunk order.

    Returns
    -------
    MonteCarloResult

    Raises
    ------
    ValueError naming the argument: bad values, missing fixes leaving fewer than 2 fixes,
    or a run refused by :func:`estimate_run` (too much memory or time).
    """
    require_instance("params", params, CalibrationParams)
    n_runs = require_int("n_runs", n_runs, minimum=2)
    require_choice("filter", filter, FILTERS)
    require_choice("truth", truth, TRUTH_MODELS)
    alpha = require_significance("alpha", alpha)
    missing = require_mask("missing_fixes", missing_fixes, params.n_gps)
    missing = np.zeros(params.n_gps, bool) if missing is None else missing.copy()
    if (~missing).sum() < 2:
        raise ValueError(f"missing_fixes must leave at least 2 of the {params.n_gps} GPS fixes, "
                         f"got {int((~missing).sum())}")
    if not isinstance(seed, np.random.Generator):
        seed = require_seed("seed", seed)
    if not isinstance(between_fixes, (bool, np.bool_)):
        raise ValueError(f"between_fixes must be True or False, got {between_fixes!r}")
    between_fixes = bool(between_fixes)
    workers = default_workers() if workers is None else require_int("workers", workers, minimum=1)
    m = filter_model(params, model)
    estimate_run(params, n_runs, filter, between_fixes=between_fixes, workers=workers)

    start = time.perf_counter()
    cov = covariance_sequence(params, missing, m)
    P, P_prior, S, K = cov
    setup = _Setup(params, truth, filter, m, model, missing, K, between_fixes, threading.Event())
    chunks = chunk_generators(params, n_runs, seed)
    sums = _Sums(params.n_gps, int((~missing).sum()))
    bsums = _BetweenSums(params.n_imu) if between_fixes else None
    bar = _progress_bar(n_runs, f"Monte Carlo ({filter})", progress)

    def combine(part, size):
        sums.combine(part[0])
        if bsums is not None:
            bsums.combine(part[1])
        if filter == "batch":
            bar.update(size)

    flying = chunks_in_flight(params, n_runs, workers, between_fixes)
    try:
        if flying == 1:  # in this thread: the bar moves with every filterpy realization
            for size, rng in chunks:
                combine(_chunk(setup, size, rng, lambda: bar.update(1)), size)
        else:
            _run_on_threads(setup, chunks, flying, combine, bar)
    finally:
        setup.cancel.set()  # after an interruption, the other threads stop at their next realization or chunk
        bar.close()

    N = sums.n
    e_mean = sums.e / N
    e_cov = (sums.m[:, 0:3, 0:3] - N * np.einsum("ia,ib->iab", e_mean, e_mean)) / (N - 1)
    eb_mean = sums.eb / N
    eb_cov = (sums.m[:, 3:6, 3:6] - N * np.einsum("ia,ib->iab", eb_mean, eb_mean)) / (N - 1)
    orth = (sums.m[:, 0:3, 6:9] - np.einsum("ia,ib->iab", e_mean, sums.x)) / N
    xx = np.einsum("iaa->ia", sums.m[:, 6:9, 6:9])
    P_post = P[params.fix_indices]
    # run-averaged NEES and NIS from the summed outer products: sum_l e^T P^-1 e = trace(P^-1 sum_l e e^T)
    nees = np.einsum("iab,iab->i", np.linalg.inv(P_post), sums.m[:, 0:3, 0:3]) / N
    n_gps, ok = params.n_gps, ~missing
    moment = np.full((n_gps, 2, n_gps, 2), np.nan)
    idx = np.flatnonzero(ok)
    moment[np.ix_(idx, [0, 1], idx, [0, 1])] = (sums.rr / N).reshape(len(idx), 2, len(idx), 2)
    nis = np.full(n_gps, np.nan)
    nis[ok] = np.einsum("iab,iaib->i", np.linalg.inv(S[ok]), moment[ok][:, :, ok, :])
    result = MonteCarloResult(
        params=params, n_runs=N, filter=filter, truth=truth, alpha=alpha, seconds=0.0,
        t_gps=params.t_gps, missing=missing, P_prior=P_prior, P_post=P_post, S=S,
        e_mean=e_mean, e_cov=e_cov, e_prior_mean=eb_mean, e_prior_cov=eb_cov,
        orthogonality=orth, xhat_sq_mean=xx / N, residual_moment=moment, nees=nees, nis=nis,
        between=bsums.result(params, P) if bsums is not None else None)
    result.checks()  # the statistics are part of the timed work
    result.seconds = time.perf_counter() - start
    return result


def _run_on_threads(setup: _Setup, chunks, flying: int, combine, bar):
    """Run the chunks on ``flying`` threads, at most ``flying`` submitted at a time, and add their sums
    in chunk order.  The bar is moved from this thread only (a count the workers raise is read every
    0.1 s).  An interruption (KeyboardInterrupt) cancels what has not started and stops the rest at
    their next realization (filterpy) or chunk."""
    lock = threading.Lock()
    done = [0, 0]  # realizations finished by the workers (filterpy), and shown on the bar

    def one_more():
        with lock:
            done[0] += 1

    def show():
        with lock:
            new = done[0] - done[1]
            done[1] = done[0]
        if new:
            bar.update(new)

    pool = ThreadPoolExecutor(max_workers=flying, thread_name_prefix="kfcal-mc")
    try:
        pending = deque()
        queue = iter(chunks)
        for size, rng in itertools.islice(queue, flying):
            pending.append((size, pool.submit(_chunk, setup, size, rng, one_more)))
        while pending:
            size, future = pending.popleft()
            while True:
                try:
                    part = future.result(timeout=0.1)
                    break
                except FutureTimeout:
                    show()
            show()
            combine(part, size)
            for size, rng in itertools.islice(queue, 1):
                pending.append((size, pool.submit(_chunk, setup, size, rng, one_more)))
    finally:
        setup.cancel.set()
        pool.shutdown(wait=False, cancel_futures=True)
