"""The sampling bands of kfcal_helpers.consistency: the formulas, their level on simulated draws, and
argument checks naming the argument."""

from functools import partial

import numpy as np
import pytest
from scipy import stats

from kfcal_helpers.consistency import (chi2_bounds, correlation_band, normal_band, t_band,
                                       uncentred_correlation_band, variance_band)


def test_the_formulas():
    n, level = 40, 0.05
    assert t_band(2.0, n, level) == stats.t.ppf(0.975, 39) * 2.0 / np.sqrt(40)
    assert normal_band(4.0, n, level) == stats.norm.ppf(0.975) * np.sqrt(4.0 / 40)
    lo, hi = variance_band(np.array([1.0, 2.0]), 39, level)
    np.testing.assert_allclose(lo, np.array([1, 2]) * stats.chi2.ppf(0.025, 39) / 39, rtol=1e-15)
    np.testing.assert_allclose(hi, np.array([1, 2]) * stats.chi2.ppf(0.975, 39) / 39, rtol=1e-15)
    lo, hi = correlation_band(np.array([0.0, 0.5, 1.0]), n, level)
    f = stats.norm.ppf(0.975) / np.sqrt(37)
    np.testing.assert_allclose(lo, np.tanh(np.arctanh([0.0, 0.5]) - f).tolist() + [1.0])
    np.testing.assert_allclose(hi, np.tanh(np.arctanh([0.0, 0.5]) + f).tolist() + [1.0])
    lo, hi = correlation_band(np.array([0.3]), 3, level)  # too few runs for Fisher: any correlation
    assert lo[0] == -1.0 and hi[0] == 1.0
    # the uncentred correlation: rho^2 ~ Beta(1/2, (n - 1)/2) exactly
    assert np.isclose(uncentred_correlation_band(n, level), np.sqrt(stats.beta.ppf(0.95, 0.5, 19.5)), rtol=1e-12)
    lo, hi = chi2_bounds(3, n, level)
    assert (lo, hi) == (stats.chi2.ppf(0.025, 120) / 40, stats.chi2.ppf(0.975, 120) / 40)


def test_levels_on_simulated_draws():
    """Each band, fed draws of a consistent ensemble, leaves out a share ``level`` (binomial band)."""
    rng = np.random.default_rng(11)
    reps, n, level = 4000, 12, 0.1
    x = rng.standard_normal((reps, n)) * 3.0
    y = 0.6 * x / 3.0 + 0.8 * rng.standard_normal((reps, n))  # correlation 0.6 with x
    sd = x.std(axis=1, ddof=1)
    z = rng.standard_normal((reps, n)) * 0.1  # independent of x, zero mean, any scale
    shares = {
        "t": np.mean(np.abs(x.mean(1)) > t_band(sd, n, level)),
        "normal": np.mean(np.abs(x.mean(1)) > normal_band(9.0, n, level)),
        "variance": np.mean(~((sd**2 >= variance_band(9.0, n - 1, level)[0]) & (sd**2 <= variance_band(9.0, n - 1, level)[1]))),
        "uncentred": np.mean(np.abs((x * z).sum(1) / np.sqrt((x**2).sum(1) * (z**2).sum(1)))
                             > uncentred_correlation_band(n, level)),
    }
    rho = np.array([np.corrcoef(a, b)[0, 1] for a, b in zip(x, y)])
    lo, hi = correlation_band(0.6, n, level)
    shares["fisher"] = np.mean((rho < lo) | (rho > hi))
    sd_share = np.sqrt(level * (1 - level) / reps)
    for name, share in shares.items():
        # the Fisher band is approximate at n = 12; the others are exact
        assert abs(share - level) < (0.02 if name == "fisher" else 4 * sd_share), (name, share, shares)


@pytest.mark.parametrize("call, word", [
    (lambda: t_band(1.0, 1, 0.05), "n must be an integer >= 2"),
    (lambda: t_band(1.0, 10, 1.5), "level"),
    (lambda: normal_band(1.0, 0, 0.05), "n must be an integer >= 1"),
    (lambda: variance_band(1.0, 0, 0.05), "dof must be an integer >= 1"),
    (lambda: correlation_band(0.0, 10, 0.0), "level"),
    (lambda: uncentred_correlation_band(2.5, 0.05), "n must be an integer"),
])
def test_arguments_are_checked(call, word):
    with pytest.raises(ValueError, match=word):
        call()


def _cv_toy(n_runs: int, n_steps: int, seed: int, dt: float = 1.0):
    """A consistent filter on a 1-D constant-velocity toy (state [p, v], white-acceleration noise of unit
    intensity, unit-variance position fixes every step), vectorised over runs: NEES and NIS, each
    (n_runs, n_steps), and the draws of run 0 (truth, fixes) for the filterpy comparison."""
    rng = np.random.default_rng(seed)
    F = np.array([[1.0, dt], [0.0, 1.0]])
    Q = np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    H, R, P0 = np.array([[1.0, 0.0]]), 1.0, np.diag([10.0, 1.0])
    x = rng.multivariate_normal(np.zeros(2), P0, n_runs)
    x_hat, P = np.zeros((n_runs, 2)), P0.copy()
    chol_q = np.linalg.cholesky(Q)
    nees, nis = np.empty((n_runs, n_steps)), np.empty((n_runs, n_steps))
    truth0, z0 = [], []
    for k in range(n_steps):
        x = x @ F.T + rng.standard_normal((n_runs, 2)) @ chol_q.T
        z = x[:, 0] + np.sqrt(R) * rng.standard_normal(n_runs)
        x_hat, P = x_hat @ F.T, F @ P @ F.T + Q
        S = (H @ P @ H.T)[0, 0] + R
        gain = (P @ H.T)[:, 0] / S
        y = z - x_hat[:, 0]
        nis[:, k] = y**2 / S
        x_hat, P = x_hat + y[:, None] * gain, P - np.outer(gain, gain) * S
        e = x - x_hat
        nees[:, k] = np.einsum("ni,ij,nj->n", e, np.linalg.inv(P), e)
        truth0.append(x[0].copy()), z0.append(z[0])
    return nees, nis, (F, Q, H, R, P0, np.array(truth0), np.array(z0))


def test_time_average_band_holds_for_nis_not_for_nees():
    """consistency's docstring: chi2_bounds(dim, K) bounds one run's time-averaged NIS (white
    innovations), not its time-averaged NEES (errors correlated from step to step), so no one-run NEES
    band is reported (coop.filters.log_summary).  2000 runs x 100 steps of a consistent toy filter,
    checked equal to filterpy on run 0."""
    from filterpy.kalman import KalmanFilter

    n_runs, n_steps, alpha = 2000, 100, 0.05
    nees, nis, (F, Q, H, R, P0, truth0, z0) = _cv_toy(n_runs, n_steps, seed=7)
    kf = KalmanFilter(dim_x=2, dim_z=1)
    kf.x, kf.P, kf.F, kf.Q, kf.H, kf.R = np.zeros((2, 1)), P0.copy(), F, Q, H, np.array([[R]])
    for k in range(n_steps):
        kf.predict()
        kf.update(np.array([[z0[k]]]))
        e = truth0[k][:, None] - kf.x
        assert np.isclose((e.T @ np.linalg.inv(kf.P) @ e).item(), nees[0, k], rtol=1e-9)
        assert np.isclose(kf.mahalanobis**2, nis[0, k], rtol=1e-9)

    # the share of runs whose time average lies inside chi2_bounds(dim, K): 1 - alpha if the band is right
    share_sd = np.sqrt(alpha * (1 - alpha) / n_runs)
    nis_avg, nees_avg = nis.mean(axis=1), nees.mean(axis=1)
    lo, hi = chi2_bounds(1, n_steps, alpha)
    nis_share = np.mean((nis_avg >= lo) & (nis_avg <= hi))
    lo, hi = chi2_bounds(2, n_steps, alpha)
    nees_share = np.mean((nees_avg >= lo) & (nees_avg <= hi))
    assert abs(nis_share - (1 - alpha)) < 4 * share_sd            # 0.95 within 4 binomial SDs (0.0049)
    assert nees_share < 1 - alpha - 4 * share_sd                   # about 0.86: the band is too narrow
    # why: the time average's variance over runs against the 2 dim / K the independent-terms band assumes
    lo_v, hi_v = variance_band(np.array([1.0]), n_runs - 1, 1e-3)
    nis_ratio = np.var(nis_avg, ddof=1) / (2 * 1 / n_steps)
    nees_ratio = np.var(nees_avg, ddof=1) / (2 * 2 / n_steps)
    assert lo_v[0] < nis_ratio < hi_v[0]                            # about 1.0
    assert nees_ratio > hi_v[0]                                     # about 1.7


def test_check_from_band_and_the_bonferroni_level():
    """Check.from_band evaluates a band at the pointwise and the simultaneous level and broadcasts
    ``expected`` and the bounds to the statistic; Check.bonferroni splits alpha over the family."""
    from kfcal_helpers.consistency import Check, chi2_bounds

    assert Check.bonferroni(0.05, 10) == 0.05 / 10
    stat = np.array([1.5, 2.5, 9.0])
    c = Check.from_band("nees", "d", stat, 2, partial(chi2_bounds, 2, 20), 0.05, Check.bonferroni(0.05, 3))
    lo, hi = chi2_bounds(2, 20, 0.05)
    slo, shi = chi2_bounds(2, 20, 0.05 / 3)
    assert c.expected.dtype == float and list(c.expected) == [2.0] * 3
    assert list(c.lower) == [lo] * 3 and list(c.upper) == [hi] * 3
    assert list(c.sim_lower) == [slo] * 3 and list(c.sim_upper) == [shi] * 3
    assert c.inside_fraction == 2 / 3 and not c.passed
