"""Monte Carlo validation of the calibration filter (seven checks at the GPS fixes, and one between them).

The run goes through the shared Monte Carlo core, :func:`kfcal_helpers.montecarlo.run`, with a
:class:`CalibrationExperiment`: realizations are simulated in chunks of at most :data:`CHUNK_SIZE`
(a chunk's draws are dropped once the chunk is filtered) and only sums over realizations are kept,
so memory does not grow with the number of runs.  The core's policy applies: chunk ``c`` draws from
its own random stream (``numpy.random.SeedSequence(seed).spawn``, PCG64DXSM, :func:`chunk_generators`),
the chunks run on a small thread pool (``workers``, default
:func:`kfcal_helpers.montecarlo.default_workers`: the environment variable ``KFCAL_WORKERS``, else
``min(2, os.cpu_count())``) and the partial sums are added in chunk order, so the result is the same,
bit for bit, for any number of workers.  The chunk size follows the size of one realization
(:func:`chunk_size`, a function of the parameters only, so results do not depend on the machine); a
run whose estimated peak memory exceeds :data:`MEMORY_LIMIT`, or whose estimated time exceeds
:data:`MAX_SECONDS`, is refused with its estimate (:func:`estimate_run`), before any work starts.

For realization ``l`` and fix ``i``: error ``e = dx - dx_hat`` (a posteriori),
prior error ``e_bar = dx - dx_hat_prior``, residual ``r = dz - H dx_hat_prior``.
The checks, each judged against its own sampling band at significance
``alpha`` (the bands are those of :mod:`kfcal_helpers.consistency`; z = ``norm.ppf(1 - alpha/2)``,
1.96 for alpha = 0.05):

1. ``mean_error``: ensemble mean of ``e`` against ``+-t_{N-1}(1 - alpha/2) s/sqrt(N)`` (s: ensemble std;
   ``consistency.t_band``).
2. ``covariance``: ensemble covariance of ``e`` against the filter's ``P``; variances
   against the chi-square interval ``P chi2_{N-1}(alpha/2, 1-alpha/2)/(N-1)`` (``variance_band``),
   correlations against the filter's, with Fisher's ``tanh(atanh(rho_P) +- z/sqrt(N-3))``
   (``correlation_band``).
3. ``orthogonality``: ``(1/N) sum (e - e_mean) dx_hat^T`` against
   ``+-z sqrt(P_kk mean(dx_hat_l^2)/N)`` (``normal_band``: the spread of a product of independent
   factors; slightly conservative, as the exact spread has the centred
   ``mean((dx_hat_l - mean dx_hat)^2) <= mean(dx_hat_l^2)``).
4. ``residual_independence``: the correlation ``sum r_i,a r_m,b / sqrt(sum r_i,a^2 sum r_m,b^2)``
   for every pair of fixes ``i < m`` against ``+-q/sqrt(N - 1 + q^2)``, ``q = t_{N-1}(1 - alpha/2)``
   (``uncentred_correlation_band``: exact for independent zero-mean Gaussian residuals, the correlation
   is the cosine of the angle between two vectors in R^N, and ``rho sqrt((N - 1)/(1 - rho^2))`` is
   Student-t with N - 1 degrees of freedom).
5. ``residual_variance``: ``(1/N) sum r_i r_i^T`` diagonal against ``S_i chi2_N/N`` (``variance_band``).
6. ``nees``: run-averaged ``e^T P^-1 e`` against ``chi2_{3N}/N`` bounds (``chi2_bounds``).
7. ``nis``: run-averaged ``r^T S^-1 r`` against ``chi2_{2N}/N`` bounds.

``inside_fraction`` is the share of entries (fix x component, or pair x component
for check 4, fix for NEES and NIS) inside the band; about ``1 - alpha`` for a
consistent filter.  The verdict judges the seven checks together, as one family (the course's one policy,
:meth:`kfcal_helpers.consistency.Check.bonferroni`): every entry's simultaneous band is at
``alpha / entries``, ``entries`` their total (:meth:`MonteCarloResult.entries`), so a consistent filter fails
one of them with probability at most ``alpha``.

Between fixes (``run_monte_carlo(..., between_fixes=True)``): the error at every
200 Hz sample, ``e(t_j) = dx(t_j) - dx_hat(t_j)`` with the predicted estimate
``dx_hat(t_i + k dt) = Phi^k dx_hat_post(t_i)``, is summed over realizations as well
(memory independent of N), and :meth:`MonteCarloResult.between_fixes_check` compares
its ensemble variance at every sample with the filter's ``P_kk(t_j)`` against the
chi-square interval ``P_kk chi2_{N-1}(level/2, 1-level/2)/(N-1)`` (its own family of
entries at ``alpha``: the seven checks above are not changed by it, and over all eight checks a
consistent filter fails somewhere with probability at most ``2 alpha``).  The error state is linear:
within the GPS period that starts at fix ``i``,
``e(t_i + k dt) = Phi_f^k e_i + (Phi^k - Phi_f^k) dx_i + l_k + d_k`` (``Phi_f`` the filter's model,
``Phi`` the true one, ``l_k`` the IMU noise integrated since the fix, ``d_k`` the deterministic mismatch of
the analytic truth), so the batch filter keeps, per period, sums of products of a few per-realization
numbers with the IMU noise and, for periods of at most 64 IMU samples, the Gram matrix of the period's
IMU noise (longer periods: sums of products with its running sums), never a (n, n_imu, 3) array; the
moments at every sample follow at the end.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .. import montecarlo as core
from ..consistency import (Check, chi2_bounds, correlation_band, normal_band, t_band, uncentred_correlation_band,
                           variance_band)
from functools import partial

from ..validation import (MAX_COUNT, checked, describe, optional, require_bool, require_choice, require_finite,
                          require_instance, require_int, require_mask, require_significance, require_workers)
from .engine import between_fixes, covariance_sequence, filter_estimates, filter_model
from .error_model import ErrorStateModel, error_state_model
from .filters import run_filterpy
from .params import CalibrationParams
from .simulation import (TRUTH_MODELS, draw_realizations, error_state_at_fixes, error_state_full,
                         mean_error_state)

__all__ = ["CHUNK_SIZE", "MEMORY_LIMIT", "MAX_SECONDS", "chunk_size", "chunk_sizes", "chunk_generators",
           "chunks_in_flight", "default_workers", "estimate_run", "require_engine", "ENGINES", "FILTERS",
           "CHECK_NAMES", "ASSIGNMENT_CHECKS", "Check",
           "MonteCarloResult", "BetweenFixes", "CalibrationExperiment", "run_monte_carlo"]

CHUNK_SIZE = 500  #: most realizations simulated together (see chunk_size)
MEMORY_LIMIT = core.MEMORY_LIMIT  #: bytes, the estimated peak memory (resident) a run may need
MAX_SECONDS = core.MAX_SECONDS  #: s, the longest estimated one-thread run accepted
default_workers = core.default_workers  #: the core's: KFCAL_WORKERS, else min(2, os.cpu_count())

# The chunk-size rule (fixed: it decides which realizations each chunk draws, so every quoted result
# depends on it; bytes per realization of the first version of the 200 Hz sums, conservative today)
_RULE_FIXED, _RULE_FIXED_PER_SAMPLE = 130e6, 100.0
_RULE_SUMS_PER_FIX2, _RULE_SUMS_PER_SAMPLE = 40.0, 200.0
_RULE_PER_SAMPLE, _RULE_PER_FIX = 16.0 + 80.0, 400.0
_RULE_PARTIAL_PER_FIX2, _RULE_PARTIAL_PER_SAMPLE = 72.0, 100.0

# Cost model of the estimate, measured (tracemalloc, VmHWM of a child, wall time) on the 2-core
# reference machine and rounded up (tests/test_calibration_montecarlo.py and
# tests/test_calibration_memory.py check it against tracemalloc and the child's peak):
# * the interpreter (the core's BASE_BYTES); per IMU sample what the whole run keeps (the filter's P);
# * the sums: per fix squared, and with between_fixes per IMU sample;
# * per chunk in flight its realizations (per IMU sample and per fix of one realization; with
#   between_fixes the running sums of the IMU noise, and for filterpy its 200 Hz estimates) and its
#   partial sums;
# * at the end, the statistics of the checks (per fix squared: the pairwise residual statistics; per
#   IMU sample with between_fixes: the 200 Hz moments);
# * seconds per IMU sample of one realization on one thread, and per fix squared.
_FIXED_BYTES_PER_SAMPLE = 100.0
_SUMS_BYTES_PER_FIX2 = 40.0
_BYTES_PER_SAMPLE, _BYTES_PER_FIX = 16.0, 400.0
_BETWEEN_BYTES_PER_SAMPLE = {"batch": 16.0, "filterpy": 80.0}
_PARTIAL_BYTES_PER_FIX2 = 72.0
_STATS_BYTES_PER_FIX2 = 260.0
_STATS_BYTES_PER_SAMPLE, _STATS_BYTES_PER_BLOCK_SAMPLE, _BLOCK_SAMPLES = 400.0, 700.0, 65536
_POWERS_BYTES_PER_STEP = 700.0
_ROWS = 32  #: realizations whose 200 Hz running sums are formed at a time (between_fixes, batch filter, long periods)
#: longest GPS period (IMU samples) whose 200 Hz sums are kept as per-period Gram matrices of the IMU
#: noise (between_fixes, batch filter: 2 r flops per sample in BLAS instead of two running sums)
_GRAM_MAX_STEPS = 64
_GRAM_ROWS = 128  #: realizations per product in the Gram form (r x rows x r below OpenBLAS's threading size)
_SECONDS_PER_SAMPLE = {"batch": 1.5e-7, "filterpy": 6e-6}
_SECONDS_PER_FIX2 = 3e-6
ENGINES = ("batch", "filterpy")  #: the engines run_monte_carlo can run the filter with
#: the calibration's filter algorithms, in the sense of ``coop.FILTERS`` and ``orbit.FILTERS``: the linear
#: Kalman filter (``filter`` of a MonteCarloResult)
FILTERS = ("kf",)
CHECK_NAMES = ("mean_error", "covariance", "orthogonality", "residual_independence",
               "residual_variance", "nees", "nis")
#: the checks the assignment asks for: mean error, covariance, orthogonality and the residuals' independence,
#: whose "~ S_i for i = m" part is residual_variance (checks 1-4 of notebook 06; NEES and NIS are extra)
ASSIGNMENT_CHECKS = CHECK_NAMES[:5]


@dataclass
class MonteCarloResult:
    """Ensemble statistics at the GPS fixes (n_gps fixes, N = n_runs realizations).

    t_gps (n_gps,) s; P_prior, P_post (n_gps, 3, 3) and S (n_gps, 2, 2) from the filter;
    e_mean, e_prior_mean (n_gps, 3); e_cov, e_prior_cov (n_gps, 3, 3) ensemble
    statistics of the a posteriori / a priori errors; orthogonality (n_gps, 3, 3);
    xhat_sq_mean (n_gps, 3); residual_moment (n_gps, 2, n_gps, 2) = (1/N) sum r r^T (NaN at missing
    fixes); nees (n_gps,), nis (n_gps,) run averages (NaN at missing fixes for NIS);
    filter: the algorithm, "kf" (the linear Kalman filter; "lkf", "ekf", "ukf" in the other problems);
    engine: how it was run, "batch" (vectorised) or "filterpy" (one KalmanFilter per realization);
    seconds: wall time of simulation + filtering + statistics.
    The interface shared by every problem (``kfcal_helpers.consistency.MonteCarloSummary``):
    ``n_runs``, ``alpha``, ``filter``, ``seconds``, ``checks()`` (printed by
    ``kfcal_helpers.consistency.format_checks``).
    """

    params: CalibrationParams
    n_runs: int
    filter: str
    engine: str
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

    def band(self, name: str, level: float) -> tuple:
        """``(statistic, expected, lower, upper)`` of the check ``name`` (one of :data:`CHECK_NAMES`)
        at per-entry significance ``level``; the bands come from :mod:`kfcal_helpers.consistency`."""
        require_choice("name", name, CHECK_NAMES)
        N = self.n_runs
        if name == "mean_error":
            half = t_band(np.sqrt(np.einsum("iaa->ia", self.e_cov)), N, level)
            return self.e_mean, 0 * half, -half, half
        Pkk = np.einsum("iaa->ia", self.P_post)
        if name == "covariance":
            iu = np.triu_indices(3)
            diag = iu[0] == iu[1]
            # variances: exact chi-square interval; correlations: Fisher's z-transform
            stat = self.e_cov[:, iu[0], iu[1]].copy()
            expected = self.P_post[:, iu[0], iu[1]].copy()
            Ekk = np.einsum("iaa->ia", self.e_cov)
            stat[:, ~diag] /= np.sqrt(Ekk[:, iu[0][~diag]] * Ekk[:, iu[1][~diag]])
            expected[:, ~diag] /= np.sqrt(Pkk[:, iu[0][~diag]] * Pkk[:, iu[1][~diag]])
            lo, hi = correlation_band(expected, N, level)
            lo[:, diag], hi[:, diag] = variance_band(Pkk, N - 1, level)
            return stat, expected, lo, hi
        if name == "orthogonality":
            half = normal_band(Pkk[:, :, None] * self.xhat_sq_mean[:, None, :], N, level)
            return self.orthogonality, 0 * half, -half, half
        ok = ~self.missing
        if name in ("residual_independence", "residual_variance"):
            M = self.residual_moment[ok][:, :, ok, :]
            Md = np.einsum("iaia->ia", M)
            if name == "residual_variance":
                Sd = np.einsum("iaa->ia", self.S[ok])
                return (Md, Sd, *variance_band(Sd, N, level))
            # uncentred correlation of two independent zero-mean Gaussians (the cosine of the angle between
            # two vectors in R^N): t = rho sqrt((N - 1) / (1 - rho^2)) ~ t_{N-1}
            i, m = np.triu_indices(M.shape[0], k=1)
            rho = M[i, :, m, :] / np.sqrt(Md[i][:, :, None] * Md[m][:, None, :])
            half = np.full_like(rho, uncentred_correlation_band(N, level))
            return rho, 0 * half, -half, half
        dim, stat = (3, self.nees) if name == "nees" else (2, self.nis[ok])
        lo, hi = chi2_bounds(dim, N, level)
        return stat, np.full_like(stat, dim), np.full_like(stat, lo), np.full_like(stat, hi)

    def bands(self, level: float) -> dict:
        """``{check: (statistic, expected, lower, upper)}`` at per-entry significance ``level``
        (:meth:`band` of every check)."""
        return {name: self.band(name, level) for name in CHECK_NAMES}

    def entries(self, name: str) -> int:
        """The number of entries of the check ``name`` (one of :data:`CHECK_NAMES`): fix x component
        (x 6 covariance entries, x 9 orthogonality entries), pair of present fixes x 4 for
        ``residual_independence``, present fix x 2 for ``residual_variance``, fix for ``nees`` and present
        fix for ``nis``; counted from the shapes, without computing the check."""
        require_choice("name", name, CHECK_NAMES)
        n_gps, n_ok = self.e_mean.shape[0], int((~self.missing).sum())
        return {"mean_error": 3 * n_gps, "covariance": 6 * n_gps, "orthogonality": 9 * n_gps,
                "residual_independence": 4 * (n_ok * (n_ok - 1) // 2), "residual_variance": 2 * n_ok,
                "nees": n_gps, "nis": n_ok}[name]

    def checks(self, names=CHECK_NAMES) -> dict[str, Check]:
        """The seven checks (see the module docstring), keyed by :data:`CHECK_NAMES`; or, with ``names``
        (some of :data:`CHECK_NAMES`, e.g. :data:`ASSIGNMENT_CHECKS`), those checks alone.

        The checks asked for are judged together, as one family (the course's one policy,
        :meth:`kfcal_helpers.consistency.Check.bonferroni`): every entry's simultaneous band is at
        ``alpha / entries``, ``entries`` the total number of entries of those checks (:meth:`entries`;
        48,622 for the seven checks at the 151 fixes of the defaults), so a consistent filter leaves some
        entry of them outside with probability at most ``alpha``."""
        names = tuple(require_choice("names", n, CHECK_NAMES) for n in names)
        if not names:
            raise ValueError("names must name at least one check, got an empty list")
        family = Check.bonferroni(self.alpha, sum(self.entries(name) for name in dict.fromkeys(names)))
        out = {}
        for name in names:  # one check at a time: its pointwise and simultaneous bands only
            stat, expected, lo, hi = self.band(name, self.alpha)
            slo, shi = self.band(name, family)[2:]
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
        return Check.from_band("between_fixes", _BETWEEN_DESCRIPTION, var, Pkk,
                               partial(variance_band, Pkk, self.n_runs - 1), self.alpha,
                               Check.bonferroni(self.alpha, var.size))

    def all_checks(self) -> dict[str, Check]:
        """:meth:`checks`, and ``between_fixes`` (:meth:`between_fixes_check`) when the run summed the
        200 Hz error and some IMU samples lie between fixes: what the command line prints."""
        out = self.checks()
        if self.between is not None and self.params.n_imu > self.params.n_gps:
            out["between_fixes"] = self.between_fixes_check()
        return out


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


# Sums over realizations ---------------------------------------------------------------------------
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


class _BetweenSums:
    """Sums of the 200 Hz error ``e`` and ``e e^T`` over realizations, from the error itself (the
    filterpy engine, whose estimates at 200 Hz are its own): O(n_imu) memory, whatever N."""

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

    def moments(self, setup=None):
        return self.e, self.ee


class _BetweenMoments:
    """The 200 Hz error's sums for the batch filter, by linearity, without the 200 Hz error itself.

    In the GPS period of fix ``i`` (samples ``J = i r + k``, k = 0..r-1) the true error state is
    ``dx_J = Phi^k dx_i + l_J + d_J``: the Euler model is exact for the IMU noise, whose part since the
    fix is ``l_J = (-dt^2 u, -dt s, 0)`` with ``s = sum_{q<k} w_{ir+q}`` and ``u = sum_{q<k} s_q + s/2``,
    and ``d_J`` is the deterministic part (zero for the Euler truth,
    :func:`~.simulation.mean_error_state` for the analytic one).  With the running sums of the IMU
    noise over the whole realization, ``c_j = sum_{l<=j} w_l`` and ``b_j = sum_{m<j} c_m``, read at
    ``j = J - 1``: ``s = c - C_i`` and ``u = b + c/2 - B_i - (k + 1/2) C_i`` (``C_i, B_i``: the same just
    before the fix).  The estimate is ``Phi_f^k x_post_i``, so ``e_J = G_k y_i + M (c, b) + d_J``
    with per-realization numbers ``y_i = [e_post_i, (dx_i if Phi_f != Phi), C_i, B_i]``, fixed matrices
    ``G_k`` and ``M (c, b) = (-dt^2 (b + c/2), -dt c, 0)``.  Kept, summed over realizations: ``[y, 1]
    [y, 1]^T`` per period (n_gps, D, D), ``[y, 1] c`` per period and sample (n_gps, D, r; the same with
    ``b`` follows, as ``b_{ir+q} = B_i + C_i + sum_{q'<q} c_{ir+q'}``) and ``c^2, c b, b^2`` per sample
    (3, n_imu); the first two moments of ``e`` at every sample follow from them in :meth:`moments`.
    Two forms of these sums (the same moments, to rounding): for GPS periods of at most
    :data:`_GRAM_MAX_STEPS` samples, per period ``sum [y, 1] w`` (n_gps, D, r) and the Gram matrix of
    the IMU noise ``sum w w^T`` (n_gps, r, r), batched BLAS products on views of the draws (:meth:`add_gram`;
    the sums above follow in :meth:`running_sums`, as the running sums within a period are fixed
    linear maps of its noise); for longer periods, two running sums and four sums of products over
    (n, n_imu) arrays, a few realizations at a time (:meth:`add_running`).  No (n, n_imu, 3) array.
    """

    def __init__(self, n_gps: int, r: int, n_imu: int, n_vars: int, gram: bool | None = None):
        self.n = 0
        self.gram = r <= _GRAM_MAX_STEPS if gram is None else bool(gram)
        self.yy = np.zeros((n_gps, n_vars + 1, n_vars + 1))
        if self.gram:  # sum [y, 1] w and sum w w^T per period (see add_gram)
            self.yw = np.zeros((n_gps, n_vars + 1, r))
            self.ww = np.zeros((n_gps, r, r))
        else:
            self.yc = np.zeros((n_gps, n_vars + 1, r))
            self.ll = np.zeros((3, n_imu))

    def add(self, params: CalibrationParams, w, y):
        """Add one chunk: ``w`` (n, n_imu) its IMU noise (may be overwritten), ``y`` (n, n_gps, n_vars - 2)
        its ``[e_post, (dx)]`` at the fixes (:meth:`add_gram` or :meth:`add_running`)."""
        if self.gram:
            self.add_gram(params, w, y)
        else:
            self.add_running(params, w, y)

    def add_gram(self, params: CalibrationParams, w, y):
        """Add one chunk without running sums (short GPS periods): per period ``i``, ``sum [y, 1] w_{ir+q}``
        (n_gps, D, r) and the Gram matrix ``sum w_{ir+p} w_{ir+q}`` (n_gps, r, r), batched BLAS products
        on views of ``w``, :data:`_GRAM_ROWS` realizations at a time (small products: BLAS runs them on
        the calling thread).  The running sums within a period are fixed linear maps of its ``w``, so
        :meth:`running_sums` forms their sums of products from these.  ``C_i`` and ``B_i`` cancel from
        ``e`` (the IMU noise since the fix is ``s = c - C_i`` and ``u = b + c/2 - B_i - (k + 1/2) C_i``,
        and within the period ``c = C_i + (w L)``, ``b = B_i + (q + 1) C_i + (w L2)``), so this form
        keeps them at zero: the same moments, without the large terms that cancel."""
        n, n_gps, r, n_imu = len(w), params.n_gps, params.steps_per_fix, params.n_imu
        nf, last = n_gps - 1, n_imu - (n_gps - 1) * r
        self.n += n
        ny = y.shape[2]
        cols = np.r_[0:ny, ny + 2]  # the columns [y, 1] of [y, C_i, B_i, 1]; C_i = B_i = 0 (see above)
        yy, yw = np.zeros((n_gps, ny + 1, ny + 1)), np.zeros((n_gps, ny + 1, r))
        for l0 in range(0, n, _GRAM_ROWS):
            rows = min(_GRAM_ROWS, n - l0)
            wr = w[l0:l0 + rows]
            periods = wr[:, : nf * r].reshape(rows, nf, r)  # a view: row-contiguous periods
            yT = np.empty((n_gps, ny + 1, rows))  # [y, 1]
            yT[:, :ny] = y[l0:l0 + rows].transpose(1, 2, 0)
            yT[:, ny] = 1.0
            yy += yT @ yT.transpose(0, 2, 1)
            if nf > 0:
                blk = periods.transpose(1, 0, 2)  # (nf, rows, r), a view
                yw[:nf] += yT[:nf] @ blk
                self.ww[:nf] += blk.transpose(0, 2, 1) @ blk
            wl = wr[:, nf * r:]
            yw[nf, :, :last] += yT[nf] @ wl
            self.ww[nf, :last, :last] += wl.T @ wl
        self.yy[:, cols[:, None], cols[None, :]] += yy
        self.yw[:, cols] += yw

    def add_running(self, params: CalibrationParams, w, y):
        """Add one chunk: ``w`` (n, n_imu) its IMU noise (overwritten by its running sum), ``y``
        (n, n_gps, n_vars - 2) its ``[e_post, (dx)]`` at the fixes.  The realizations are taken
        :data:`_ROWS` at a time, so that each one's running sums are still in the cache when they are
        multiplied."""
        n, n_gps, r, n_imu = len(w), params.n_gps, params.steps_per_fix, params.n_imu
        fix = params.fix_indices
        nf, last = n_gps - 1, n_imu - (n_gps - 1) * r  # full periods; samples from the last fix on
        b_rows = np.empty((min(n, _ROWS), n_imu))
        self.n += n
        for l0 in range(0, n, _ROWS):
            rows = min(_ROWS, n - l0)
            c = np.cumsum(w[l0:l0 + rows], axis=1, out=w[l0:l0 + rows])  # in place: c_j = sum_{l <= j} w_l
            b = b_rows[:rows]  # b_j = sum_{m < j} c_m
            b[:, 0] = 0.0
            np.cumsum(c[:, :-1], axis=1, out=b[:, 1:])
            y1 = np.zeros((rows, n_gps, y.shape[2] + 3))  # [y, C_i, B_i, 1]; C_0 = B_0 = 0
            y1[..., :-3] = y[l0:l0 + rows]
            y1[:, 1:, -3], y1[:, 1:, -2] = c[:, fix[1:] - 1], b[:, fix[1:] - 1]
            y1[..., -1] = 1.0
            yT = np.ascontiguousarray(y1.transpose(1, 2, 0))  # (n_gps, D, rows)
            self.yy += yT @ yT.transpose(0, 2, 1)
            # period i, column q: c at j = i r + q (the sums with b follow from these, see moments)
            if nf > 0:
                self.yc[:nf] += yT[:nf] @ c[:, : nf * r].reshape(rows, nf, r).transpose(1, 0, 2)
            self.yc[nf, :, :last] += yT[nf] @ c[:, nf * r:]
            self.ll[0] += np.einsum("nj,nj->j", c, c)
            self.ll[1] += np.einsum("nj,nj->j", c, b)
            self.ll[2] += np.einsum("nj,nj->j", b, b)

    def combine(self, other: "_BetweenMoments"):
        self.n += other.n
        self.yy += other.yy
        if self.gram:
            self.yw += other.yw
            self.ww += other.ww
        else:
            self.yc += other.yc
            self.ll += other.ll

    def running_sums(self, params: CalibrationParams):
        """``(yc, ll)`` of the running-sum form (see the class docstring), from the Gram form's sums:
        within period ``i``, ``c_{ir+q} = C_i + (w L)_q`` and ``b_{ir+q} = B_i + (q + 1) C_i + (w L2)_q``
        with ``L_pq = [p <= q]`` and ``L2_pq = max(q - p, 0)``."""
        if not self.gram:
            return self.yc, self.ll
        n_imu, r = params.n_imu, params.steps_per_fix
        nv = self.yy.shape[1] - 1
        ic, ib = nv - 2, nv - 1  # the columns C_i, B_i of [y, 1]
        p, q = np.arange(r)[:, None], np.arange(r)[None, :]
        L = (p <= q).astype(float)
        L2 = np.maximum(q - p, 0).astype(float)
        yy, W = self.yy, self.ww
        ywL, ywL2 = self.yw @ L, self.yw @ L2  # (n_gps, D, r): sum [y, 1] (w L), sum [y, 1] (w L2)
        yc = yy[:, :, ic, None] + ywL
        k1 = np.arange(1, r + 1, dtype=float)  # q + 1
        cC, cB, bB = yy[:, ic, ic, None], yy[:, ic, ib, None], yy[:, ib, ib, None]
        WL, WL2 = W @ L, W @ L2
        lcl = np.einsum("pq,ipq->iq", L, WL)  # diag(L^T W L): sum (w L)_q^2
        lcb = np.einsum("pq,ipq->iq", L, WL2)  # diag(L^T W L2)
        lbb = np.einsum("pq,ipq->iq", L2, WL2)  # diag(L2^T W L2)
        cc = cC + 2 * ywL[:, ic] + lcl
        cb = (cB + k1 * cC) + ywL2[:, ic] + (ywL[:, ib] + k1 * ywL[:, ic]) + lcb
        bb = (bB + 2 * k1 * cB + k1 * k1 * cC) + 2 * (ywL2[:, ib] + k1 * ywL2[:, ic]) + lbb
        ll = np.stack([cc, cb, bb]).reshape(3, -1)[:, :n_imu]
        return yc, ll

    def moments(self, setup: "_Setup"):
        """``(sum e, sum e e^T)`` over realizations at every IMU sample, (n_imu, 3) and (n_imu, 3, 3)."""
        params = setup.params
        n_gps, r, n_imu, dt = params.n_gps, params.steps_per_fix, params.n_imu, params.dt
        G = setup.G  # (r, 3, n_vars)
        nv = G.shape[2]
        N = self.n
        E1 = np.empty((n_gps * r, 3))
        E2 = np.empty((n_gps * r, 3, 3))
        yc_all, ll_j = self.running_sums(params)
        ll = np.zeros((3, n_gps * r))
        ll[:, 1:n_imu] = ll_j[:, : n_imu - 1]  # sample J reads the running sums at J - 1
        ll = ll.reshape(3, n_gps, r)
        step = max(1, _BLOCK_SAMPLES // r)  # periods at a time: temporaries of at most 65536 + r samples
        for i0 in range(0, n_gps, step):
            i1 = min(n_gps, i0 + step)
            yy = self.yy[i0:i1]
            A1 = np.einsum("kad,id->ika", G, yy[:, :nv, nv])
            A2 = (G[None] @ yy[:, None, :nv, :nv]) @ np.swapaxes(G, 1, 2)[None]
            if r > 1:  # M (c, b) at the samples k >= 1 (column k - 1 of the period)
                Yc = yc_all[i0:i1, :, : r - 1]  # (periods, D, r - 1)
                # b_{ir+q} = B_i + C_i + sum_{q' < q} c_{ir+q'}, and C_i, B_i are columns of y
                Yb = np.empty_like(Yc)
                Yb[..., 0] = 0.0
                np.cumsum(Yc[..., :-1], axis=2, out=Yb[..., 1:])
                Yb += (yy[:, :, nv - 1] + yy[:, :, nv - 2])[:, :, None]
                Yp = -dt * dt * (Yb + 0.5 * Yc)  # sum [y, 1] l_p
                Yv = -dt * Yc  # sum [y, 1] l_v
                A1[:, 1:, 0] += Yp[:, nv]
                A1[:, 1:, 1] += Yv[:, nv]
                Z = np.zeros((i1 - i0, r - 1, nv, 3))
                Z[..., 0] = np.swapaxes(Yp[:, :nv], 1, 2)
                Z[..., 1] = np.swapaxes(Yv[:, :nv], 1, 2)
                cross = G[None, 1:] @ Z
                A2[:, 1:] += cross + np.swapaxes(cross, 2, 3)
                cc, cb, bb = ll[0, i0:i1, 1:], ll[1, i0:i1, 1:], ll[2, i0:i1, 1:]
                A2[:, 1:, 0, 0] += dt**4 * (bb + cb + 0.25 * cc)
                pv = dt**3 * (cb + 0.5 * cc)
                A2[:, 1:, 0, 1] += pv
                A2[:, 1:, 1, 0] += pv
                A2[:, 1:, 1, 1] += dt * dt * cc
            E1[i0 * r: i1 * r] = A1.reshape(-1, 3)
            E2[i0 * r: i1 * r] = A2.reshape(-1, 3, 3)
        E1, E2 = E1[:n_imu], E2[:n_imu]
        if setup.offset is not None:  # the deterministic part d_J
            d = setup.offset
            E2 += np.einsum("ja,jb->jab", d, E1) + np.einsum("ja,jb->jab", E1, d) + N * np.einsum("ja,jb->jab", d, d)
            E1 += N * d
        return E1, E2


def _between_result(params: CalibrationParams, bsums, setup, P: np.ndarray) -> BetweenFixes:
    N = bsums.n
    e, ee = bsums.moments(setup)
    mean = e / N
    cov = (ee - N * np.einsum("ja,jb->jab", mean, mean)) / (N - 1)
    return BetweenFixes(params.t_imu, P, mean, cov)


# Chunks and memory -------------------------------------------------------------------------------
def chunk_size(params: CalibrationParams) -> int:
    """Realizations simulated together for ``params``: :data:`CHUNK_SIZE`, or fewer when the
    realizations are long (a fixed rule on the numbers of IMU samples and GPS fixes; at least 1;
    :func:`estimate_run` refuses runs where even 1 does not fit).  It depends on neither
    ``between_fixes``, ``engine`` nor ``workers``, so the random draws, and the seven checks, are the
    same with and without them."""
    require_instance("params", params, CalibrationParams)
    n_imu, n_gps = params.n_imu, params.n_gps
    room = (MEMORY_LIMIT - _RULE_FIXED - _RULE_FIXED_PER_SAMPLE * n_imu
            - (_RULE_SUMS_PER_FIX2 * n_gps**2 + _RULE_SUMS_PER_SAMPLE * n_imu)
            - (_RULE_PARTIAL_PER_FIX2 * n_gps**2 + _RULE_PARTIAL_PER_SAMPLE * n_imu))
    return int(max(1, min(CHUNK_SIZE, room // (_RULE_PER_SAMPLE * n_imu + _RULE_PER_FIX * n_gps))))


def chunk_sizes(params: CalibrationParams, n_runs: int) -> list[int]:
    """The sizes of the chunks of a run of ``n_runs`` realizations, in order."""
    return core.chunk_sizes(chunk_size(params), n_runs)


def chunk_generators(params: CalibrationParams, n_runs: int, seed) -> list[tuple[int, np.random.Generator]]:
    """``(size, generator)`` of every chunk of :func:`run_monte_carlo` (the core's
    :func:`kfcal_helpers.montecarlo.chunk_generators` with :func:`chunk_size`): chunk ``c`` draws its
    realizations (with ``simulation.draw_realizations``, the draws of ``simulate``) from its own stream,
    ``numpy.random.Generator(numpy.random.PCG64DXSM(numpy.random.SeedSequence(seed).spawn(n_chunks)[c]))``;
    for a Generator ``seed``, from ``seed.spawn(n_chunks)``.  So a chunk's numbers do not depend on
    which thread runs it."""
    return core.chunk_generators(chunk_size(params), n_runs, seed)


@dataclass
class _Setup:
    """What every chunk shares (read only), computed when the run starts."""

    params: CalibrationParams
    model: ErrorStateModel
    missing: np.ndarray
    P: np.ndarray
    P_prior: np.ndarray
    S: np.ndarray
    K: np.ndarray
    G: np.ndarray | None  # (r, 3, n_vars) the 200 Hz error from [e_post, (dx), S_i] (batch, between)
    with_dx: bool
    truth: str
    offset: np.ndarray | None  # (n_imu, 3) the deterministic part of the 200 Hz error (analytic truth)


class CalibrationExperiment:
    """The calibration Monte Carlo as a :class:`kfcal_helpers.montecarlo.Experiment` of the shared core.

    Built from validated settings (see :func:`run_monte_carlo`); cheap to build, so that
    :func:`estimate_run` can ask it its memory and time before anything of the scenario's size exists.
    The data-independent part of the filter (covariances, gains) is computed in :meth:`prepare`, which
    the core calls when the run starts.  Sizes in bytes, times in seconds.
    """

    def __init__(self, params: CalibrationParams, *, engine: str = "batch", truth: str = "euler",
                 alpha: float = 0.05, missing=None, model: ErrorStateModel | None = None,
                 between_fixes: bool = False, filter: str | None = None):
        self.params, self.truth, self.alpha = params, truth, alpha
        self.engine = require_engine(engine, filter)
        self.missing = np.zeros(params.n_gps, bool) if missing is None else missing
        self.given_model = model
        self.between = between_fixes
        self.setup: _Setup | None = None

    # memory and time ---------------------------------------------------------------------------
    def chunk_size(self) -> int:
        return chunk_size(self.params)

    def _between_sums_bytes(self) -> float:
        p = self.params
        if not self.between:
            return 0.0
        if self.engine == "filterpy":
            return 96.0 * p.n_imu
        d = 9 if self.given_model is not None else 6  # [e_post, (dx), C_i, B_i, 1]
        r = p.steps_per_fix
        per_sample = r * r * p.n_gps if r <= _GRAM_MAX_STEPS else 3 * p.n_imu  # the Gram matrices, or ll
        return 8.0 * (p.n_gps * d * d + d * p.n_gps * r + per_sample)

    def _gram_bytes(self) -> float:
        """One (n_gps, r, r) array of the Gram form of the 200 Hz sums (0 when it is not used)."""
        p = self.params
        use = self.between and self.engine == "batch" and p.steps_per_fix <= _GRAM_MAX_STEPS
        return 8.0 * p.n_gps * p.steps_per_fix**2 if use else 0.0

    def fixed_bytes(self, n_runs: int) -> float:
        """The interpreter, the filter's covariances and the sums of the whole run."""
        p = self.params
        return (core.BASE_BYTES + _FIXED_BYTES_PER_SAMPLE * p.n_imu + _SUMS_BYTES_PER_FIX2 * p.n_gps**2
                + self._between_sums_bytes())

    def chunk_bytes(self, size: int) -> float:
        """One chunk of ``size`` realizations in flight: its draws, its filtering and its partial sums."""
        p = self.params
        per_sample = _BYTES_PER_SAMPLE + (_BETWEEN_BYTES_PER_SAMPLE[self.engine] if self.between else 0.0)
        return (size * (per_sample * p.n_imu + _BYTES_PER_FIX * p.n_gps)
                + _PARTIAL_BYTES_PER_FIX2 * p.n_gps**2 + self._between_sums_bytes()
                + self._gram_bytes())  # a product before it is added

    def final_bytes(self, n_runs: int) -> float:
        """The statistics of the checks at the end (the pairwise residual statistics; with
        between_fixes the 200 Hz moments, and the temporaries of a block of periods), or the start
        (the powers of Phi over one GPS period, twice), whichever is larger."""
        p = self.params
        r = p.steps_per_fix
        start = _POWERS_BYTES_PER_STEP * (r + 1)
        end = _STATS_BYTES_PER_FIX2 * p.n_gps**2
        if self.between:
            end += (_STATS_BYTES_PER_SAMPLE * p.n_imu
                    + _STATS_BYTES_PER_BLOCK_SAMPLE * min(p.n_imu, _BLOCK_SAMPLES + r)
                    + 2 * self._gram_bytes())  # W L and W L2 (running_sums)
        return max(start, end)

    def seconds(self, n_runs: int) -> float:
        p = self.params
        return _SECONDS_PER_SAMPLE[self.engine] * p.n_imu * float(n_runs) + _SECONDS_PER_FIX2 * p.n_gps**2

    def what(self) -> str:
        p = self.params
        return f"one realization of {p.n_imu} IMU samples and {p.n_gps} GPS fixes, engine {self.engine!r}"

    def scenario_advice(self) -> str:
        return _SCENARIO_ADVICE

    # the run -----------------------------------------------------------------------------------
    def prepare(self) -> None:
        """The filter's covariances and gains (and with between_fixes the 200 Hz forms), which every
        chunk reads: computed once, after the estimate accepted the run."""
        p = self.params
        m = filter_model(p, self.given_model)
        P, P_prior, S, K = covariance_sequence(p, self.missing, m)
        G, with_dx, offset = None, False, None
        if self.between and self.engine == "batch":
            r = p.steps_per_fix
            Pf = between_fixes(p, m)[0][:r]  # the filter's Phi^k
            Pt = between_fixes(p, error_state_model(p))[0][:r]  # the true one
            with_dx = not np.array_equal(Pf, Pt)
            g = np.zeros((r, 3, 2))  # the columns of C_i and B_i, for k >= 1 (at the fix, k = 0: none)
            g[1:, 0, 0] = p.dt * p.dt * (np.arange(1, r) + 0.5)
            g[1:, 1, 0] = p.dt
            g[1:, 0, 1] = p.dt * p.dt
            G = np.concatenate([Pf, Pt - Pf, g] if with_dx else [Pf, g], axis=2)
            if self.truth != "euler":
                c = mean_error_state(p, self.truth)
                fix = p.fix_indices
                base = np.repeat(c[fix], r, axis=0)[: p.n_imu]  # c at the fix of each sample's period
                k = np.tile(np.arange(r), p.n_gps)[: p.n_imu]
                offset = c - np.einsum("jab,jb->ja", Pt[k], base)
        self.setup = _Setup(p, m, self.missing, P, P_prior, S, K, G, with_dx, self.truth, offset)

    def empty(self, n_runs: int):
        return self._new_sums()

    def _new_sums(self):
        p = self.params
        sums = _Sums(p.n_gps, int((~self.missing).sum()))
        if not self.between:
            return sums, None
        if self.engine == "filterpy":
            return sums, _BetweenSums(p.n_imu)
        return sums, _BetweenMoments(p.n_gps, p.steps_per_fix, p.n_imu, self.setup.G.shape[2])

    def run_chunk(self, size: int, rng: np.random.Generator, chunk: core.Chunk):
        """Draw, filter, and return the chunk's partial sums (and the 200 Hz ones with between_fixes)."""
        setup, params = self.setup, self.params
        missing = setup.missing
        draws = draw_realizations(params, size, rng)
        dx = error_state_at_fixes(params, draws, self.truth)
        dz = dx[..., :2] + draws.eta
        dz[:, missing] = np.nan
        if self.engine == "batch":
            x_prior, x_post, y = filter_estimates(params, dz, setup.K, missing, setup.model)
        else:
            x_prior, x_post = np.empty((size, params.n_gps, 3)), np.empty((size, params.n_gps, 3))
            y = np.empty((size, params.n_gps, 2))
            runs = np.empty((size, params.n_imu, 3)) if self.between else None  # filterpy's 200 Hz estimates
            for l in range(size):  # the bar moves with every realization (about 0.03 s each)
                chunk.check()
                res = run_filterpy(params, dz[l], self.given_model)
                x_prior[l], x_post[l], y[l] = res.x_prior, res.x_post, res.y
                if runs is not None:
                    runs[l] = res.x
                del res
                chunk.tick()
        sums, bsums = self._new_sums()
        sums.add(dx, x_prior, x_post, y[:, ~missing])
        if bsums is not None:
            if self.engine == "batch":
                e_post = dx - x_post
                bsums.add(params, draws.w, np.concatenate([e_post, dx], axis=2) if setup.with_dx else e_post)
            else:
                bsums.add(error_state_full(params, draws, self.truth), runs)
        return sums, bsums

    def add(self, total, part):
        total[0].combine(part[0])
        if total[1] is not None:
            total[1].combine(part[1])
        return total

    def result(self, total, n_runs: int, seconds: float) -> MonteCarloResult:
        start = time.perf_counter()
        sums, bsums = total
        setup, params = self.setup, self.params
        P, P_prior, S, missing = setup.P, setup.P_prior, setup.S, setup.missing
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
            params=params, n_runs=N, filter=FILTERS[0], engine=self.engine, truth=self.truth, alpha=self.alpha, seconds=0.0,
            t_gps=params.t_gps, missing=missing, P_prior=P_prior, P_post=P_post, S=S,
            e_mean=e_mean, e_cov=e_cov, e_prior_mean=eb_mean, e_prior_cov=eb_cov,
            orthogonality=orth, xhat_sq_mean=xx / N, residual_moment=moment, nees=nees, nis=nis,
            between=_between_result(params, bsums, setup, P) if bsums is not None else None)
        result.checks()  # the statistics are part of the timed work
        result.seconds = seconds + time.perf_counter() - start
        return result


def chunks_in_flight(params: CalibrationParams, n_runs: int, workers: int | None = None,
                     between_fixes: bool = False, engine: str = "batch", *, filter: str | None = None) -> int:
    """How many chunks run at once: ``workers`` (default :func:`default_workers`), but no more than
    there are chunks, nor than fit in :data:`MEMORY_LIMIT` (at least 1); the core's
    :func:`kfcal_helpers.montecarlo.estimate` (ValueError when the run does not fit at all)."""
    exp = CalibrationExperiment(params, engine=engine, filter=filter, between_fixes=between_fixes)
    return core.estimate(exp, n_runs, workers).in_flight


def estimate_run(params: CalibrationParams, n_runs: int, engine: str = "batch",
                 runs_name: str = "n_runs", params_name: str = "params",
                 extra_bytes: float = 0.0, between_fixes: bool = False,
                 workers: int | None = None, model: ErrorStateModel | None = None, *,
                 filter: str | None = None) -> tuple[float, float]:
    """Estimated ``(peak bytes, seconds)`` of :func:`run_monte_carlo`, with every chunk in flight
    counted (the core's :func:`kfcal_helpers.montecarlo.estimate`); ValueError, with the estimate,
    when the peak exceeds :data:`MEMORY_LIMIT` (naming ``params_name``: the scenario has too many IMU
    samples or GPS fixes) or the time exceeds :data:`MAX_SECONDS` (naming ``runs_name``).
    ``extra_bytes``: what the caller needs after the Monte Carlo, while its result is alive (the
    command line's output and figures).  The time is that of one thread (a conservative bound).
    ``engine`` and ``filter`` as in :func:`run_monte_carlo`."""
    require_instance("params", params, CalibrationParams)
    exp = CalibrationExperiment(params, engine=engine, filter=filter, between_fixes=bool(between_fixes), model=model)
    est = core.estimate(exp, n_runs, workers, extra_bytes=extra_bytes, runs_name=runs_name,
                        params_name=params_name)
    return est.peak_bytes, est.seconds


def require_engine(engine, filter=None) -> str:
    """The engine ``engine`` ("batch" or "filterpy") names, or that ``filter`` names in code written when
    ``filter`` meant the engine; ``filter`` may also be "kf", the algorithm (the only one).  ValueError
    naming the argument otherwise, or when ``filter`` and ``engine`` name different engines."""
    engine = require_choice("engine", engine, ENGINES)
    if filter is None or (isinstance(filter, str) and filter in FILTERS):
        return engine
    if not isinstance(filter, str) or filter not in ENGINES:
        raise ValueError(f"filter must be 'kf' (the linear Kalman filter; the engine is engine='batch' or "
                         f"'filterpy'), got {describe(filter)}")
    if engine != ENGINES[0] and filter != engine:
        raise ValueError(f"filter={filter!r} names an engine other than engine={engine!r}; give engine only")
    return filter


_SCENARIO_ADVICE = ("use a shorter duration or lower rates (at most about 1000 GPS fixes and 3 million IMU "
                    "samples)")


def _byte_count(name, value):
    value = require_finite(name, value)
    if value < 0:
        raise ValueError(f"{name} must be >= 0 bytes, got {value:g}")
    return value


@checked(n_runs=partial(require_int, minimum=2, maximum=MAX_COUNT), progress=optional(require_bool),
         between_fixes=require_bool, workers=optional(require_workers), extra_bytes=_byte_count)
def run_monte_carlo(params: CalibrationParams, n_runs: int, seed=0, *, engine: str = "batch",
                    truth: str = "euler", alpha: float = 0.05, missing_fixes=None, progress: bool | None = False,
                    model: ErrorStateModel | None = None, between_fixes: bool = False,
                    workers: int | None = None, extra_bytes: float = 0.0,
                    filter: str | None = None) -> MonteCarloResult:
    """Simulate ``n_runs`` realizations, filter them, and accumulate the check statistics.

    Parameters
    ----------
    params : CalibrationParams
    n_runs : int >= 2
    seed : int (or None: fresh entropy) seeding ``numpy.random.SeedSequence``, or a numpy.random.Generator;
        chunk ``c`` draws from its own stream (:func:`chunk_generators`)
    engine : "batch" (vectorised, shared gains) or "filterpy" (one KalmanFilter per run): how the filter
        runs; the same seed gives both the same draws
    truth : "euler" or "analytic"
    alpha : significance of the bands, in (0, 1)
    missing_fixes : optional bool array (n_gps,), fixes that are missing (outages)
    progress : show a progress bar (None: unless CI/KFCAL_QUIET is set)
    model : optional ErrorStateModel the filter assumes (default: the true one); the
        truth is always simulated with ``params``
    between_fixes : also accumulate the error at every 200 Hz sample (``result.between``,
        checked by ``result.between_fixes_check()``); memory O(n_imu), independent of N
    workers : threads running chunks at once (default :func:`default_workers`; fewer when the
        chunks would not fit in :data:`MEMORY_LIMIT`).  The result is the same, bit for bit, for any
        number: every chunk has its own random stream and the sums are added in chunk order.
    extra_bytes : bytes the caller needs while the result is alive (counted in the estimate)
    filter : the algorithm, "kf" (the only one, the linear Kalman filter; the result's ``filter``).
        Code written when ``filter`` named the engine still runs: ``filter="batch"`` or
        ``filter="filterpy"`` is read as ``engine=``.

    Returns
    -------
    MonteCarloResult

    Raises
    ------
    ValueError naming the argument: bad values, missing fixes leaving fewer than 2 fixes,
    or a run refused by :func:`estimate_run` (too much memory or time).
    """
    require_instance("params", params, CalibrationParams)
    engine = require_engine(engine, filter)
    require_choice("truth", truth, TRUTH_MODELS)
    alpha = require_significance("alpha", alpha)
    missing = require_mask("missing_fixes", missing_fixes, params.n_gps)
    missing = np.zeros(params.n_gps, bool) if missing is None else missing.copy()
    if (~missing).sum() < 2:
        raise ValueError(f"missing_fixes must leave at least 2 of the {params.n_gps} GPS fixes, "
                         f"got {int((~missing).sum())}")
    filter_model(params, model)  # validates model
    exp = CalibrationExperiment(params, engine=engine, truth=truth, alpha=alpha, missing=missing, model=model,
                                between_fixes=bool(between_fixes))
    return core.run(exp, n_runs, seed, workers=workers, progress=progress, desc=f"Monte Carlo ({engine})",
                    extra_bytes=extra_bytes)
