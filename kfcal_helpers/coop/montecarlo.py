"""Truth-model tests: Monte Carlo NEES and NIS of any of the three filters.

Each run draws a true initial state from N(x0, P0), simulates the truth with process
noise Omega w_k, w_k ~ N(0, Qtrue) (Omega = dt I by default, ``params.noise_model``) and measurements with noise N(0, Rtrue)
(:mod:`~kfcal_helpers.coop.simulation`), and runs the filterpy filter of
:mod:`~kfcal_helpers.coop.filters` on it.  All runs are drawn up front from one
seeded generator, so the result does not depend on ``workers``.

With N runs, the run-averaged NEES (dimension 6) and NIS (dimension 5, or the number of measurements used) of a
consistent filter lie in ``[chi2(alpha/2, N n)/N, chi2(1 - alpha/2, N n)/N]`` at each
step with probability 1 - alpha (:func:`kfcal_helpers.consistency.chi2_bounds`).

:meth:`MonteCarloResult.checks` turns these into verdicts, as the calibration Monte Carlo
does: the mean error (per step and state, against ``+-t_{N-1} s/sqrt(N)``), the NEES and
the NIS, each with its pointwise band and a simultaneous (Bonferroni) band split over
all entries of the three checks, so that a consistent filter fails any of them with
probability at most ``alpha``.
"""

from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from multiprocessing import get_context

import numpy as np

from scipy import stats

from ..consistency import Check, chi2_bounds, inside_fraction
from ..progress import progress
from ..validation import require_int, require_significance
from .filters import FilterSetup, run
from .model import N_MEAS, N_STATES, CoopParams
from .simulation import simulate

__all__ = ["MonteCarloResult", "truth_model_test", "default_workers"]


@dataclass(frozen=True, eq=False)
class MonteCarloResult:
    """NEES/NIS of N truth-model runs over K samples.

    Attributes
    ----------
    filter : str; n_runs : int (N); alpha : float; every : int (measurement every ``every`` steps)
    t : (K,) s
    nees : (N, K); nis : (N, K) (NaN at steps without a measurement)
    errors : (N, K, 6) truth - estimate, headings wrapped; sigma2 : (N, K, 6) 2 sqrt(diag P)
    nees_bounds, nis_bounds : (lower, upper) for the run averages
    measurements : the rows of y the filter used (the NIS has ``len(measurements)`` degrees of freedom)
    """

    filter: str
    n_runs: int
    alpha: float
    every: int
    t: np.ndarray
    nees: np.ndarray
    nis: np.ndarray
    errors: np.ndarray
    sigma2: np.ndarray
    nees_bounds: tuple
    nis_bounds: tuple
    measurements: tuple = tuple(range(N_MEAS))

    @property
    def nees_mean(self) -> np.ndarray:
        """Run-averaged NEES per step, (K,)."""
        return self.nees.mean(axis=0)

    @property
    def nis_mean(self) -> np.ndarray:
        """Run-averaged NIS per step, (K,), NaN at steps without a measurement."""
        out = np.full(self.nis.shape[1], np.nan)
        has = np.isfinite(self.nis).all(axis=0)
        out[has] = self.nis[:, has].mean(axis=0)
        return out

    @property
    def nees_inside_fraction(self) -> float:
        """Share of the steps whose run-averaged NEES is inside ``nees_bounds``."""
        return inside_fraction(self.nees_mean, *self.nees_bounds)

    @property
    def nis_inside_fraction(self) -> float:
        """Share of the steps with a measurement whose run-averaged NIS is inside ``nis_bounds``."""
        return inside_fraction(self.nis_mean, *self.nis_bounds)

    def median_run(self) -> int:
        """Index of the median run by time-averaged NEES (the "typical run" of the notebooks;
        for an even N the lower of the two middle runs)."""
        avg = self.nees.mean(axis=1)
        return int(np.argsort(avg, kind="stable")[(self.n_runs - 1) // 2])

    @property
    def rms_error(self) -> np.ndarray:
        """RMS error over runs and steps, per state, (6,) in m or rad."""
        return np.sqrt(np.mean(self.errors ** 2, axis=(0, 1)))

    def checks(self) -> dict:
        """The three checks at significance ``alpha``: name -> :class:`~kfcal_helpers.consistency.Check`.

        * ``mean_error``: run mean of each error component (K x 6 entries, m or rad) against 0,
          band ``+-t_{N-1}(1 - a/2) s / sqrt(N)`` with s the ensemble standard deviation;
        * ``nees``: run-averaged NEES per step (K entries) against ``chi2_{6N}/N``;
        * ``nis``: run-averaged NIS per step with a measurement against ``chi2_{mN}/N`` (m = the number of measurements used).

        The simultaneous band uses ``a = alpha / (all entries of the three checks)``.
        """
        if self.n_runs < 2:
            raise ValueError("n_runs must be at least 2 for the checks (an ensemble standard deviation)")
        n = self.n_runs
        has = np.isfinite(self.nis).all(axis=0)
        n_entries = self.errors[0].size + self.nees.shape[1] + int(has.sum())
        a_sim = self.alpha / n_entries
        mean = self.errors.mean(axis=0).ravel()
        sem = self.errors.std(axis=0, ddof=1).ravel() / np.sqrt(n)
        zero = np.zeros_like(mean)
        t_pt, t_sim = stats.t.ppf(1 - self.alpha / 2, n - 1), stats.t.ppf(1 - a_sim / 2, n - 1)
        out = {"mean_error": Check("mean_error", "run mean of the error, per step and state", mean, zero,
                                   -t_pt * sem, t_pt * sem, -t_sim * sem, t_sim * sem)}
        for name, dim, values in (("nees", N_STATES, self.nees_mean), ("nis", len(self.measurements), self.nis_mean[has])):
            lo, hi = chi2_bounds(dim, n, self.alpha)
            slo, shi = chi2_bounds(dim, n, a_sim)
            full = np.full(values.shape, 1.0)
            out[name] = Check(name, f"run-averaged {name.upper()} per step", values, dim * full,
                              lo * full, hi * full, slo * full, shi * full)
        return out

    def summary(self) -> dict:
        """Plain-Python summary (for JSON): bounds, inside fractions, time averages."""
        return {
            "filter": self.filter,
            "n_runs": self.n_runs,
            "steps": int(self.t.size),
            "alpha": self.alpha,
            "nees_bounds": list(self.nees_bounds),
            "nis_bounds": list(self.nis_bounds),
            "nees_inside_fraction": self.nees_inside_fraction,
            "nis_inside_fraction": self.nis_inside_fraction,
            "nees_time_average": float(self.nees_mean.mean()),
            "nis_time_average": float(np.nanmean(self.nis_mean)),
        }


def default_workers() -> int:
    """Worker processes for Monte Carlo runs: the ``KFCAL_WORKERS`` variable, else min(2, CPUs)."""
    env = os.environ.get("KFCAL_WORKERS")
    if env:
        return require_int("KFCAL_WORKERS", int(env), minimum=1)
    return max(1, min(2, os.cpu_count() or 1))


def _one_run(task):
    y, truth, setup = task
    r = run(y, setup, truth)
    return r.nees, r.nis, r.errors(truth), r.sigma2


def truth_model_test(params: CoopParams | None = None, n_runs: int = 50, seed=0, *, filter: str = "ekf",
                     alpha: float = 0.05, every: int = 1, workers: int | None = None, desc: str | None = None,
                     **settings) -> MonteCarloResult:
    """Monte Carlo truth-model test of ``filter`` ("lkf", "ekf" or "ukf").

    Parameters
    ----------
    params : CoopParams -- model, noise, duration (default: the course's, 100 s)
    n_runs : int >= 1 -- N
    seed : int or numpy Generator -- all truths and measurements are drawn from it by
        :func:`~kfcal_helpers.coop.simulation.simulate` (``simulate(params, n_runs, seed, every=every)``
        gives the same draws, to re-run and plot one run)
    filter : "lkf", "ekf" or "ukf"
    alpha : float in (0, 1) -- significance of the two-sided chi-square tests
    every : int >= 1 -- keep the measurements of every ``every``-th step only (NaN elsewhere)
    workers : int >= 1 -- processes (default :func:`default_workers`); results do not depend on it
    settings : the filter's settings, keywords of :meth:`~kfcal_helpers.coop.filters.FilterSetup.build`:
        Q, R, x0, P0, measurements, points (UKF), wrap_innovations (EKF), subtract_nominal (LKF)

    Returns
    -------
    MonteCarloResult
    """
    n_runs = require_int("n_runs", n_runs, minimum=1)
    alpha = require_significance("alpha", alpha)
    workers = default_workers() if workers is None else require_int("workers", workers, minimum=1)
    setup = FilterSetup.build(filter, params, **settings)
    p = setup.params
    sim = simulate(p, n_runs, seed, every=every)
    nees_bounds = chi2_bounds(N_STATES, n_runs, alpha)
    nis_bounds = chi2_bounds(setup.measurement.dim, n_runs, alpha)
    tasks = [(sim.y[i], sim.truth[i], setup) for i in range(n_runs)]
    desc = desc or f"{setup.filter.upper()} truth-model test"
    if workers > 1 and n_runs > 1:
        with ProcessPoolExecutor(max_workers=min(workers, n_runs), mp_context=get_context("fork")) as pool:
            out = list(progress(pool.map(_one_run, tasks), total=n_runs, desc=desc))
    else:
        out = [_one_run(task) for task in progress(tasks, total=n_runs, desc=desc)]
    nees, nis, err, sig = (np.stack(a) for a in zip(*out))
    return MonteCarloResult(setup.filter, n_runs, alpha, sim.every, p.t, nees, nis, err, sig, nees_bounds,
                            nis_bounds, setup.measurement.rows)
