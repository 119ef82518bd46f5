"""The two forms of the batch filter's 200 Hz sums between fixes agree: the Gram form (GPS periods of
at most ``_GRAM_MAX_STEPS`` IMU samples: per-period Gram matrices of the IMU noise) and the running-sum
form (longer periods: the running sums of the IMU noise, taken a few realizations at a time)."""

import numpy as np
import pytest

from kfcal_helpers.calibration import CalibrationParams, montecarlo, run_monte_carlo
from kfcal_helpers.calibration.mistakes import mistaken_model

SCENARIOS = {  # (params, truth, mistake): a partial last period, several blocks of realizations, Phi_f != Phi
    "default-euler": (CalibrationParams(duration=5.0), "euler", None),
    "partial-period-analytic": (CalibrationParams(duration=2.05), "analytic", None),
    "10-steps-mistaken-model": (CalibrationParams(imu_rate=100.0, gps_rate=10.0, duration=4.0), "euler",
                                "no_propagation"),
}


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_gram_form_equals_running_sum_form(name, monkeypatch):
    params, truth, mistake = SCENARIOS[name]
    model = None if mistake is None else mistaken_model(params, mistake)
    n = 300  # more than one block of realizations (montecarlo._GRAM_ROWS = 128), not a multiple of it
    assert params.steps_per_fix <= montecarlo._GRAM_MAX_STEPS and n > montecarlo._GRAM_ROWS
    gram = run_monte_carlo(params, n_runs=n, seed=7, truth=truth, model=model, between_fixes=True)
    monkeypatch.setattr(montecarlo, "_GRAM_MAX_STEPS", 0)  # every period takes the running-sum form
    running = run_monte_carlo(params, n_runs=n, seed=7, truth=truth, model=model, between_fixes=True)
    a, b = gram.between, running.between
    sd = np.sqrt(np.einsum("jaa->ja", b.e_cov))
    sd[sd == 0] = 1.0  # a component without noise (none expected): compare it unscaled
    np.testing.assert_allclose(a.e_mean / sd, b.e_mean / sd, rtol=0, atol=1e-9)
    scale = sd[:, :, None] * sd[:, None, :]
    np.testing.assert_allclose(a.e_cov / scale, b.e_cov / scale, rtol=0, atol=1e-9)
    assert not np.array_equal(a.e_cov, b.e_cov)  # both forms really ran (their rounding differs)
    plain = running.checks()
    for check_name, c in gram.checks().items():  # the seven checks at the fixes do not depend on it
        assert c.worst == plain[check_name].worst, check_name
