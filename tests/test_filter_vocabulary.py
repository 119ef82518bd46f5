"""``filter`` means one thing in every problem: the algorithm ("kf" in the calibration, "lkf", "ekf" or
"ukf" in coop and orbit).  How the calibration's Kalman filter is run (vectorised or filterpy run by
run) is its ``engine``; code written when ``filter`` named the engine still runs, silently."""

import warnings

import numpy as np
import pytest

from kfcal_helpers import calibration, coop, orbit
from kfcal_helpers.calibration import CalibrationParams, run_monte_carlo
from kfcal_helpers.calibration.figures import CalibrationCase
from kfcal_helpers.calibration.montecarlo import CalibrationExperiment, chunks_in_flight, estimate_run
from kfcal_helpers.consistency import MonteCarloSummary

P0 = CalibrationParams(duration=2.0)


def test_filter_is_the_algorithm_in_every_problem():
    results = {
        "calibration": (run_monte_carlo(P0, 4, seed=1), calibration.FILTERS),
        "coop": (coop.truth_model_test(n_runs=2, seed=1, filter="ekf"), coop.FILTERS),
        "orbit": (orbit.truth_model_test(n_runs=2, seed=1, filter="ukf"), orbit.FILTERS),
    }
    for problem, (mc, algorithms) in results.items():
        assert isinstance(mc, MonteCarloSummary), problem
        assert mc.filter in algorithms, (problem, mc.filter)
    assert results["calibration"][0].filter == "kf" and results["calibration"][0].engine == "batch"
    assert (results["coop"][0].filter, results["orbit"][0].filter) == ("ekf", "ukf")
    # the engines are not algorithms of any problem
    assert not set(calibration.ENGINES) & {*calibration.FILTERS, *coop.FILTERS, *orbit.FILTERS}


@pytest.mark.parametrize("engine", ["batch", "filterpy"])
def test_the_old_keyword_still_runs_silently(engine):
    new = run_monte_carlo(P0, 4, seed=3, engine=engine)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning may reach a user
        old = run_monte_carlo(P0, 4, seed=3, filter=engine)
        case = CalibrationCase(P0, n_runs=4, seed=3, filter=engine)
        assert estimate_run(P0, 4, filter=engine) == estimate_run(P0, 4, engine=engine)
        assert chunks_in_flight(P0, 4, filter=engine) == chunks_in_flight(P0, 4, engine=engine)
        assert CalibrationExperiment(P0, filter=engine).engine == engine
    assert (old.engine, old.filter, case.engine) == (engine, "kf", engine)
    np.testing.assert_array_equal(old.e_cov, new.e_cov)
    np.testing.assert_array_equal(old.nees, new.nees)
    assert run_monte_carlo(P0, 4, seed=3, engine=engine, filter="kf").engine == engine


def test_filter_and_engine_refuse_what_they_do_not_name():
    with pytest.raises(ValueError, match=r"^filter must be 'kf'.*got 'ekf'$"):
        run_monte_carlo(P0, 4, filter="ekf")
    with pytest.raises(ValueError, match="^engine must be"):
        run_monte_carlo(P0, 4, engine="kf")
    with pytest.raises(ValueError, match="^filter='batch' names an engine other than engine='filterpy'"):
        run_monte_carlo(P0, 4, engine="filterpy", filter="batch")
    with pytest.raises(ValueError, match="^filter must be"):
        CalibrationCase(P0, filter=3)


@pytest.mark.parametrize("run", [lambda **kw: run_monte_carlo(P0, **{"n_runs": 4, **kw}),
                                 lambda **kw: coop.truth_model_test(**{"n_runs": 2, **kw}),
                                 lambda **kw: orbit.truth_model_test(**{"n_runs": 2, **kw})],
                         ids=["calibration", "coop", "orbit"])
@pytest.mark.parametrize("name, value", [("n_runs", 0), ("n_runs", 2.5), ("n_runs", True), ("seed", -1),
                                         ("seed", "1"), ("workers", 0), ("alpha", 2.0)])
def test_seed_runs_and_workers_are_refused_in_one_line(run, name, value):
    """Each argument is checked once (``@checked`` or the shared core), with one line naming it."""
    with pytest.raises(ValueError) as info:
        run(**{name: value})
    message = str(info.value)
    assert message.startswith(name) and "\n" not in message
