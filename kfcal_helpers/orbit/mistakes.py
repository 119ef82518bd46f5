"""The orbit-determination mistakes of course reports, for the mistakes table (notebook 14).

Each row is a truth-model test (the checks of :meth:`~kfcal_helpers.orbit.montecarlo.MonteCarloResult.checks`,
:data:`N_RUNS` runs, seed :data:`SEED`: every row draws the same truths and noise) of the EKF with one mistake,
after the correct EKF:

* ``orbit_nis_fixed_dof`` -- the filter is right, the NIS band is not: built for 3 dof (one station) at every
  step with a measurement, where two stations give 6;
* ``orbit_no_rotation`` -- the filter's stations stay where they are at t = 0 (``omegaE = 0`` in its model);
* ``orbit_inertial_rhodot`` -- the filter's ``rhodot`` from the satellite's inertial velocity, the station's
  velocity not subtracted (its Jacobian consistent with that);
* ``orbit_no_wrap`` -- phi innovations not wrapped (filterpy's default ``z - h(x)``);
* ``orbit_visibility`` -- the truth model's visibility test ``|phi_i - theta_i| < pi/2`` without wrapping the
  difference (theta_i grows past pi): the data lose the passes of the stations at theta_i > pi/2, the filter
  is right;
* ``orbit_omega_gamma`` -- the noise entering as ``Omega = Gamma`` (dt forgotten): the filter's state noise
  ``Gamma Q Gamma^T`` is 1/dt^2 = 1/100 of the truth model's ``dt^2 Gamma Q Gamma^T``.

The rows whose mistake is in the measurement model (``orbit_inertial_rhodot``, ``orbit_no_wrap``) run
filterpy's EKF (:class:`~kfcal_helpers.orbit.filters.OrbitEKF` with the mistaken method) run by run; the
others the batched EKF.  :func:`mistake_row` is the problem's ``mistake_row`` of
:class:`kfcal_helpers.registry.Problem`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.linalg import cholesky

from .. import montecarlo as core
from ..consistency import nees as nees_of
from ..consistency import step_checks
from ..registry import MistakeRow
from ..validation import require_choice, require_instance, require_int, require_significance
from .batch import run_batch
from .filters import FilterSetup, OrbitEKF, make_ekf, stations_at
from .model import jacobian_relative, measure_relative, relative_states, station_angles, station_states, wrap_phi
from .montecarlo import MonteCarloResult, OrbitExperiment
from .params import N_STATES, N_STATION_MEAS, OrbitParams
from .simulation import simulate, simulate_truth

__all__ = ["MISTAKES", "N_RUNS", "SEED", "InertialRhodotEKF", "NoWrapEKF", "MistakeExperiment", "orbit_case",
           "mistake_row", "wrong_visibility_measurements"]

#: orbit mistakes, the correct filter first: name -> what is wrong
MISTAKES = {
    "orbit_ekf_correct": "the correct EKF (rotating stations, relative velocity in rhodot, phi wrapped, Omega = dt Gamma)",
    "orbit_nis_fixed_dof": "NIS band built for 3 dof at every step, where two stations give 6",
    "orbit_no_rotation": "the filter's stations fixed where they are at t = 0 (Earth's rotation forgotten)",
    "orbit_inertial_rhodot": "rhodot from the satellite's inertial velocity (station velocity not subtracted)",
    "orbit_no_wrap": "phi innovations not wrapped",
    "orbit_visibility": "visibility |phi - theta| < pi/2 without wrapping the difference (truth model's data)",
    "orbit_omega_gamma": "noise entering as Omega = Gamma (dt forgotten): filter state noise 1/100 of the truth's",
}

N_RUNS = 50  #: runs of a row's truth-model test by default
SEED = 11  #: seed of every row by default: the rows differ only by the mistake


class NoWrapEKF(OrbitEKF):
    """:class:`OrbitEKF` whose innovation ``z - h(x)`` leaves phi unwrapped (the mistake)."""

    @staticmethod
    def residual_z(a, b):
        return a - b


class InertialRhodotEKF(OrbitEKF):
    """:class:`OrbitEKF` whose ``rhodot`` uses the satellite's inertial velocity: the stations' positions
    rotate, their velocity is left out (the mistake); the Jacobian is that of this measurement."""

    def _relative(self, x, t, stations):
        st = station_states(t, self.setup.params)[np.asarray(stations, dtype=int)]
        st[:, 1] = st[:, 3] = 0.0
        return x[:, 0] - st  # (m, 4)

    def hx(self, x, t, stations):
        return measure_relative(self._relative(x, t, stations)).reshape(-1, 1)

    def H_jacobian(self, x, t, stations):
        return jacobian_relative(self._relative(x, t, stations)).reshape(-1, N_STATES)


def _run_per_run(ekf_class, setup: FilterSetup, y, truth) -> tuple:
    """filterpy's EKF ``ekf_class`` on one run's ``y`` (K, n_stations, 3): (nees, nis, dof, errors, sigma2)."""
    ekf = ekf_class(setup)
    start = make_ekf(setup)
    ekf.x, ekf.P, ekf.Q = start.x, start.P, start.Q
    p = setup.params
    K = y.shape[0]
    nis, dof = np.full(K, np.nan), np.zeros(K, dtype=int)
    x, P = np.empty((K, N_STATES)), np.empty((K, N_STATES, N_STATES))
    for k, ids in enumerate(stations_at(y)):
        if k > 0:
            ekf.predict()
        if ids.size:
            step = (p.dt * k, ids)
            ekf.update(y[k, ids].reshape(-1, 1), HJacobian=ekf.H_jacobian, Hx=ekf.hx, R=setup.station_R(ids.size),
                       args=step, hx_args=step, residual=ekf.residual_z)
            nu = ekf.y[:, 0]
            nis[k], dof[k] = float(nu @ np.linalg.solve(ekf.S, nu)), N_STATION_MEAS * ids.size
        x[k], P[k] = ekf.x[:, 0], ekf.P
    errors = truth - x
    return nees_of(errors, P), nis, dof, errors, 2.0 * np.sqrt(np.diagonal(P, axis1=-2, axis2=-1))


def wrong_visibility_measurements(truth, params: OrbitParams, rng) -> np.ndarray:
    """Noisy measurements (..., K, n_stations, 3) of ``truth`` (..., K, 4) like
    :func:`~kfcal_helpers.orbit.simulation.simulate_measurements` (the same draws), but a station counts as
    seeing the satellite when ``|phi_i - theta_i| < pi/2`` with ``theta_i`` not wrapped (the mistake)."""
    p = params
    t = p.dt * np.arange(truth.shape[-2])
    d, _ = relative_states(truth, t, p)
    noise = rng.standard_normal(truth.shape[:-1] + (p.n_stations, N_STATION_MEAS)) @ cholesky(p.Rtrue, lower=True).T
    clean = measure_relative(d)
    y = wrap_phi(clean + noise)
    y[np.abs(clean[..., 2] - station_angles(t, p)) >= np.pi / 2] = np.nan
    y[..., 0, :, :] = np.nan
    return y


class MistakeExperiment(OrbitExperiment):
    """A truth-model test whose truth model (``truth_params``, the visibility rule) or filter differs from the
    correct one: :class:`~kfcal_helpers.orbit.montecarlo.OrbitExperiment` with

    setup : the (mistaken) filter's FilterSetup; truth_params : OrbitParams of the truth model (default
    ``setup.params``); ekf_class : None (the batched filter of ``setup``) or an :class:`OrbitEKF` subclass run
    by filterpy run by run; wrong_visibility : the truth model's data with :func:`wrong_visibility_measurements`.
    """

    #: one-thread seconds per run of 1401 steps of filterpy's EKF (measured 0.74 s, rounded up)
    SECONDS_PER_EKF_RUN = 1.5

    def __init__(self, setup: FilterSetup, n_runs: int | None = None, alpha: float = 0.05, *, truth_params=None,
                 ekf_class=None, wrong_visibility: bool = False):
        super().__init__(setup, n_runs, alpha)
        self.truth_params = require_instance("truth_params", truth_params, OrbitParams, allow_none=True) or setup.params
        if ekf_class is not None and not (isinstance(ekf_class, type) and issubclass(ekf_class, OrbitEKF)):
            raise ValueError(f"ekf_class must be None or a subclass of OrbitEKF, got {ekf_class!r}")
        self.ekf_class = ekf_class
        self.wrong_visibility = bool(wrong_visibility)

    def seconds(self, n_runs: int) -> float:
        extra = self.SECONDS_PER_EKF_RUN * n_runs * self.K / 1401 if self.ekf_class is not None else 0.0
        return super().seconds(n_runs) + extra

    def run_chunk(self, size, rng, chunk):
        p = self.truth_params
        if self.wrong_visibility:
            truth = simulate_truth(p, rng, n_runs=size, integrator=self.integrator)
            y = wrong_visibility_measurements(truth, p, rng)
        else:
            sim = simulate(p, size, rng, integrator=self.integrator)
            truth, y = sim.truth, sim.y
        chunk.check()
        if self.ekf_class is None:
            b = run_batch(y, self.setup, truth)
            return b.nees, b.nis, b.dof, b.errors, b.sigma2
        runs = []
        for r in range(size):
            chunk.check()
            runs.append(_run_per_run(self.ekf_class, self.setup, y[r], truth[r]))
            chunk.tick(1)
        return tuple(np.stack(parts) for parts in zip(*runs))


def orbit_case(mistake: str, params: OrbitParams | None = None) -> dict:
    """The :class:`MistakeExperiment` keywords of a row (``setup``, ``truth_params``, ``ekf_class``,
    ``wrong_visibility``) for the truth model ``params`` (default the course's)."""
    mistake = require_choice("mistake", mistake, tuple(MISTAKES))
    p = require_instance("params", params, OrbitParams, allow_none=True) or OrbitParams()
    case = {"setup": FilterSetup("ekf", p), "truth_params": p, "ekf_class": None, "wrong_visibility": False}
    if mistake == "orbit_no_rotation":
        case["setup"] = FilterSetup("ekf", replace(p, omegaE=0.0))
    elif mistake == "orbit_inertial_rhodot":
        case["ekf_class"] = InertialRhodotEKF
    elif mistake == "orbit_no_wrap":
        case["ekf_class"] = NoWrapEKF
    elif mistake == "orbit_visibility":
        case["wrong_visibility"] = True
    elif mistake == "orbit_omega_gamma":
        case["setup"] = FilterSetup("ekf", p, Q=p.Qtrue / p.dt**2)
    return case


def _fixed_dof_checks(mc: MonteCarloResult) -> dict:
    """``mc``'s checks with the NIS band of 3 dof wherever a run has a measurement (the mistake)."""
    checks = mc.checks()
    fixed = np.where(mc.dof > 0, N_STATION_MEAS, 0)
    checks["nis"] = step_checks(mc.nees, mc.nis, fixed, N_STATES, mc.alpha,
                                extra_entries=checks["mean_error"].statistic.size)["nis"]
    return checks


def mistake_row(mistake: str, n_runs: int | None = None, params: OrbitParams | None = None, alpha: float = 0.05,
                seed: int = SEED) -> MistakeRow:
    """Truth-model test of the orbit EKF with ``mistake`` (:data:`MISTAKES`, :func:`orbit_case`).

    n_runs : runs, >= 2 (None: :data:`N_RUNS`); params : OrbitParams of the truth model (None: the course's);
    alpha : family-wise level of the checks, in (0, 1); seed : int >= 0.
    Returns a :class:`~kfcal_helpers.registry.MistakeRow` whose ``checks`` are the result's checks (for
    ``orbit_nis_fixed_dof``, with the NIS band of 3 dof).
    """
    case = orbit_case(mistake, params)
    n_runs = N_RUNS if n_runs is None else require_int("n_runs", n_runs, minimum=2)
    alpha = require_significance("alpha", alpha)
    exp = MistakeExperiment(case.pop("setup"), alpha=alpha, **case)
    mc = core.run(exp, n_runs, seed, progress=None, desc=f"orbit row {mistake}")
    checks = _fixed_dof_checks(mc) if mistake == "orbit_nis_fixed_dof" else mc.checks()
    return MistakeRow("orbit", mistake, MISTAKES[mistake], checks, mc)
