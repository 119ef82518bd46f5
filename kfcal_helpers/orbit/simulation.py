"""Truth-model simulation of the orbit-determination problem, and logs in the course's format.

Truth: ``x_0 ~ N(x0, P0)``, then the filters' DT model ``x_{k+1} = f_d(x_k) + Omega w_k``,
``Omega = dt Gamma``, with the acceleration noise ``w_k ~ N(0, Qtrue)`` (km/s^2): ``f_d`` the noise-free
flow of ``xdot = f(x)`` over the sample interval, integrated by ``scipy.integrate.solve_ivp`` (DOP853,
``rtol=1e-12``, ``atol=1e-9`` km and km/s) with every run of a batch stacked into one ODE, and the noise a
velocity change ``dt w_k`` at the end of the interval (as in the cooperative-localization problem).  The
truth so has exactly the per-step noise covariance ``Omega Q Omega^T`` the filters assume; holding ``w_k``
over the interval would also move the position by ``dt^2 w_k / 2``, a noise the filters do not model, and
makes their truth-model NEES about 3 % low (``tests/test_orbit_model.py``).

Measurements at t_k (k >= 1; also k = 0 with ``first=True``): for every station that sees the true
satellite (:func:`~kfcal_helpers.orbit.model.visible`), ``[rho, rhodot, phi] + v``, ``v ~ N(0, Rtrue)``,
phi wrapped.  They are kept two ways:

* dense, for the filters: ``y`` of shape (..., K, n_stations, 3), NaN for a station that does not see
  the satellite (and at k = 0 unless ``first``);
* the course's columns (:class:`OrbitLog`): per step an array (4, m_k), one column
  ``[rho; rhodot; phi; station id]`` per visible station (ids 1..n_stations), empty (4, 0) where none.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import cholesky

from functools import partial

from ..angles import wrap_angle
from ..validation import (MAX_SEED, as_generator, checked, optional, require_bool, require_choice, require_covariance,
                          require_array, require_finite_array, require_int, require_positive, require_sequence, require_text)
from .model import PHI, horizon, measure_relative, params_or_default, relative_states, require_states, rk4_flow
from .params import MAX_STATIONS, MAX_STEPS, N_NOISE, N_STATES, N_STATION_MEAS, OrbitParams

_n_runs = optional(partial(require_int, minimum=1, maximum=MAX_SEED))

__all__ = ["DEFAULT_LOG_SEED", "ODE_RTOL", "ODE_ATOL", "INTEGRATORS", "RK4_TRUTH_SUBSTEPS", "integrate", "simulate_truth", "simulate_measurements",
           "to_columns", "from_columns", "OrbitLog", "Simulation", "simulate"]

#: seed of the generated observation log
DEFAULT_LOG_SEED = 5044
#: tolerances of the truth ODE (relative; absolute in km and km/s)
ODE_RTOL, ODE_ATOL = 1e-12, 1e-9
#: how the truth is integrated over a step: "solve_ivp" (default, one adaptive DOP853 call per step with every
#: run stacked) or "rk4" (classical RK4 in RK4_TRUTH_SUBSTEPS fixed substeps, vectorised: agrees with
#: "solve_ivp" to about 1e-7 km over the course's 1400 steps, at a fraction of the cost; for large Monte Carlos)
INTEGRATORS = ("solve_ivp", "rk4")
RK4_TRUTH_SUBSTEPS = 5


def _gaussian(rng, cov, size):
    return rng.standard_normal(size + (cov.shape[0],)) @ cholesky(cov, lower=True).T


@checked(w=optional(partial(require_finite_array, shape=(..., N_NOISE))), dt=optional(require_positive))
def integrate(x, params: OrbitParams | None = None, w=None, dt: float | None = None) -> np.ndarray:
    """States after ``dt`` (s, default ``params.dt``) of ``xdot = f(x) + Gamma w`` from ``x`` (..., 4), with
    the accelerations ``w`` (..., 2) (km/s^2, default zero) held constant: one ``solve_ivp`` call for all
    leading axes at once (DOP853, :data:`ODE_RTOL`, :data:`ODE_ATOL`).  Returns (..., 4)."""
    p = params_or_default(params)
    x = require_states("x", x)
    dt = p.dt if dt is None else float(dt)
    shape = x.shape
    acc = np.zeros(shape[:-1] + (N_NOISE,)) if w is None else np.broadcast_to(w, shape[:-1] + (N_NOISE,))
    push = (acc @ p.Gamma.T).reshape(-1, N_STATES)
    mu = p.mu

    def rhs(_t, z):
        s = z.reshape(-1, N_STATES)
        X, Y = s[:, 0], s[:, 2]
        r2 = X * X + Y * Y
        g = mu / (r2 * np.sqrt(r2))
        out = push.copy()
        out[:, 0] += s[:, 1]
        out[:, 1] -= g * X
        out[:, 2] += s[:, 3]
        out[:, 3] -= g * Y
        return out.ravel()

    sol = solve_ivp(rhs, (0.0, dt), x.ravel(), method="DOP853", rtol=ODE_RTOL, atol=ODE_ATOL)
    if not sol.success:
        raise ValueError(f"x: the orbit ODE failed ({sol.message})")
    return sol.y[:, -1].reshape(shape)


@checked(n_runs=_n_runs, process_noise=require_bool)
def simulate_truth(params: OrbitParams | None = None, seed=None, n_runs: int | None = None, x0=None,
                   process_noise: bool = True, integrator: str = "solve_ivp") -> np.ndarray:
    """True states at t_k = k dt, (K, 4) or (n_runs, K, 4) [km, km/s, km, km/s]:
    ``x_{k+1} = f_d(x_k) + Omega w_k`` (the module docstring).

    seed : int or numpy Generator (advanced by the draws), None for an unseeded one; x0 : (4,) or
    (n_runs, 4) initial states (default: drawn from N(params.x0, params.P0)); process_noise : False for
    the noise-free orbit; integrator : "solve_ivp" or "rk4" (:data:`INTEGRATORS`).  The draws: initial
    states, then ``w_k`` (K - 1 per run).
    """
    integrator = require_choice("integrator", integrator, INTEGRATORS)
    p, K = params_or_default(params), params_or_default(params).n_samples
    runs = () if n_runs is None else (require_int("n_runs", n_runs, minimum=1),)
    rng = np.random.default_rng() if seed is None else as_generator("seed", seed)
    start = p.x0 + _gaussian(rng, p.P0, runs) if x0 is None else require_states("x0", x0) + np.zeros(runs + (N_STATES,))
    w = _gaussian(rng, p.Qtrue, runs + (K - 1,)) if process_noise else np.zeros(runs + (K - 1, N_NOISE))
    x = np.empty(runs + (K, N_STATES))
    x[..., 0, :] = start
    kick = w @ p.Omega.T  # (..., K - 1, 4): Omega w_k, a velocity change dt w_k
    for k in range(K - 1):
        if integrator == "rk4":
            flow = rk4_flow(x[..., k, :], p.dt, p.mu, RK4_TRUTH_SUBSTEPS)
        else:
            flow = integrate(x[..., k, :], p)
        x[..., k + 1, :] = flow + kick[..., k, :]
    return x


@checked(first=require_bool)
def simulate_measurements(truth, params: OrbitParams | None = None, seed=None, first: bool = False) -> np.ndarray:
    """Noisy measurements of the stations that see ``truth`` (..., K, 4): shape (..., K, n_stations, 3),
    ``[rho, rhodot, phi]`` (km, km/s, rad, phi wrapped), NaN for a station that does not see the
    satellite and, unless ``first``, at k = 0.  The noise is drawn for every station (seeded the same
    whichever are visible)."""
    p = params_or_default(params)
    rng = np.random.default_rng() if seed is None else as_generator("seed", seed)
    truth = require_states("truth", truth)
    if truth.ndim < 2:
        raise ValueError(f"truth must have shape (..., K, 4), got {truth.shape}")
    d, st = relative_states(truth, p.dt * np.arange(truth.shape[-2]), p)  # stations once per step
    # in place, each large temporary freed before the next is made (the Monte Carlo's peak memory)
    y = measure_relative(d)
    hidden = ~horizon(d, st)
    del d
    y += _gaussian(rng, p.Rtrue, truth.shape[:-1] + (p.n_stations,))
    y[..., PHI] = wrap_angle(y[..., PHI])
    y[hidden] = np.nan
    if not first:
        y[..., 0, :, :] = np.nan
    return y


def to_columns(y) -> tuple:
    """The course's per-step columns of dense measurements ``y`` (K, n_stations, 3): a tuple of K arrays
    (4, m_k), one column ``[rho; rhodot; phi; station id]`` per station with a measurement (ids from 1,
    in increasing order), (4, 0) where none."""
    y = require_array("y", y)
    if y.ndim != 3 or y.shape[2] != N_STATION_MEAS:
        raise ValueError(f"y must have shape (K, n_stations, 3), got {y.shape}")
    out = []
    for yk in y:
        ids = np.flatnonzero(np.isfinite(yk).all(axis=1))
        out.append(np.vstack([yk[ids].T, ids + 1.0]) if ids.size else np.empty((4, 0)))
    return tuple(out)


def from_columns(ydata, n_stations: int = 12) -> np.ndarray:
    """Dense measurements (K, n_stations, 3) (NaN where a station has no column) from the course's
    per-step columns ``ydata``: a sequence of K arrays (4, m_k) ``[rho; rhodot; phi; station id]``
    (ids 1..n_stations, each at most once per step; a step with none may be empty)."""
    n_stations = require_int("n_stations", n_stations, minimum=1, maximum=MAX_STATIONS)
    ydata = require_sequence("ydata", ydata)
    out = np.full((len(ydata), n_stations, N_STATION_MEAS), np.nan)
    for k, cols in enumerate(ydata):
        cols = np.asarray(cols, dtype=float)
        if cols.size == 0:
            continue
        if cols.ndim != 2 or cols.shape[0] != 4 or not np.isfinite(cols).all():
            raise ValueError(f"ydata[{k}] must be a (4, m) array of finite numbers [rho; rhodot; phi; station id], "
                             f"got shape {cols.shape}")
        ids = cols[3]
        if np.any(ids != np.round(ids)) or np.any(ids < 1) or np.any(ids > n_stations) \
                or len(set(ids.tolist())) != ids.size:
            raise ValueError(f"ydata[{k}]: station ids must be distinct integers in 1..{n_stations}, got {ids.tolist()}")
        out[k, ids.astype(int) - 1] = cols[:3].T
    return out


@dataclass(frozen=True, eq=False)
class OrbitLog:
    """An observation log in the course's format.

    t : (K,) s; ydata : tuple of K arrays (4, m_k), columns ``[rho; rhodot; phi; station id]`` (km, km/s,
    rad, 1..n_stations); Qtrue (2, 2), Rtrue (3, 3): the noise covariances the log was made with;
    truth : (K, 4) true states when known (a simulated log), else None; source : where it came from
    """

    t: np.ndarray
    ydata: tuple
    Qtrue: np.ndarray
    Rtrue: np.ndarray
    n_stations: int = 12
    truth: np.ndarray | None = None
    source: str = ""

    def __post_init__(self):
        stations = require_int("n_stations", self.n_stations, minimum=1, maximum=MAX_STATIONS)
        K = len(from_columns(self.ydata, stations))
        require_finite_array("t", self.t, shape=(K,))
        require_covariance("Qtrue", self.Qtrue, N_NOISE)
        require_covariance("Rtrue", self.Rtrue, N_STATION_MEAS)
        if self.truth is not None:
            require_finite_array("truth", self.truth, shape=(K, N_STATES))
        require_text("source", self.source)

    @property
    def y(self) -> np.ndarray:
        """The dense measurements (K, n_stations, 3), NaN where a station has none."""
        return from_columns(self.ydata, self.n_stations)

    @property
    def dof(self) -> np.ndarray:
        """Measurement components per step, (K,) ints: 3 per station with a column."""
        return np.array([3 * np.asarray(c).reshape(4, -1).shape[1] for c in self.ydata])


@dataclass(frozen=True, eq=False)
class Simulation:
    """One seeded draw of the truth model.

    params : OrbitParams (its ``t`` are the sample times); seed : the int seed (None when a Generator was given)
    truth : (K, 4) or (n_runs, K, 4) true states
    y : (K, n_stations, 3) or (n_runs, K, n_stations, 3) dense measurements, NaN where none
    """

    params: OrbitParams
    seed: int | None
    truth: np.ndarray
    y: np.ndarray

    def log(self, run: int | None = None) -> OrbitLog:
        """The draw (run ``run`` of several; None for a single-run draw) as a course-format
        :class:`OrbitLog`, with its truth."""
        runs = self.n_runs
        single = runs is None and run is None
        chosen = runs is not None and isinstance(run, (int, np.integer)) and not isinstance(run, bool) \
            and 0 <= run < runs
        if not (single or chosen):
            allowed = "None (a single-run draw)" if runs is None else f"an integer in 0..{runs - 1}"
            raise ValueError(f"run must be {allowed}, got {run!r}")
        pick = (lambda a: a) if single else (lambda a: a[run])
        p = self.params
        where = "simulated" if self.seed is None else f"simulated (seed {self.seed})"
        return OrbitLog(p.t, to_columns(pick(self.y)), p.Qtrue, p.Rtrue, p.n_stations, pick(self.truth), where)

    @property
    def n_runs(self) -> int | None:
        """How many runs the draw holds; None when its arrays have no run axis (one run)."""
        return self.truth.shape[0] if self.truth.ndim == 3 else None


@checked(n_runs=_n_runs, every=partial(require_int, minimum=1, maximum=MAX_STEPS), first=require_bool)
def simulate(params: OrbitParams | None = None, n_runs: int | None = None, seed=DEFAULT_LOG_SEED, *,
             every: int = 1, first: bool = False, integrator: str = "solve_ivp") -> Simulation:
    """Truths and measurements of the truth model from one seeded generator.

    params : OrbitParams (default the course's); n_runs : None for one run, else the number of runs;
    seed : int or numpy Generator (default :data:`DEFAULT_LOG_SEED`, the generated log); every : keep the
    measurements of every ``every``-th step only (larger gaps); first : also measure at t_0; integrator :
    how the truth is integrated ("solve_ivp" or "rk4", :data:`INTEGRATORS`).
    The truths are drawn first (initial states, then process noise), then the measurement noise.
    """
    p = params_or_default(params)
    every = require_int("every", every, minimum=1)
    seed_value = None if isinstance(seed, np.random.Generator) else seed
    rng = as_generator("seed", seed)
    truth = simulate_truth(p, rng, n_runs=n_runs, integrator=integrator)
    y = simulate_measurements(truth, p, rng, first=first)
    if every > 1:
        drop = np.ones(p.n_samples, dtype=bool)
        drop[::every] = False
        y[..., drop, :, :] = np.nan
    return Simulation(p, None if seed_value is None else int(seed_value), truth, y)
