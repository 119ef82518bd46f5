"""Truth-model tests of the orbit filters: Monte Carlo NEES and NIS through the shared core.

Each run draws ``x_0 ~ N(x0, P0)``, the truth of the filters' DT model ``x_{k+1} = f_d(x_k) + Omega w_k`` with
the acceleration noise ``w_k ~ N(0, Qtrue)`` (``f_d`` the vectorised RK4 of the simulation by default, or
``solve_ivp``), and noisy
measurements of the stations that see it (:func:`~kfcal_helpers.orbit.simulation.simulate`),
then filters them with the batched filters of :mod:`~kfcal_helpers.orbit.batch` (proven equal to the per-run
filterpy filters in ``tests/test_orbit_batch.py``).  The runs go through :func:`kfcal_helpers.montecarlo.run`
(:class:`OrbitExperiment`): chunks of :data:`CHUNK_SIZE` runs, each from its own generator of the core's
seed policy, on threads, added in chunk order (the result does not depend on the number of workers).

The measurement dimension changes per step and per run (3 per visible station), so the NIS checks are built
per step from the dof present (:func:`kfcal_helpers.consistency.step_checks`): the NIS averaged over the runs
with a measurement at step k is chi-square with the sum of their dofs, over their number.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import montecarlo as core
from ..consistency import Check, step_checks, t_band
from functools import partial

from ..validation import (MAX_SEED, checked, optional, require_choice, require_instance, require_int,
                          require_significance, require_workers)
from .batch import run_batch
from .filters import FilterSetup
from .params import MAX_STEPS, N_STATES, OrbitParams
from .simulation import INTEGRATORS, simulate

__all__ = ["CHUNK_SIZE", "MonteCarloResult", "OrbitExperiment", "truth_model_test"]

#: runs drawn and filtered together
CHUNK_SIZE = 100


@dataclass(frozen=True, eq=False)
class MonteCarloResult:
    """NEES/NIS of N truth-model runs over K samples.

    filter : str; n_runs : int (N); alpha : float; t : (K,) s
    nees : (N, K); nis : (N, K), NaN where a run had no station; dof : (N, K) ints, 3 per station present
    errors : (N, K, 4) truth - estimate (km, km/s); sigma2 : (N, K, 4) two-sigma bounds
    seconds : wall time of the test, s
    """

    filter: str
    n_runs: int
    alpha: float
    t: np.ndarray
    nees: np.ndarray
    nis: np.ndarray
    dof: np.ndarray
    errors: np.ndarray
    sigma2: np.ndarray
    seconds: float = 0.0

    def checks(self) -> dict:
        """The checks at significance ``alpha``, name -> :class:`~kfcal_helpers.consistency.Check`:
        ``mean_error`` (run mean of each error component per step against 0, ``+-t_{N-1} s / sqrt(N)``),
        ``nees`` and ``nis`` per step (:func:`~kfcal_helpers.consistency.step_checks`, the NIS with the dof
        present); one Bonferroni split over all their entries for the simultaneous bands."""
        if self.n_runs < 2:
            raise ValueError("n_runs must be at least 2 for the checks (an ensemble standard deviation)")
        n = self.n_runs
        mean = self.errors.mean(axis=0).ravel()
        sd = self.errors.std(axis=0, ddof=1).ravel()
        out = step_checks(self.nees, self.nis, self.dof, N_STATES, self.alpha, extra_entries=mean.size)
        a_sim = Check.bonferroni(self.alpha, mean.size + out["nees"].statistic.size + out["nis"].statistic.size)
        error = Check.from_band("mean_error", "run mean of the error, per step and state", mean, 0.0,
                                lambda a: (-t_band(sd, n, a), t_band(sd, n, a)), self.alpha, a_sim)
        return {"mean_error": error, **out}


# Estimates (bytes, s): the interpreter and the per-run arrays the experiment declares (the core's
# ArrayExperiment counts them: NEES, NIS, dof, 4 errors, 4 two-sigma bounds per step); per run and step those
# of a chunk in flight: the peak is the measurements' simulation (truth, the relative states and dense
# measurements of 12 stations, their noise), 985 bytes measured in a child process (VmHWM of 100 UKF runs
# less that of 2) on the 2-core machine, with 22 % margin (CI machines measured up to 4 % above it);
# one-thread seconds per run of 1401 steps and per chunk (the step loops), rounded up from runs on the
# 2-core machine.
_CHUNK_PER_STEP = 150 * 8
_SECONDS_PER_RUN = {"lkf": 0.02, "ekf": 0.04, "ukf": 0.08}
_SECONDS_PER_CHUNK = 2.0


class OrbitExperiment(core.ArrayExperiment):
    """The orbit truth-model test as a :class:`kfcal_helpers.montecarlo.Experiment`.

    setup : FilterSetup (its params are the truth model's); n_runs : None, or the only runs this experiment
    may run (the core gives ``empty`` the runs it runs; None: any);
    alpha : of the result; every : keep the measurements of every ``every``-th step; integrator : of the
    truth: "rk4" (default; the vectorised fixed-step RK4, within 1e-7 km of "solve_ivp" on the same draws,
    ``tests/test_orbit_model.py``, at a fraction of its cost) or "solve_ivp"
    """

    keep, CHUNK_SIZE = "runs", CHUNK_SIZE

    def __init__(self, setup: FilterSetup, n_runs: int | None = None, alpha: float = 0.05, every: int = 1,
                 integrator: str = "rk4"):
        self.setup = require_instance("setup", setup, FilterSetup)
        self.n_runs = None if n_runs is None else require_int("n_runs", n_runs, minimum=1, maximum=MAX_SEED)
        self.alpha = require_significance("alpha", alpha)
        self.every = require_int("every", every, minimum=1, maximum=MAX_STEPS)
        self.integrator = require_choice("integrator", integrator, INTEGRATORS)
        self.K = setup.params.n_samples

    def arrays(self) -> dict:
        K = self.K
        return {"nees": (K,), "nis": (K,), "dof": ((K,), int), "errors": (K, N_STATES), "sigma2": (K, N_STATES)}

    def chunk_bytes(self, size: int) -> float:
        return _CHUNK_PER_STEP * self.K * size

    def final_bytes(self, n_runs: int) -> float:
        return 3 * N_STATES * 8 * self.K * n_runs  # the checks' mean, sd and their temporaries

    def seconds(self, n_runs: int) -> float:
        scale = self.K / 1401
        return scale * (_SECONDS_PER_RUN[self.setup.filter] * n_runs + _SECONDS_PER_CHUNK * -(-n_runs // CHUNK_SIZE))

    def what(self) -> str:
        return f"{self.K} steps of the {self.setup.filter.upper()}"

    def run_chunk(self, size, rng, chunk):
        sim = simulate(self.setup.params, size, rng, every=self.every, integrator=self.integrator)
        chunk.check()
        b = run_batch(sim.y, self.setup, sim.truth)
        return b.nees, b.nis, b.dof, b.errors, b.sigma2

    def empty(self, n_runs):
        if self.n_runs is not None and n_runs != self.n_runs:
            raise ValueError(f"n_runs: the experiment holds {self.n_runs} runs, {n_runs} asked")
        return super().empty(n_runs)

    def result(self, total, n_runs, seconds) -> MonteCarloResult:
        p = self.setup.params
        return MonteCarloResult(self.setup.filter, n_runs, self.alpha, p.t, total["nees"], total["nis"],
                                total["dof"], total["errors"], total["sigma2"], seconds)


@checked(n_runs=partial(require_int, minimum=1, maximum=MAX_SEED), every=partial(require_int, minimum=1, maximum=MAX_STEPS),
         workers=optional(require_workers))
def truth_model_test(params: OrbitParams | None = None, n_runs: int = 50, seed=0, *, filter: str = "ekf",
                     alpha: float = 0.05, every: int = 1, integrator: str = "rk4", workers: int | None = None,
                     setup: FilterSetup | None = None, **settings) -> MonteCarloResult:
    """Monte Carlo truth-model test of ``filter`` ("lkf", "ekf", "ukf") over ``n_runs`` runs.

    params : OrbitParams (default the course's); seed : int in [0, 2**63 - 1], None or a Generator (the
    core's seed policy); alpha : significance of the checks; every : measurements of every ``every``-th
    step only; integrator : of the truth, "rk4" (default) or "solve_ivp" (:class:`OrbitExperiment`); workers : threads (the result does not depend on it);
    settings : :class:`~kfcal_helpers.orbit.filters.FilterSetup` fields (Q, R, x0, P0, transition, substeps,
    beta, kappa); setup : a whole FilterSetup instead of ``params``, ``filter`` and ``settings`` (the way
    to set the UKF's sigma-point ``alpha``, since ``alpha`` here is the significance).
    Returns a :class:`MonteCarloResult`; ValueError before any work when the estimate exceeds 500 MB or 1 h.
    """
    if setup is None:
        setup = FilterSetup(filter, params, **settings)
    elif params is not None or settings:
        raise ValueError("setup: give either a FilterSetup or params and filter settings, not both")
    exp = OrbitExperiment(setup, alpha=alpha, every=every, integrator=integrator)
    return core.run(exp, n_runs, seed, workers=workers, progress=None, desc=f"{setup.filter.upper()} truth-model test")
