"""Truth-model simulation: noisy states and measurements, and seeded observation logs.

Noise model (discrete time): ``x_{k+1} = phi(x_k, u0) + Omega w_k`` with ``phi`` the exact
closed-form one-step map (:func:`~kfcal_helpers.coop.model.step`), ``w_k ~ N(0, Qtrue)`` and
``Omega = params.Omega`` (``dT * I`` by default, so the state noise per step has covariance
``dT^2 Qtrue``; ``I`` for ``noise_model="identity"``); ``y_k = h(x_k) + v_k`` with
``v_k ~ N(0, Rtrue)``, bearings wrapped.  The filters use the same ``Omega``
(``P- = F P F^T + Omega Q Omega^T``).  The true
initial state is drawn from ``N(x0, P0)``.  Everything is vectorised over runs.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import cholesky

from ..validation import require_int
from .data import CoopLog
from .model import N_MEAS, N_STATES, CoopParams, _arc, measure, wrap_measurement, wrap_state

__all__ = ["simulate_truth", "simulate_measurements", "generate_log", "DEFAULT_LOG_SEED"]

#: seed of the observation log the notebooks and the CLI generate
DEFAULT_LOG_SEED = 5044


def _gaussian(rng, cov, size):
    return rng.standard_normal(size + (cov.shape[0],)) @ cholesky(cov, lower=True).T


def _rng(rng):
    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None or isinstance(rng, (int, np.integer)) and not isinstance(rng, bool):
        return np.random.default_rng(rng)
    raise ValueError(f"rng must be a numpy Generator, an integer seed or None, got {rng!r}")


def simulate_truth(params: CoopParams | None = None, rng=None, n_runs: int | None = None,
                   x0=None, process_noise: bool = True) -> np.ndarray:
    """Noisy true states at t_k = k dT.

    Parameters
    ----------
    params : CoopParams (default: the course's)
    rng : numpy Generator or int seed
    n_runs : None for one run, else the number of independent runs
    x0 : array (6,) or (n_runs, 6), optional -- initial state(s); default: drawn from N(params.x0, params.P0)
    process_noise : bool -- False gives the noise-free closed-form propagation

    Returns
    -------
    array (K, 6), or (n_runs, K, 6), headings wrapped.
    """
    p = params if params is not None else CoopParams()
    rng = _rng(rng)
    runs = () if n_runs is None else (require_int("n_runs", n_runs, minimum=1),)
    if x0 is None:
        start = p.x0 + _gaussian(rng, p.P0, runs)
    else:
        start = np.broadcast_to(np.asarray(x0, dtype=float), runs + (N_STATES,))
    K = p.n_samples
    noise = _gaussian(rng, p.process_noise(), runs + (K - 1,)) if process_noise else np.zeros(runs + (K - 1, N_STATES))
    x = np.empty(runs + (K, N_STATES))
    x[..., 0, :] = wrap_state(start)
    for k in range(K - 1):
        x[..., k + 1, :] = _arc(x[..., k, :], p.u0, p.dT, p.L) + noise[..., k, :]
    return wrap_state(x)


def simulate_measurements(truth, params: CoopParams | None = None, rng=None, first: bool = False) -> np.ndarray:
    """Noisy measurements ``h(x_k) + v_k``, v_k ~ N(0, Rtrue), bearings wrapped.

    ``truth`` has shape (..., K, 6); returns (..., K, 5).  Row k = 0 is NaN (as in
    the course log) unless ``first`` is True.
    """
    p = params if params is not None else CoopParams()
    truth = np.asarray(truth, dtype=float)
    y = wrap_measurement(measure(truth) + _gaussian(_rng(rng), p.Rtrue, truth.shape[:-1]))
    if not first:
        y[..., 0, :] = np.nan
    return y


def generate_log(params: CoopParams | None = None, seed: int = DEFAULT_LOG_SEED) -> CoopLog:
    """A seeded simulated observation log in the course format, with its truth."""
    p = params if params is not None else CoopParams()
    rng = np.random.default_rng(require_int("seed", seed, minimum=0))
    truth = simulate_truth(p, rng)
    y = simulate_measurements(truth, p, rng)
    assert y.shape == (p.n_samples, N_MEAS)
    return CoopLog(p.t, y, p.Qtrue, p.Rtrue, truth=truth, source=f"simulated (seed {seed})")
