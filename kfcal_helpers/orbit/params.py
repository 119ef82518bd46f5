"""Parameters of the orbit-determination problem: :class:`OrbitParams`.

A satellite in a planar orbit about a point-mass Earth, tracked by ground stations on the equator of
the rotating Earth.  Units throughout: km, s, rad (velocities km/s, accelerations km/s^2).

State ``x = [X, Xdot, Y, Ydot]`` (km, km/s, km, km/s) in the inertial frame; the process noise
``w = [w1, w2]`` (km/s^2) adds to the two accelerations.  Measurement of station ``i``:
``[rho_i, rhodot_i, phi_i]`` (km, km/s, rad).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..validation import require_covariance, require_finite, require_int, require_positive, require_shape

__all__ = ["N_STATES", "N_NOISE", "N_STATION_MEAS", "MAX_STATIONS", "MAX_STEPS", "OrbitParams"]

N_STATES = 4  #: [X, Xdot, Y, Ydot]
N_NOISE = 2  #: [w1, w2], accelerations
N_STATION_MEAS = 3  #: [rho, rhodot, phi] of one station
MAX_STATIONS = 36  #: most stations an OrbitParams may place (every 10 degrees)
#: most steps an OrbitParams may describe: a filter run keeps about 1 kB per step, a simulation 0.3 kB per
#: step and run (100,000 steps of 10 s are 11.6 days, over 180 orbits)
MAX_STEPS = 100_000


def _matrix(values):
    return field(default_factory=lambda: np.diag(np.array(values, dtype=float)))


def _read_only(array) -> np.ndarray:
    out = np.array(array, dtype=float)
    out.setflags(write=False)
    return out


def _vector(values):
    return field(default_factory=lambda: np.array(values, dtype=float))


@dataclass(frozen=True, eq=False)
class OrbitParams:
    """All inputs of the orbit-determination problem, validated on construction (arrays stored read-only).

    mu : gravitational parameter of the Earth, km^3/s^2 (398600)
    r0 : radius of the nominal circular orbit, km (6678: 300 km altitude)
    RE : radius of the Earth, on which the stations sit, km (6378)
    omegaE : rotation rate of the Earth, rad/s (2 pi / 86400)
    dt : sampling interval, s (10); n_steps : steps after t_0 (1400: t = 0 ... 14000 s, 1401 samples; at
        most :data:`MAX_STEPS`)
    n_stations : stations, equally spaced on the equator (12: station i = 1..12 at angle
        ``omegaE t + (i - 1) 2 pi / n_stations``)
    Qtrue : (2, 2) covariance of the acceleration noise w_k, (km/s^2)^2, which enters each step as the
        velocity change ``Omega w_k = dt Gamma w_k`` (default ``1e-10 I``)
    Rtrue : (3, 3) covariance of one station's measurement noise, [km^2, (km/s)^2, rad^2]
        (default ``diag(0.01, 1, 0.01)``)
    dx0 : (4,) the initial perturbation from the nominal, [km, km/s, km, km/s]
        (default ``[0, 0.075, 0, -0.021]``): the true initial state is about ``x_nom(0) + dx0``
    P0 : (4, 4) covariance of the initial state about ``x0`` (the truth-model tests draw the true initial
        state from N(x0, P0) and every filter starts at (x0, P0)), [km^2, (km/s)^2, ...]
        (default ``diag(0.01, 1e-6, 0.01, 1e-6)``: 100 m and 1 m/s, this package's choice)

    The defaults of ``Qtrue``, ``Rtrue`` and ``dx0`` are the values published with public solutions of
    this course problem; the units are those of the state and measurement above.
    """

    mu: float = 398600.0
    r0: float = 6678.0
    RE: float = 6378.0
    omegaE: float = 2.0 * math.pi / 86400.0
    dt: float = 10.0
    n_steps: int = 1400
    n_stations: int = 12
    Qtrue: np.ndarray = _matrix([1e-10, 1e-10])
    Rtrue: np.ndarray = _matrix([0.01, 1.0, 0.01])
    dx0: np.ndarray = _vector([0.0, 0.075, 0.0, -0.021])
    P0: np.ndarray = _matrix([0.01, 1e-6, 0.01, 1e-6])

    def __post_init__(self):
        for name in ("mu", "r0", "RE", "dt"):
            object.__setattr__(self, name, require_positive(name, getattr(self, name)))
        omega = require_finite("omegaE", self.omegaE)
        if omega < 0:
            raise ValueError(f"omegaE must be a finite number >= 0 (rad/s), got {omega!r}")
        object.__setattr__(self, "omegaE", float(omega))
        steps = require_int("n_steps", self.n_steps, minimum=1)
        if steps > MAX_STEPS:
            raise ValueError(f"n_steps must be an integer in 1..{MAX_STEPS}, got {steps}")
        object.__setattr__(self, "n_steps", steps)
        stations = require_int("n_stations", self.n_stations, minimum=1)
        if stations > MAX_STATIONS:
            raise ValueError(f"n_stations must be an integer in 1..{MAX_STATIONS}, got {stations}")
        object.__setattr__(self, "n_stations", stations)
        if self.RE >= self.r0:
            raise ValueError(f"r0 must be larger than RE (the orbit above the ground), got r0={self.r0:g} km, "
                             f"RE={self.RE:g} km")
        checked = (require_covariance("Qtrue", self.Qtrue, N_NOISE), require_covariance("Rtrue", self.Rtrue, N_STATION_MEAS),
                   require_shape("dx0", self.dx0, (N_STATES,)), require_covariance("P0", self.P0, N_STATES))
        if not np.isfinite(checked[2]).all():
            raise ValueError("dx0 must hold only finite numbers (km, km/s)")
        for name, value in zip(("Qtrue", "Rtrue", "dx0", "P0"), checked):
            object.__setattr__(self, name, _read_only(value))

    @property
    def n_samples(self) -> int:
        """Samples t_k = k dt, k = 0..n_steps (1401 for the defaults)."""
        return self.n_steps + 1

    @property
    def t(self) -> np.ndarray:
        """Sample times, s, shape (n_samples,)."""
        return self.dt * np.arange(self.n_samples)

    @property
    def n(self) -> float:
        """Mean motion of the nominal orbit ``sqrt(mu / r0^3)``, rad/s."""
        return math.sqrt(self.mu / self.r0**3)

    @property
    def period(self) -> float:
        """Period of the nominal orbit ``2 pi / n``, s (about 5431 s)."""
        return 2.0 * math.pi / self.n

    @property
    def x0(self) -> np.ndarray:
        """Initial state ``x_nom(0) + dx0``, (4,) [km, km/s, km, km/s]."""
        return np.array([self.r0, 0.0, 0.0, self.r0 * self.n]) + self.dx0

    @property
    def Gamma(self) -> np.ndarray:
        """CT noise input matrix (4, 2): the noise adds to the accelerations."""
        return np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 0.0], [0.0, 1.0]])

    @property
    def Omega(self) -> np.ndarray:
        """DT noise input matrix ``Omega = dt Gamma`` (4, 2), s: ``x_{k+1} = f_d(x_k) + Omega w_k``."""
        return self.dt * self.Gamma

    def process_noise(self, Q=None) -> np.ndarray:
        """Per-step state-noise covariance ``Omega Q Omega^T`` (4, 4) of the DT model for the covariance
        ``Q`` (2, 2) of w_k, (km/s^2)^2 (default ``Qtrue``)."""
        Q = self.Qtrue if Q is None else require_covariance("Q", Q, N_NOISE)
        Om = self.Omega
        return Om @ Q @ Om.T

    def station_R(self, m: int) -> np.ndarray:
        """Measurement-noise covariance (3m, 3m) of ``m`` stations stacked: ``Rtrue`` on the diagonal."""
        return np.kron(np.eye(m), self.Rtrue)
