"""Monte Carlo validation of the calibration filter (seven checks at the GPS fixes, and one between them).

Realizations are simulated in chunks of at most :data:`CHUNK_SIZE` (the 200 Hz arrays of a
chunk are dropped once the chunk is filtered), and only sums over realizations
are kept, so memory does not grow with the number of runs.  The chunk size follows the
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

import time
from dataclasses import dataclass

import numpy as np
from scipy import stats

from ..consistency import Check, chi2_bounds
from ..progress import progress_bar as _progress_bar
from ..validation import require_choice, require_finite, require_int, require_seed
from .error_model import ErrorStateModel
from .filters import batch_filter, between_fixes as _between_fix_steps, covariance_sequence, run_filterpy
from .params import CalibrationParams
from .simulation import TRUTH_MODELS, simulate

__all__ = ["CHUNK_SIZE", "MEMORY_LIMIT", "MAX_SECONDS", "chunk_size", "estimate_run", "ENGINES", "CHECK_NAMES",
           "Check", "MonteCarloResult", "BetweenFixes", "run_monte_carlo", "format_checks"]

CHUNK_SIZE = 500  #: most realizations simulated together (see chunk_size)
MEMORY_LIMIT = 500e6  #: bytes, the estimated peak memory (resident) a run may need
MAX_SECONDS = 3600.0  #: s, the longest estimated run accepted
# Cost model, measured (tracemalloc, ru_maxrss, wall time) on the 2-core reference machine and
# rounded up: the interpreter with numpy and scipy; bytes per GPS fix squared (the pairwise
# residual statistics) and per IMU sample (the covariance sequence); bytes per IMU sample and
# per fix of one realization in a chunk; seconds per IMU sample of one realization.
_BASE_BYTES = 130e6
_FIXED_BYTES_PER_FIX2, _FIXED_BYTES_PER_SAMPLE = 340.0, 120.0
_BYTES_PER_SAMPLE, _BYTES_PER_FIX = 64.0, 256.0
_BETWEEN_BYTES_PER_SAMPLE = 48.0
_SECONDS_PER_SAMPLE = {"batch": 1.5e-7, "filterpy": 6e-6}
_SECONDS_PER_FIX2 = 3e-6
ENGINES = ("batch", "filterpy")
CHECK_NAMES = ("mean_error", "covariance", "orthogonality", "residual_independence",
               "residual_variance", "nees", "nis")


@dataclass
class MonteCarloResult:
    """Ensemble statistics at the GPS fixes (n_gps fixes, N = n_runs realizations).

    t_gps (n_gps,) s; P_prior, P_post (n_gps, 3, 3) and S (n_gps, 2, 2) from the filter;
    e_mean, e_prior_mean (n_gps, 3); e_cov, e_prior_cov (n_gps, 3, 3) ensemble
    statistics of the a posteriori / a priori errors; orthogonality (n_gps, 3, 3);
    xhat_sq_mean (n_gps, 3); residual_moment (n_gps, 2, n_gps, 2) = (1/N) sum r r^T;
    nees (n_gps,), nis (n_gps,) run averages (NaN at missing fixes for NIS);
    seconds: wall time of simulation + filtering + statistics.
    """

    params: CalibrationParams
    n_runs: int
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


class _BetweenSums:
    """Running sums of the 200 Hz error over realizations: O(n_imu) memory, whatever N."""

    def __init__(self, params: CalibrationParams):
        self.params = params
        self.n = 0
        self.e = np.zeros((params.n_imu, 3))
        self.ee = np.zeros((params.n_imu, 3, 3))

    def add(self, dx_full, x_full):
        e = dx_full - x_full
        self.n += len(e)
        self.e += e.sum(0)
        self.ee += np.einsum("nja,njb->jab", e, e)

    def result(self, P: np.ndarray) -> BetweenFixes:
        N = self.n
        mean = self.e / N
        cov = (self.ee - N * np.einsum("ja,jb->jab", mean, mean)) / (N - 1)
        return BetweenFixes(self.params.t_imu, P, mean, cov)


def _predicted_between(params: CalibrationParams, x_post: np.ndarray, model) -> np.ndarray:
    """The batch estimate at every sample, ``Phi^k x_post(t_i)`` (n, n_imu, 3)."""
    powers, _ = _between_fix_steps(params, model)
    r = params.steps_per_fix
    n = x_post.shape[0]
    return np.einsum("kab,nib->nika", powers[:r], x_post).reshape(n, -1, 3)[:, : params.n_imu]


_DESCRIPTIONS = {
    "mean_error": "ensemble mean of the error vs 0 (+-t s/sqrt(N))",
    "covariance": "ensemble covariance of the error vs the filter's P",
    "orthogonality": "(1/N) sum (e - e_mean) x_hat^T vs 0",
    "residual_independence": "correlation of r_i and r_m for fixes i < m vs 0",
    "residual_variance": "(1/N) sum r_i^2 vs the filter's S_i",
    "nees": "run-averaged NEES vs chi2_3N/N bounds",
    "nis": "run-averaged NIS vs chi2_2N/N bounds",
}


class _Sums:
    """Running sums over realizations (everything at the GPS fixes)."""

    def __init__(self, n_gps: int):
        self.n = 0
        self.e = np.zeros((n_gps, 3))
        self.ee = np.zeros((n_gps, 3, 3))
        self.eb = np.zeros((n_gps, 3))
        self.ebeb = np.zeros((n_gps, 3, 3))
        self.ex = np.zeros((n_gps, 3, 3))
        self.x = np.zeros((n_gps, 3))
        self.xx = np.zeros((n_gps, 3))
        self.rr = np.zeros((2 * n_gps, 2 * n_gps))
        self.nees = np.zeros(n_gps)
        self.nis = np.zeros(n_gps)

    def add(self, dx, x_prior, x_post, residual, P_post_inv, S_inv):
        e = dx - x_post
        eb = dx - x_prior
        self.n += len(dx)
        self.e += e.sum(0)
        self.ee += np.einsum("nia,nib->iab", e, e)
        self.eb += eb.sum(0)
        self.ebeb += np.einsum("nia,nib->iab", eb, eb)
        self.ex += np.einsum("nia,nib->iab", e, x_post)
        self.x += x_post.sum(0)
        self.xx += (x_post**2).sum(0)
        r = residual.reshape(len(dx), -1)
        self.rr += r.T @ r  # NaN only in the rows/columns of missing fixes
        self.nees += np.einsum("nia,iab,nib->i", e, P_post_inv, e)
        self.nis += np.einsum("nia,iab,nib->i", residual, S_inv, residual)


def _fixed_bytes(params: CalibrationParams) -> float:
    return _BASE_BYTES + _FIXED_BYTES_PER_FIX2 * params.n_gps**2 + _FIXED_BYTES_PER_SAMPLE * params.n_imu


def _realization_bytes(params: CalibrationParams, between_fixes: bool = False) -> float:
    # between_fixes keeps the true and the estimated 200 Hz error state of the chunk (2 x 3 floats)
    per_sample = _BYTES_PER_SAMPLE + (_BETWEEN_BYTES_PER_SAMPLE if between_fixes else 0.0)
    return per_sample * params.n_imu + _BYTES_PER_FIX * params.n_gps


def chunk_size(params: CalibrationParams) -> int:
    """Realizations simulated together for ``params``: :data:`CHUNK_SIZE`, or fewer when the
    realizations are long, so that the estimated peak stays under :data:`MEMORY_LIMIT` even with
    ``between_fixes`` (at least 1; :func:`estimate_run` refuses runs where even 1 does not fit).  It does
    not depend on ``between_fixes``, so the random draws, and the seven checks, are the same with and
    without it."""
    room = MEMORY_LIMIT - _fixed_bytes(params)
    return int(max(1, min(CHUNK_SIZE, room // _realization_bytes(params, between_fixes=True))))


def estimate_run(params: CalibrationParams, n_runs: int, engine: str = "batch",
                 runs_name: str = "n_runs", params_name: str = "params",
                 extra_bytes: float = 0.0, between_fixes: bool = False) -> tuple[float, float]:
    """Estimated ``(peak bytes, seconds)`` of :func:`run_monte_carlo`; ValueError, with the
    estimate, when the peak exceeds :data:`MEMORY_LIMIT` (the scenario has too many IMU samples
    or GPS fixes) or the time exceeds :data:`MAX_SECONDS` (``runs_name`` and ``params_name`` name
    the arguments in the message).  ``extra_bytes``: what the caller needs after the Monte Carlo,
    while its result is alive (the command line's figures)."""
    per_run = _realization_bytes(params, between_fixes)
    peak = _fixed_bytes(params) + max(min(n_runs, chunk_size(params)) * per_run, extra_bytes)
    if peak > MEMORY_LIMIT:
        raise ValueError(
            f"{params_name}: one realization of {params.n_imu} IMU samples and {params.n_gps} GPS fixes needs about "
            f"{peak / 1e6:.0f} MB, more than the {MEMORY_LIMIT / 1e6:.0f} MB allowed; use a shorter duration "
            f"or lower rates (at most about 1000 GPS fixes and 2 million IMU samples)")
    seconds = (_SECONDS_PER_SAMPLE[engine] * params.n_imu * float(n_runs)
               + _SECONDS_PER_FIX2 * params.n_gps**2)
    if seconds > MAX_SECONDS:
        raise ValueError(f"{runs_name}: {n_runs} realizations with engine {engine!r} would take about "
                         f"{seconds / 3600:.3g} h, more than the {MAX_SECONDS / 3600:g} h allowed; use fewer")
    return peak, seconds


def run_monte_carlo(params: CalibrationParams | None = None, n_runs: int = 1000, seed=0,
                    engine: str = "batch", truth: str = "euler", alpha: float = 0.05,
                    missing_fixes=None, progress: bool | None = False,
                    model: ErrorStateModel | None = None, between_fixes: bool = False) -> MonteCarloResult:
    """Simulate ``n_runs`` realizations, filter them, and accumulate the check statistics.

    Parameters
    ----------
    params : CalibrationParams (default: ``CalibrationParams()``)
    n_runs : int >= 2
    seed : int or None, seed of ``numpy.random.default_rng``
    engine : "batch" (vectorised, shared gains) or "filterpy" (one KalmanFilter per run)
    truth : "euler" or "analytic"
    alpha : significance of the bands, in (0, 1)
    missing_fixes : optional bool array (n_gps,), fixes that are missing (outages)
    progress : show a progress bar over chunks (None: unless CI/KFCAL_QUIET is set)
    model : optional ErrorStateModel the filter assumes (default: the true one); the
        truth is always simulated with ``params``
    between_fixes : also accumulate the error at every 200 Hz sample (``result.between``,
        checked by ``result.between_fixes_check()``); memory O(n_imu), independent of N

    Returns
    -------
    MonteCarloResult

    Raises
    ------
    ValueError naming the argument: bad values, missing fixes leaving fewer than 2 fixes,
    or a run refused by :func:`estimate_run` (too much memory or time).
    """
    params = CalibrationParams() if params is None else params
    if not isinstance(params, CalibrationParams):
        raise ValueError(f"params must be a CalibrationParams, got {type(params).__name__}")
    n_runs = require_int("n_runs", n_runs, minimum=2)
    require_choice("engine", engine, ENGINES)
    require_choice("truth", truth, TRUTH_MODELS)
    alpha = require_finite("alpha", alpha)
    if not 0 < alpha < 1:
        raise ValueError(f"alpha must be in (0, 1), got {alpha!r}")
    missing = np.zeros(params.n_gps, bool) if missing_fixes is None else np.asarray(missing_fixes)
    if missing.shape != (params.n_gps,) or missing.dtype != bool:
        raise ValueError(f"missing_fixes must be a bool array of shape ({params.n_gps},)")
    if (~missing).sum() < 2:
        raise ValueError(f"missing_fixes must leave at least 2 of the {params.n_gps} GPS fixes, "
                         f"got {int((~missing).sum())}")
    seed = require_seed("seed", seed)
    if not isinstance(between_fixes, (bool, np.bool_)):
        raise ValueError(f"between_fixes must be True or False, got {between_fixes!r}")
    between_fixes = bool(between_fixes)
    estimate_run(params, n_runs, engine, between_fixes=between_fixes)

    start = time.perf_counter()
    rng = np.random.default_rng(seed)
    cov = covariance_sequence(params, missing, model)
    bsums = _BetweenSums(params) if between_fixes else None
    P, P_prior, S, K = cov
    P_post = P[params.fix_indices]
    P_post_inv = np.linalg.inv(P_post)
    S_inv = np.linalg.inv(S)
    sums = _Sums(params.n_gps)
    chunk = chunk_size(params)
    sizes = [chunk] * (n_runs // chunk) + ([n_runs % chunk] if n_runs % chunk else [])
    bar = _progress_bar(n_runs, f"Monte Carlo ({engine})", progress)
    for size in sizes:
        sim = simulate(params, size, rng, truth=truth, missing_fixes=missing if missing.any() else None)
        dx, dz = sim.dx_at_fixes, sim.dz
        dx_full = sim.dx if bsums is not None else None  # the true error state at every sample, (n, n_imu, 3)
        del sim
        if engine == "batch":
            res = batch_filter(params, dz, full_rate=False, covariances=cov, model=model)
            x_prior, x_post, residual = res.x_prior, res.x_post, res.residual
        else:
            runs = []
            for l in range(size):  # the bar moves with every realization (about 0.1 s each)
                runs.append(run_filterpy(params, dz[l], model))
                bar.update(1)
            x_prior = np.stack([r.x_prior for r in runs])
            x_post = np.stack([r.x_post for r in runs])
            residual = np.stack([r.residual for r in runs])
        sums.add(dx, x_prior, x_post, residual, P_post_inv, S_inv)
        if bsums is not None:
            x_full = (_predicted_between(params, x_post, model) if engine == "batch"
                      else np.stack([run.x for run in runs]))
            bsums.add(dx_full, x_full)
            del dx_full, x_full
        if engine == "batch":
            bar.update(size)
    bar.close()

    N = sums.n
    e_mean = sums.e / N
    e_cov = (sums.ee - N * np.einsum("ia,ib->iab", e_mean, e_mean)) / (N - 1)
    eb_mean = sums.eb / N
    eb_cov = (sums.ebeb - N * np.einsum("ia,ib->iab", eb_mean, eb_mean)) / (N - 1)
    orth = (sums.ex - np.einsum("ia,ib->iab", e_mean, sums.x)) / N
    n_gps = params.n_gps
    nis = sums.nis / N
    nis[missing] = np.nan
    result = MonteCarloResult(
        params=params, n_runs=N, engine=engine, truth=truth, alpha=alpha, seconds=0.0,
        t_gps=params.t_gps, missing=missing, P_prior=P_prior, P_post=P_post, S=S,
        e_mean=e_mean, e_cov=e_cov, e_prior_mean=eb_mean, e_prior_cov=eb_cov,
        orthogonality=orth, xhat_sq_mean=sums.xx / N,
        residual_moment=(sums.rr / N).reshape(n_gps, 2, n_gps, 2), nees=sums.nees / N, nis=nis,
        between=bsums.result(cov[0]) if bsums is not None else None)
    result.checks()  # the statistics are part of the timed work
    result.seconds = time.perf_counter() - start
    return result


def format_checks(result: MonteCarloResult) -> str:
    """A fixed-precision text table of the checks (for notebooks and the CLI)."""
    lines = [f"{'check':<22} {'inside':>7} {'worst':>7}  verdict",
             f"{'-' * 22} {'-' * 7} {'-' * 7}  -------"]
    checks = dict(result.checks())
    if result.between is not None:
        checks["between_fixes"] = result.between_fixes_check()
    for name, c in checks.items():
        verdict = "pass" if c.passed else "FAIL"
        lines.append(f"{name:<22} {c.inside_fraction:7.3f} {c.worst:7.2f}  {verdict}")
    return "\n".join(lines)
