"""Parameters of the accelerometer-calibration problem."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

from ..validation import require_finite, require_positive

__all__ = ["CalibrationParams", "MAX_SAMPLES"]

MAX_SAMPLES = 1e12  #: most IMU samples (duration * imu_rate) a scenario may describe


@dataclass(frozen=True)
class CalibrationParams:
    """All inputs of the calibration problem, validated on construction.

    Units: accelerations m/s^2, velocities m/s, positions m, rates Hz,
    times s, angular frequency rad/s, variances in the squared units.

    The defaults are the course problem's: 200 Hz IMU, 5 Hz GPS, 30 s, ``a(t) = 10 sin(0.2 t)``.
    """

    A: float = 10.0  #: acceleration amplitude, m/s^2
    omega: float = 0.2  #: angular frequency of the acceleration, rad/s (0 < omega <= pi imu_rate; A = 0 for none)
    imu_rate: float = 200.0  #: IMU sampling rate, Hz
    gps_rate: float = 5.0  #: GPS fix rate, Hz (must divide imu_rate)
    duration: float = 30.0  #: length of the run, s
    bias_mean: float = 0.0  #: prior mean of the accelerometer bias, m/s^2
    bias_var: float = 0.01  #: prior variance of the bias M_b, (m/s^2)^2
    W: float = 0.0004  #: IMU white-noise variance per sample, (m/s^2)^2
    p0_mean: float = 0.0  #: prior mean of the initial position, m
    p0_var: float = 100.0  #: prior variance of the initial position M_p, m^2
    v0_mean: float = 100.0  #: prior mean of the initial velocity, m/s
    v0_var: float = 1.0  #: prior variance of the initial velocity M_v, (m/s)^2
    gps_pos_var: float = 1.0  #: GPS position noise variance, m^2
    gps_vel_var: float = 0.0016  #: GPS velocity noise variance, (m/s)^2

    def __post_init__(self):
        for name in ("A", "bias_mean", "p0_mean", "v0_mean"):
            object.__setattr__(self, name, require_finite(name, getattr(self, name)))
        for name in ("omega", "imu_rate", "gps_rate", "duration", "bias_var", "W", "p0_var",
                     "v0_var", "gps_pos_var", "gps_vel_var"):
            object.__setattr__(self, name, require_positive(name, getattr(self, name)))
        if self.omega > math.pi * self.imu_rate:
            raise ValueError(f"omega must be at most pi * imu_rate = {math.pi * self.imu_rate:g} rad/s (the IMU's "
                             f"Nyquist frequency: a faster acceleration is not sampled), got {self.omega:g} rad/s")
        if self.imu_rate / self.gps_rate > MAX_SAMPLES:
            raise ValueError(f"imu_rate / gps_rate must be at most {MAX_SAMPLES:g} IMU samples per GPS period, got "
                             f"imu_rate={self.imu_rate:g} Hz, gps_rate={self.gps_rate:g} Hz")
        if self.duration * self.imu_rate > MAX_SAMPLES:
            raise ValueError(f"duration * imu_rate must be at most {MAX_SAMPLES:g} IMU samples, got "
                             f"duration={self.duration:g} s, imu_rate={self.imu_rate:g} Hz")
        ratio = self.imu_rate / self.gps_rate
        if abs(ratio - round(ratio)) > 1e-9 * ratio or round(ratio) < 1:
            raise ValueError(
                f"gps_rate must divide imu_rate (imu_rate/gps_rate a whole number >= 1), "
                f"got imu_rate={self.imu_rate:g} Hz, gps_rate={self.gps_rate:g} Hz"
            )
        steps = self.duration * self.imu_rate
        if abs(steps - round(steps)) > 1e-9 * steps:
            raise ValueError(
                f"duration must be a whole number of IMU periods (1/imu_rate = {1 / self.imu_rate:g} s), "
                f"got {self.duration:g} s"
            )
        if self.duration < 1.0 / self.gps_rate - 1e-12:
            raise ValueError(
                f"duration must be at least one GPS period ({1 / self.gps_rate:g} s), got {self.duration:g} s"
            )

    # Derived quantities --------------------------------------------------
    @property
    def dt(self) -> float:
        """IMU sampling interval, s."""
        return 1.0 / self.imu_rate

    @property
    def steps_per_fix(self) -> int:
        """IMU samples per GPS period (40 for the defaults)."""
        return int(round(self.imu_rate / self.gps_rate))

    @property
    def n_imu(self) -> int:
        """Number of IMU samples t_j = j*dt, j = 0..n_imu-1 (6001 for the defaults)."""
        return int(round(self.duration * self.imu_rate)) + 1

    @property
    def fix_indices(self) -> np.ndarray:
        """IMU sample indices of the GPS fixes, shape (n_gps,): 0, 40, 80, ..."""
        return np.arange(0, self.n_imu, self.steps_per_fix)

    @property
    def n_gps(self) -> int:
        """Number of GPS fixes (151 for the defaults)."""
        return len(self.fix_indices)

    @property
    def t_imu(self) -> np.ndarray:
        """IMU sample times, s, shape (n_imu,)."""
        return np.arange(self.n_imu) * self.dt

    @property
    def t_gps(self) -> np.ndarray:
        """GPS fix times, s, shape (n_gps,)."""
        return self.t_imu[self.fix_indices]

    def replace(self, **changes) -> "CalibrationParams":
        """A copy with some fields changed (validated again); ValueError for a name that is not a field."""
        unknown = sorted(set(changes) - {f.name for f in fields(self)})
        if unknown:
            raise ValueError(f"changes must name fields of CalibrationParams, got {unknown}")
        return replace(self, **changes)
