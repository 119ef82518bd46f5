"""Truth-model tests: Monte Carlo NEES and NIS of any of the three filters.

Each run draws a true initial state from N(x0, P0), simulates the truth with process
noise Omega w_k, w_k ~ N(0, Qtrue) (Omega = dt I by default, ``params.noise_model``) and measurements with
noise N(0, Rtrue) (:func:`~kfcal_helpers.coop.simulation.simulate`), and filters it with the batched
filters of :mod:`~kfcal_helpers.coop.batch` (filterpy's equations on many runs at once, proven equal
to the per-run filterpy filters of :mod:`~kfcal_helpers.coop.filters` in ``tests/test_coop_batch.py``).

The runs go through the shared Monte Carlo core :func:`kfcal_helpers.montecarlo.run`
(:class:`TruthModelExperiment`): chunks of :data:`CHUNK_SIZE` runs, each drawn from its own
generator of the core's seed policy (``SeedSequence(seed).spawn``, PCG64DXSM), on threads, added in
chunk order, so the result does not depend on ``workers``.  :func:`truth_model_draws` redraws the
truths and measurements of any run exactly, to re-run and plot it.  The core refuses, before any
work, a test whose estimated peak memory exceeds 500 MB: the per-run arrays kept (NEES, NIS,
errors, two-sigma bounds) take 112 kB per run of 1001 steps, so about 3,000 runs of 100 s fit.

With N runs, the run-averaged NEES (dimension 6) and NIS (dimension 5, or the number of measurements
used) of a consistent filter lie in ``[chi2(alpha/2, N n)/N, chi2(1 - alpha/2, N n)/N]`` at each
step with probability 1 - alpha (:func:`kfcal_helpers.consistency.chi2_bounds`).

:meth:`MonteCarloResult.checks` turns these into verdicts, as the calibration Monte Carlo
does: the mean error (per step and state, against ``+-t_{N-1} s/sqrt(N)``), the NEES and
the NIS (per step, by :func:`kfcal_helpers.consistency.step_checks`, as in the orbit problem), each
with its pointwise band and a simultaneous (Bonferroni) band split over all entries of the three
checks, so that a consistent filter fails any of them with probability at most ``alpha``.  A diverged
run is an error, not a FAIL (:meth:`MonteCarloResult.checks`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import montecarlo as core
from ..consistency import Check, chi2_bounds, inside_fraction, step_checks, t_band
from functools import partial

from ..validation import (MAX_SEED, checked, optional, require_instance, require_int, require_seed,
                          require_significance, require_text, require_workers)
from .batch import run_batch
from .filters import FilterSetup
from .model import MAX_STEPS, N_MEAS, N_STATES, CoopParams
from .simulation import Simulation, simulate

__all__ = ["CHUNK_SIZE", "MonteCarloResult", "TruthModelExperiment", "truth_model_test", "truth_model_draws",
           "estimate_truth_model_test"]

#: runs drawn and filtered together (one generator each, :func:`kfcal_helpers.montecarlo.chunk_generators`)
CHUNK_SIZE = 100


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
    seconds : float -- wall time of the test, s
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
    seconds: float = 0.0

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
        * ``nees`` and ``nis`` per step (:func:`~kfcal_helpers.consistency.step_checks`): the run-averaged
          NEES (K entries) against ``chi2_{6N}/N``, the run-averaged NIS at the steps with a measurement
          against ``chi2_{mN}/N`` (m = the number of measurements used).

        The simultaneous band uses ``a = alpha / (all entries of the three checks)``.  A run that
        diverged never reaches a verdict: the batch refuses it (ValueError "the EKF diverged ... in run
        i", one line on the command line), and a result holding a non-finite NEES or NIS anyway gets a
        ValueError here, since a FAIL computed from inf or NaN would say nothing.
        """
        if self.n_runs < 2:
            raise ValueError("n_runs must be at least 2 for the checks (an ensemble standard deviation)")
        n = self.n_runs
        mean, std = (a.ravel() for a in _mean_std(self.errors))
        out = step_checks(self.nees, self.nis, len(self.measurements), N_STATES, self.alpha, extra_entries=mean.size)
        a_sim = Check.bonferroni(self.alpha, mean.size + out["nees"].statistic.size + out["nis"].statistic.size)
        error = Check.from_band("mean_error", "run mean of the error, per step and state", mean, 0.0,
                                lambda a: (-t_band(std, n, a), t_band(std, n, a)), self.alpha, a_sim)
        return {"mean_error": error, **out}

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


_BLOCK = 256  #: runs per block of the ensemble standard deviation in checks()


def _mean_std(errors):
    """Mean and ensemble standard deviation (ddof 1) over the runs of ``errors`` (N, K, 6), in blocks of
    runs: the two-pass formula of ``numpy.std`` without an (N, K, 6) temporary."""
    mean = errors.mean(axis=0)
    ss = np.zeros_like(mean)
    for i in range(0, errors.shape[0], _BLOCK):
        d = errors[i:i + _BLOCK] - mean
        ss += np.einsum("nkj,nkj->kj", d, d)
    return mean, np.sqrt(ss / (errors.shape[0] - 1))


# Memory of a test, bytes (measured with tracemalloc and the peak RSS of a child process,
# tests/test_coop_memory.py): the interpreter and the per-run arrays the experiment declares (the
# core's ArrayExperiment counts them: NEES, NIS, 6 errors, 6 two-sigma bounds per step); those of one chunk
# in flight per run and step (its truths, measurements, the draws' temporaries and its partial
# result); at the end, the memory of the last chunks, which the allocator may keep, and the blocks
# of ``checks()``.
_CHUNK_PER_STEP = 48 * 8
#: one-thread seconds per run of 1001 steps (2-core machine, 2026), and per chunk (the step loop)
_SECONDS_PER_RUN = {"lkf": 1.5e-3, "ekf": 4.0e-3, "ukf": 1.0e-2}
_SECONDS_PER_CHUNK = {"lkf": 0.05, "ekf": 0.15, "ukf": 0.25}


class TruthModelExperiment(core.ArrayExperiment):
    """The truth-model test as an :class:`kfcal_helpers.montecarlo.Experiment` of the shared core.

    A chunk of ``size`` runs draws its truths and measurements with
    ``simulate(params, size, rng, every=every)`` from the chunk's generator and filters them with
    :func:`~kfcal_helpers.coop.batch.run_batch`; the per-run NEES (N, K), NIS (N, K), errors (N, K, 6)
    and two-sigma bounds (N, K, 6) are written into the arrays of the total (allocated once for the
    ``n_runs`` runs), in chunk order.

    setup : FilterSetup -- the filter and its settings (its ``params`` are the truth model's)
    n_runs : None, or int >= 1 -- the only runs this experiment may run (the core gives ``empty`` the
        runs it runs; None: any)
    every : int >= 1 -- keep the measurements of every ``every``-th step only; alpha : of the result
    """

    keep = "runs"

    def __init__(self, setup: FilterSetup, n_runs: int | None = None, every: int = 1, alpha: float = 0.05):
        self.setup = require_instance("setup", setup, FilterSetup)
        self.n_runs = None if n_runs is None else require_int("n_runs", n_runs, minimum=1)
        self.every = require_int("every", every, minimum=1)
        self.alpha = require_significance("alpha", alpha)
        self.params = setup.params

    CHUNK_SIZE = CHUNK_SIZE

    def arrays(self) -> dict:
        K = self.params.n_samples
        return {"nees": (K,), "nis": (K,), "errors": (K, N_STATES), "sigma2": (K, N_STATES)}

    def chunk_bytes(self, size: int) -> float:
        return _CHUNK_PER_STEP * self.params.n_samples * size

    def final_bytes(self, n_runs: int) -> float:
        return 2 * self.chunk_bytes(min(n_runs, CHUNK_SIZE)) + 2 * 6 * 8 * self.params.n_samples * min(n_runs, _BLOCK)

    def seconds(self, n_runs: int) -> float:
        f = self.setup.filter
        steps = self.params.n_samples / 1001
        return steps * (_SECONDS_PER_RUN[f] * n_runs + _SECONDS_PER_CHUNK[f] * -(-n_runs // CHUNK_SIZE))

    def what(self) -> str:
        return f"{self.params.n_samples} steps of the {self.setup.filter.upper()}"

    def draw(self, size: int, rng: np.random.Generator) -> Simulation:
        """The truths and measurements of a chunk of ``size`` runs drawn from ``rng``."""
        return simulate(self.params, size, rng, every=self.every)

    def run_chunk(self, size, rng, chunk):
        sim = self.draw(size, rng)
        chunk.check()
        b = run_batch(sim.y, self.setup, sim.truth)
        return b.nees, b.nis, b.errors, b.sigma2

    def empty(self, n_runs):
        if self.n_runs is not None and n_runs != self.n_runs:
            raise ValueError(f"n_runs: the experiment was made for {self.n_runs} runs, {n_runs} asked")
        return super().empty(n_runs)

    def result(self, total, n_runs, seconds) -> MonteCarloResult:
        s = self.setup
        return MonteCarloResult(s.filter, n_runs, self.alpha, self.every, self.params.t, total["nees"],
                                total["nis"], total["errors"], total["sigma2"],
                                chi2_bounds(N_STATES, n_runs, self.alpha),
                                chi2_bounds(s.measurement.dim, n_runs, self.alpha), s.measurement.rows, seconds)


def _experiment(params, filter, alpha, every, settings) -> TruthModelExperiment:
    return TruthModelExperiment(FilterSetup.build(filter, params, **settings), every=every, alpha=alpha)


def estimate_truth_model_test(params: CoopParams | None = None, n_runs: int = 50, *, filter: str = "ekf",
                              every: int = 1, workers: int | None = None, runs_name: str = "n_runs",
                              extra_bytes: float = 0.0, **settings) -> core.Estimate:
    """The memory and time estimate of :func:`truth_model_test` with these arguments, before it runs
    (:func:`kfcal_helpers.montecarlo.estimate`): ValueError naming ``runs_name`` when the test would
    need more than 500 MB or more than an hour."""
    exp = _experiment(params, filter, 0.05, every, settings)
    return core.estimate(exp, n_runs, workers, extra_bytes=extra_bytes, runs_name=runs_name)


@checked(params=optional(partial(require_instance, cls=CoopParams)), n_runs=partial(require_int, minimum=1, maximum=MAX_SEED),
         every=partial(require_int, minimum=1, maximum=MAX_STEPS),
         workers=optional(require_workers), desc=optional(require_text))
def truth_model_test(params: CoopParams | None = None, n_runs: int = 50, seed=0, *, filter: str = "ekf",
                     alpha: float = 0.05, every: int = 1, workers: int | None = None, desc: str | None = None,
                     **settings) -> MonteCarloResult:
    """Monte Carlo truth-model test of ``filter`` ("lkf", "ekf" or "ukf").

    Parameters
    ----------
    params : CoopParams -- model, noise, duration (default: the course's, 100 s)
    n_runs : int >= 1 -- N
    seed : int in [0, 2**63 - 1] (or a numpy Generator, or None for fresh entropy) -- the seed of the
        core's policy (:func:`kfcal_helpers.montecarlo.chunk_generators`): chunk c of
        :data:`CHUNK_SIZE` runs draws from its own generator.  ``truth_model_draws(params, n_runs,
        seed, every=every)`` redraws the same truths and measurements, to re-run and plot one run
    filter : "lkf", "ekf" or "ukf"
    alpha : float in (0, 1) -- significance of the two-sided chi-square tests
    every : int >= 1 -- keep the measurements of every ``every``-th step only (NaN elsewhere)
    workers : int >= 1 -- threads (default :func:`kfcal_helpers.montecarlo.default_workers`, which reads
        ``KFCAL_WORKERS``); the result does not depend on it
    desc : the progress bar's label
    settings : the filter's settings, keywords of :meth:`~kfcal_helpers.coop.filters.FilterSetup.build`:
        Q, R, x0, P0, measurements, points (UKF), wrap_innovations (EKF), subtract_nominal (LKF)

    Returns
    -------
    MonteCarloResult (with ``seconds``, the wall time).  ValueError, before any work, when the test
    would need more than 500 MB (the per-run arrays: 112 kB per run of 1001 steps) or an hour; ValueError
    naming ``y`` when a run diverges (a non-finite estimate, NEES or NIS: no checks are judged).
    """
    exp = _experiment(params, filter, alpha, every, settings)  # checks alpha (n_runs: @checked, seed: core.run)
    desc = desc or f"{exp.setup.filter.upper()} truth-model test"
    return core.run(exp, n_runs, seed, workers=workers, progress=None, desc=desc)


@checked(params=optional(partial(require_instance, cls=CoopParams)), n_runs=partial(require_int, minimum=1, maximum=MAX_SEED),
         every=partial(require_int, minimum=1, maximum=MAX_STEPS),
         run=optional(partial(require_int, minimum=0)))
def truth_model_draws(params: CoopParams | None = None, n_runs: int = 50, seed=0, *, every: int = 1,
                      run: int | None = None) -> Simulation:
    """The truths and measurements :func:`truth_model_test` ``(params, n_runs, seed, every=every)``
    filters, drawn again from the same chunk generators.

    params, n_runs, seed, every : as in :func:`truth_model_test` (an int seed redraws exactly; a
        Generator is advanced by its ``spawn``, so pass the same seed, not the same Generator)
    run : None for all runs (``truth`` (n_runs, K, 6), ``y`` (n_runs, K, 5)), or the index of one run
        in 0..n_runs-1 (``truth`` (K, 6), ``y`` (K, 5); only its chunk is drawn)

    Returns
    -------
    Simulation (``seed`` is the int seed, None for a Generator)
    """
    p = require_instance("params", params, CoopParams, allow_none=True) or CoopParams()
    n_runs = require_int("n_runs", n_runs, minimum=1)
    every = require_int("every", every, minimum=1)
    if run is not None:
        run = require_int("run", run, minimum=0)
        if run >= n_runs:
            raise ValueError(f"run must be an integer in 0..{n_runs - 1}, got {run}")
    seed_value = None if isinstance(seed, np.random.Generator) else require_seed("seed", seed)
    chunks = core.chunk_generators(CHUNK_SIZE, n_runs, seed)
    if run is not None:
        size, rng = chunks[run // CHUNK_SIZE]
        sim = simulate(p, size, rng, every=every)
        i = run % CHUNK_SIZE
        return Simulation(p, seed_value, every, sim.truth[i].copy(), sim.y[i].copy())
    sims = [simulate(p, size, rng, every=every) for size, rng in chunks]
    return Simulation(p, seed_value, every, np.concatenate([s.truth for s in sims]),
                      np.concatenate([s.y for s in sims]))
