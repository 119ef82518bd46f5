"""Truth-model simulation: noisy states and measurements, and seeded observation logs.

Noise model (discrete time): ``x_{k+1} = phi(x_k, u0) + Omega w_k`` with ``phi`` the exact
closed-form one-step map (:func:`~kfcal_helpers.coop.model.step`), ``w_k ~ N(0, Qtrue)`` a noise on
the rates held constant over the step and ``Omega = params.Omega`` (``dt * I`` by default, the Euler step
of that held noise, so the state noise per step has covariance ``dt^2 Qtrue``; ``I`` for
``noise_model="identity"``); ``y_k = h(x_k) + v_k`` with
``v_k ~ N(0, Rtrue)``, bearings wrapped.  The filters use the same ``Omega``
(``P- = F P F^T + Omega Q Omega^T``).  The true
initial state is drawn from ``N(x0, P0)``.  Everything is vectorised over runs.

:func:`simulate` is the entry: one seeded draw of truths and measurements, a :class:`Simulation`.
:func:`simulate_truth` and :func:`simulate_measurements` are its two halves, for a caller that
brings its own truth or draws the measurements of another one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import cholesky

from functools import partial

from ..validation import (MAX_SEED, as_generator, checked, optional, require_bool, require_finite_array, require_instance,
                          require_int, require_seed_or_generator)
from .data import CoopLog
from .model import MAX_STEPS, N_MEAS, N_STATES, STATE, CoopParams, MeasurementModel, arc

__all__ = ["Simulation", "simulate", "simulate_truth", "simulate_measurements", "DEFAULT_LOG_SEED"]

#: seed of the observation log the notebooks and the CLI generate
DEFAULT_LOG_SEED = 5044

_MEASURE = MeasurementModel(np.eye(N_MEAS))  # h and its bearings (R unused)


def _gaussian(rng, cov, size):
    return rng.standard_normal(size + (cov.shape[0],)) @ cholesky(cov, lower=True).T


def _params(params) -> CoopParams:
    return require_instance("params", params, CoopParams, allow_none=True) or CoopParams()


@checked(params=optional(partial(require_instance, cls=CoopParams)),
         seed=optional(require_seed_or_generator), n_runs=optional(partial(require_int, minimum=1, maximum=MAX_SEED)),
         x0=optional(partial(require_finite_array, shape=(..., N_STATES))), process_noise=require_bool)
def simulate_truth(params: CoopParams | None = None, seed=None, n_runs: int | None = None,
                   x0=None, process_noise: bool = True) -> np.ndarray:
    """Noisy true states at t_k = k dt.

    Parameters
    ----------
    params : CoopParams (default: the course's)
    seed : int seed or numpy Generator (the draws advance it); None for a fresh unseeded generator
    n_runs : None for one run, else the number of independent runs
    x0 : array (6,) or (n_runs, 6), optional -- initial state(s); default: drawn from N(params.x0, params.P0)
    process_noise : bool -- False gives the noise-free closed-form propagation

    Returns
    -------
    array (K, 6), or (n_runs, K, 6), headings wrapped.
    """
    p = _params(params)
    rng = np.random.default_rng() if seed is None else as_generator("seed", seed)
    runs = () if n_runs is None else (require_int("n_runs", n_runs, minimum=1),)
    if x0 is None:
        start = p.x0 + _gaussian(rng, p.P0, runs)
    else:
        start = np.broadcast_to(np.asarray(x0, dtype=float), runs + (N_STATES,))
    K = p.n_samples
    noise = _gaussian(rng, p.process_noise(), runs + (K - 1,)) if process_noise else np.zeros(runs + (K - 1, N_STATES))
    x = np.empty(runs + (K, N_STATES))
    x[..., 0, :] = STATE.wrap(start)
    for k in range(K - 1):
        x[..., k + 1, :] = arc(x[..., k, :], p.u0, p.dt, p.L) + noise[..., k, :]
    return STATE.wrap(x)


@checked(truth=partial(require_finite_array, shape=(..., None, N_STATES)),
         params=optional(partial(require_instance, cls=CoopParams)), seed=optional(require_seed_or_generator),
         first=require_bool)
def simulate_measurements(truth, params: CoopParams | None = None, seed=None, first: bool = False) -> np.ndarray:
    """Noisy measurements ``h(x_k) + v_k``, v_k ~ N(0, Rtrue), bearings wrapped.

    ``truth`` has shape (..., K, 6); returns (..., K, 5).  Row k = 0 is NaN (as in
    the course log) unless ``first`` is True.  ``seed``: int or Generator (None: unseeded).
    """
    p = _params(params)
    rng = np.random.default_rng() if seed is None else as_generator("seed", seed)
    truth = np.asarray(truth, dtype=float)
    y = _MEASURE.wrap(_MEASURE.h(truth) + _gaussian(rng, p.Rtrue, truth.shape[:-1]))
    if not first:
        y[..., 0, :] = np.nan
    return y


@dataclass(frozen=True, eq=False)
class Simulation:
    """One seeded draw of the truth model.

    params : CoopParams; seed : the int seed (None when a Generator was given); every : measurements
    kept every ``every`` steps (NaN rows elsewhere; row 0 is NaN as in the course log)
    truth : (K, 6) or (n_runs, K, 6) true states, headings wrapped
    y : (K, 5) or (n_runs, K, 5) measurements, bearings wrapped
    """

    params: CoopParams
    seed: int | None
    every: int
    truth: np.ndarray
    y: np.ndarray

    @property
    def t(self) -> np.ndarray:
        """Sample times, s, (K,)."""
        return self.params.t

    @property
    def n_runs(self) -> int | None:
        """Number of runs (None for a single run without a leading axis)."""
        return None if self.truth.ndim == 2 else self.truth.shape[0]

    def log(self, run: int | None = None) -> CoopLog:
        """The draw as an observation log in the course format, with its truth (``run``: which run of
        several)."""
        if self.n_runs is None:
            if run is not None:
                raise ValueError("run must be None for a single-run simulation")
            truth, y = self.truth, self.y
        else:
            run = require_int("run", run, minimum=0) if run is not None else None
            if run is None or run >= self.n_runs:
                raise ValueError(f"run must be an integer in 0..{self.n_runs - 1}, got {run!r}")
            truth, y = self.truth[run], self.y[run]
        p = self.params
        source = "simulated" + (f" (seed {self.seed})" if self.seed is not None else "")
        return CoopLog(p.t, y, p.Qtrue, p.Rtrue, truth=truth, source=source)


@checked(params=optional(partial(require_instance, cls=CoopParams)), n_runs=optional(partial(require_int, minimum=1, maximum=MAX_SEED)),
         seed=require_seed_or_generator, every=partial(require_int, minimum=1, maximum=MAX_STEPS))
def simulate(params: CoopParams | None = None, n_runs: int | None = None, seed=DEFAULT_LOG_SEED, *,
             every: int = 1) -> Simulation:
    """Truths and measurements of the truth model, from one seeded generator.

    params : CoopParams (default: the course's); n_runs : None for one run (arrays without a run
    axis), else the number of independent runs; seed : int or numpy Generator (default
    :data:`DEFAULT_LOG_SEED`, the log of the notebooks and the CLI); every : keep the measurements of
    every ``every``-th step only (NaN elsewhere).

    The truths are drawn first (initial states, then process noise), then the measurement noise, so a
    run ``i`` of ``n_runs`` is reproduced by the same seed, and ``n_runs=1`` gives the single run.
    """
    p = _params(params)
    every = require_int("every", every, minimum=1)
    seed_value = None if isinstance(seed, np.random.Generator) else seed
    rng = as_generator("seed", seed)
    truth = simulate_truth(p, rng, n_runs=n_runs)
    y = simulate_measurements(truth, p, rng)
    assert y.shape == truth.shape[:-1] + (N_MEAS,)
    if every > 1:
        keep = np.zeros(p.n_samples, dtype=bool)
        keep[::every] = True
        y[..., ~keep, :] = np.nan
    return Simulation(p, None if seed_value is None else int(seed_value), every, truth, y)
