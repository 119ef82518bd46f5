"""The sampling bands of kfcal_helpers.consistency: the formulas, their level on simulated draws, and
argument checks naming the argument."""

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
