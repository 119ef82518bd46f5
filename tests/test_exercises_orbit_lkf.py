"""Exercise checks of notebook 21 (kfcal_helpers.orbit.exercises).

For every check: (1) it accepts the right answer, computed here by another route than the check's
(scipy.special.gammaincinv for the chi-square quantiles, the range/angle Jacobian written out by hand);
(2) it rejects each listed wrong answer, built here by making the mistake, with that mistake's hint;
(3) the placeholder gives "not answered yet"; (4) the exercise's numbers agree with the notebook's text.
"""

from pathlib import Path

import numpy as np
import pytest
from scipy.special import gammaincinv

from kfcal_helpers.exercises._core import ROUNDED_HINT
from kfcal_helpers.orbit import OrbitParams, nominal_state, station_states
from kfcal_helpers.orbit import exercises as orbit

SOURCE = Path(__file__).resolve().parents[1] / "notebooks" / "source" / "21_orbit_lkf.md"
HINTS = {ex: e.hints for ex, e in orbit.EXERCISES.items()}
P = OrbitParams()


def chi2_ppf(q, dof):
    return 2.0 * gammaincinv(dof / 2.0, q)


def band(m, alpha=0.05, per_run=None, divisor=None, tails=None):
    m = np.asarray(m)
    n = int(np.count_nonzero(m))
    dof = 3 * int(m.sum()) if per_run is None else per_run * n
    lo, hi = tails if tails is not None else (alpha / 2, 1 - alpha / 2)
    return np.array([chi2_ppf(lo, dof), chi2_ppf(hi, dof)]) / (n if divisor is None else divisor)


def test_21_1_accepts_the_dof_present_band():
    fb = orbit.check_nis_step_band(band(orbit.STEP_STATIONS))
    assert fb.correct and "66" in fb.message and "17 runs" in fb.message


@pytest.mark.parametrize("make,key", [
    (lambda m: band(m, per_run=3), "fixed3"),
    (lambda m: band(m, per_run=6), "fixed6"),
    (lambda m: band(m, divisor=len(m)), "all_runs"),
    (lambda m: band(m, per_run=3, divisor=len(m)), "all_runs"),
    (lambda m: band(m, tails=(0.05, 0.95)), "one_sided"),
    (lambda m: band(m, per_run=4), "state_dim"),
    (lambda m: band(m, divisor=1), "not_divided"),
])
def test_21_1_names_each_mistake(make, key):
    fb = orbit.check_nis_step_band(make(orbit.STEP_STATIONS))
    assert not fb.correct and fb.message == HINTS["21.1"][key]


def test_21_1_slips_placeholder_and_bad_answers():
    right = band(orbit.STEP_STATIONS)
    assert orbit.check_nis_step_band(np.round(right, 2)).message == ROUNDED_HINT
    assert not orbit.check_nis_step_band(right[::-1]).correct
    assert not orbit.check_nis_step_band(...).answered
    for bad in ("x", [1.0], np.full(2, np.nan), None):
        assert not orbit.check_nis_step_band(bad).correct
    with pytest.raises(ValueError, match="stations"):
        orbit.check_nis_step_band(right, stations=[0, 0])


def _H_by_hand(t):
    """Stacked [rho, rhodot, phi] rows of the stations that see the nominal at t, from the partials written out."""
    x = nominal_state(t, P)
    rows, ids = [], []
    for i, s in enumerate(station_states(t, P)):
        dX, dVX, dY, dVY = x - s
        if dX * s[0] + dY * s[2] <= 0:
            continue
        ids.append(i)
        r = np.hypot(dX, dY)
        rd = (dX * dVX + dY * dVY) / r
        rows += [[dX / r, 0, dY / r, 0],
                 [dVX / r - rd * dX / r**2, dX / r, dVY / r - rd * dY / r**2, dY / r],
                 [-dY / r**2, 0, dX / r**2, 0]]
    return np.array(ids), np.array(rows)


def test_21_2_accepts_S_and_names_each_mistake():
    ids, H = _H_by_hand(orbit.S_TIME)
    assert ids.tolist() == [0, 1] and orbit.step_stations_visible().tolist() == [0, 1]
    R = P.Rtrue
    HMH = H @ orbit.S_PRIOR @ H.T
    Rk = np.zeros((6, 6))
    Rk[:3, :3] = Rk[3:, 3:] = R
    assert orbit.check_two_station_S(HMH + Rk).correct
    interleaved = np.zeros((6, 6))
    for a in range(3):
        for b in range(3):
            interleaved[2 * a:2 * a + 2, 2 * b:2 * b + 2] = R[a, b] * np.eye(2)
    first = np.zeros((6, 6))
    first[:3, :3] = R
    for wrong, key in ((HMH + interleaved, "kron_order"), (HMH + first, "one_R"), (HMH, "no_R")):
        fb = orbit.check_two_station_S(wrong)
        assert not fb.correct and fb.message == HINTS["21.2"][key]
    assert not orbit.check_two_station_S(...).answered
    assert not orbit.check_two_station_S((HMH + Rk)[:3, :3]).correct


def test_the_notebook_states_the_exercises_numbers():
    text = " ".join(SOURCE.read_text(encoding="utf-8").split())
    assert f"`{tuple(orbit.STEP_STATIONS)}`" in text
    assert f"$t = {orbit.S_TIME:.0f}$ s stations 0 and 1" in text
    d = np.diag(orbit.S_PRIOR)
    assert d[0] == d[2] == 2.5e-3 and d[1] == d[3] == 2.5e-7 and np.count_nonzero(orbit.S_PRIOR) == 4
    assert r"\mathrm{diag}(2.5\cdot10^{-3}, 2.5\cdot10^{-7}, 2.5\cdot10^{-3}, 2.5\cdot10^{-7})" in text
    assert orbit.STEP_ALPHA == 0.05 and r"$\alpha = 0.05$" in text
