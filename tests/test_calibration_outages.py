"""GPS outages: the mask, its parser, the CLI option, and the filter coasting through a gap."""

import numpy as np
import pytest

from kfcal_helpers.calibration import (CalibrationParams, covariance_sequence, outage_mask, parse_outage,
                                       run_filterpy, run_monte_carlo, simulate)
from kfcal_helpers.cli import main

PARAMS = CalibrationParams()


def test_mask_is_half_open():
    m = outage_mask(PARAMS, [(5.0, 10.0)])
    assert m.shape == (PARAMS.n_gps,) and m.dtype == bool
    t = PARAMS.t_gps
    assert m.sum() == 25
    assert m[np.isclose(t, 5.0)].all() and not m[np.isclose(t, 10.0)].any()
    assert not m[np.isclose(t, 4.8)].any() and m[np.isclose(t, 9.8)].all()


def test_mask_union_and_edges():
    m = outage_mask(PARAMS, [(0.0, 1.0), (0.5, 2.0), (29.0, 30.0)])
    assert m.sum() == 10 + 5
    assert not m[-1]  # the fix at 30 s is END, not inside
    assert not outage_mask(PARAMS, []).any()
    # a window between two fixes removes nothing
    assert not outage_mask(PARAMS, [(5.05, 5.15)]).any()


@pytest.mark.parametrize("windows", [[(5, 3)], [(2, 2)], [(-1, 2)], [(25, 31)], [(1, 2, 3)], [("a", 2)],
                                     [(np.nan, 2)], 5, [3]])
def test_mask_rejects_bad_windows(windows):
    with pytest.raises(ValueError, match="windows"):
        outage_mask(PARAMS, windows)


def test_parse_outage():
    assert parse_outage("5:10") == (5.0, 10.0)
    assert parse_outage(" 2.5 : 7 ") == (2.5, 7.0)
    for bad in ["5", "5:10:15", "a:b", "10:5", "3:3", "nan:4", ""]:
        with pytest.raises(ValueError, match="--outage"):
            parse_outage(bad)


@pytest.mark.parametrize("arg", ["x", "10:5", "25:31", "-1:2", "1:2:3"])
def test_cli_rejects_bad_outage(arg, capsys):
    assert main(["calibrate", "--runs", "5", f"--outage={arg}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--outage" in err


def test_cli_outage_runs(capsys):
    assert main(["calibrate", "--runs", "20", "--outage", "5:10", "--outage", "14:29", "--json"]) == 0
    import json

    d = json.loads(capsys.readouterr().out)
    assert d["n_runs"] == 20
    # the final sigma with outages is larger than without (fewer fixes)
    assert d["sigma_final"][2] > run_monte_carlo(PARAMS, 2, seed=0).sigma_final[2]


def test_filter_coasts_through_gap():
    windows = [(14.0, 29.0)]
    missing = outage_mask(PARAMS, windows)
    sim = simulate(PARAMS, 1, np.random.default_rng(3), missing_fixes=missing)
    fr = run_filterpy(PARAMS, sim.dz[0])
    P_seq = covariance_sequence(PARAMS, missing)[0]
    np.testing.assert_allclose(fr.P, P_seq, rtol=1e-10, atol=1e-18)
    j0 = int(round(13.8 * PARAMS.imu_rate))  # last fix before the gap
    j1 = int(round(29.0 * PARAMS.imu_rate))  # first fix after it
    for k in (0, 1):  # position and velocity variances grow at every step inside the gap
        assert np.all(np.diff(fr.P[j0:j1, k, k]) > 0)
        assert fr.P[j1, k, k] < fr.P[j1 - 1, k, k]  # and drop at the first fix back
    # the bias variance is frozen inside the gap (no process noise, no update)
    np.testing.assert_allclose(fr.P[j0:j1, 2, 2], fr.P[j0, 2, 2], rtol=1e-12)
    assert np.isnan(fr.y[missing]).all()
    assert np.all(fr.K[missing] == 0)


def test_monte_carlo_with_outage_is_consistent():
    missing = outage_mask(PARAMS, [(6.0, 11.0), (14.0, 29.0)])
    mc = run_monte_carlo(PARAMS, n_runs=500, seed=11, missing_fixes=missing)
    for name, c in mc.checks().items():
        assert c.passed, (name, c.worst)
    ratio = np.sqrt(np.einsum("iaa->ia", mc.e_cov[missing]) / np.einsum("iaa->ia", mc.P_post[missing]))
    assert np.all(np.abs(ratio - 1) < 0.1)
