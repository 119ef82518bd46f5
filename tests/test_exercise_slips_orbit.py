"""The slips of the orbit exercises (19.x to 23.x), one row per exercise and slip, in the labels of the other
problems' slip rows: each check, given the right answer with that slip (a units factor, degrees for radians,
reversed, transposed, one entry off), answers with a hint naming the slip, never "correct"; a units slip names
the orbit exercises' units (km, km/s), not the harness's SI units.

CONTRIBUTING's table "slips its tests cover" lists, for each orbit exercise, exactly the slips of its rows here.
The right answers come from tests/test_exercises_orbit.py and tests/test_exercises_orbit_23.py, which compute them by
another route than the checks; the NIS bands of 23.x have no units (no units slip).
"""

import re
from pathlib import Path

import numpy as np
import pytest

import test_exercises_orbit as orb
import test_exercises_orbit_23 as orb23
from kfcal_helpers.orbit import exercises as ox
from kfcal_helpers.orbit.exercises import _shared

UNITS, DEGREES, REVERSED, TRANSPOSED, ENTRY = "units", "degrees", "reversed", "transposed", "entry named"
WRAP = "wrap [0, 2π)"

CHECK = {"19.1": ox.check_station_measurement, "19.2": ox.check_visible_stations, "19.3": ox.check_perturbed_period,
         "20.1": ox.check_gravity_jacobian, "20.2": ox.check_range_rate_row, "20.3": ox.check_expm_F,
         "22.1": ox.check_ukf_phi_mean, "22.2": ox.check_stacked_update,
         "23.1": ox.check_log_nis_band, "23.2": ox.check_step_nis_band}


def _right():
    n = (orb.MU / orb.R0**3) ** 0.5
    x0 = np.array([orb.R0, 0.0, 0.0, orb.R0 * n]) + np.array(_shared.PERIOD_DX0)
    energy = (x0[1] ** 2 + x0[3] ** 2) / 2 - orb.MU / orb.R0
    a = -orb.MU / (2 * energy)
    return {"19.1": orb.measurement_c(orb.X1, orb.T1, orb.S1), "19.2": orb.visible_c(orb.X2, orb.T2).astype(float),
            "19.3": np.array(2 * np.pi * (a**3 / orb.MU) ** 0.5),
            "20.1": orb.complex_step_jacobian(orb.f_complex, orb.XA),
            "20.2": orb.complex_step_jacobian(orb.rhodot_complex, orb.XR)[0],
            "20.3": orb.taylor_expm(_shared.EXPM_DT * orb.A_nominal()),
            "22.1": np.array(orb.RIGHT_22_1), "22.2": orb.information_correction(),
            "23.1": orb23.RIGHT_23_1, "23.2": orb23.RIGHT_23_2}


RIGHT = _right()
KM = "(the orbit exercises work in km, km/s, s and rad"


def _rows():
    r = RIGHT
    deg = r["19.1"].copy()
    deg[2] = np.degrees(deg[2])
    off = r["19.1"] * [1.0, 1.0, 1.03]
    row_off = r["20.2"] * [1.0, 1.0, 1.0, 1.03]
    rows = []
    for ex in ("19.1", "19.3", "20.1", "20.2", "20.3", "22.1", "22.2"):
        rows += [(ex, UNITS, r[ex] * 1000, "your answer is 1000 times the right one: check the units " + KM),
                 (ex, UNITS, r[ex] / 100, "your answer is 0.01 times the right one: check the units " + KM)]
    rows += [("19.1", DEGREES, deg, "your answer is in degrees"),
             ("19.1", REVERSED, r["19.1"][::-1], "your entries are in reverse order"),
             ("19.1", ENTRY, off, "only the angle phi is off, the rest is right"),
             ("20.1", TRANSPOSED, r["20.1"].T, "your matrix is transposed"),
             ("20.2", REVERSED, r["20.2"][::-1], "your entries are in reverse order"),
             ("20.2", ENTRY, row_off, "only d rhodot/dYdot is off, the rest is right"),
             ("20.3", TRANSPOSED, r["20.3"].T, "your matrix is transposed"),
             ("22.1", DEGREES, np.degrees(r["22.1"]), "your answer is in degrees"),
             ("22.1", WRAP, r["22.1"] + 2 * np.pi, orb.hint("22.1", "wrap_2pi")),
             ("22.2", REVERSED, r["22.2"][::-1], "your entries are in reverse order"),
             ("22.2", ENTRY, r["22.2"] * [1.0, 1.0, 1.03, 1.0], "only Y is off, the rest is right")]
    for ex in ("23.1", "23.2"):
        rows += [(ex, REVERSED, r[ex][::-1], "your entries are in reverse order"),
                 (ex, ENTRY, r[ex] * [1.0, 1.03], "only the upper bound is off, the rest is right")]
    return rows


ROWS = _rows()


@pytest.mark.parametrize("row", ROWS, ids=[f"{r[0]}-{r[1]}" for r in ROWS])
def test_a_slipped_answer_gets_the_slips_hint(row):
    exercise, _, answer, words = row
    assert CHECK[exercise](RIGHT[exercise]).correct
    fb = CHECK[exercise](answer)
    assert not fb.correct and fb.answered and words in fb.message, (exercise, str(fb))
    assert "SI units" not in fb.message


def test_station_ids_get_no_units_or_order_slip():
    for wrong in (RIGHT["19.2"] * 10, RIGHT["19.2"] / 10):
        fb = ox.check_visible_stations(wrong)
        assert not fb.correct and "units" not in fb.message, str(fb)


def test_the_contributing_table_lists_exactly_the_orbit_slips_tested():
    text = (Path(__file__).parents[1] / "CONTRIBUTING.md").read_text(encoding="utf-8")
    table = {ex: {s.strip() for s in slips.split(";")} - {"—"}
             for ex, slips in re.findall(r"^\| (\d\d\.\d) \| ([^|]*) \|$", text, flags=re.M) if ex[:2] in ("19", "20", "21", "22", "23")}
    tested = {ex: set() for ex in ox.EXERCISES}
    for row in ROWS:
        tested[row[0]].add(row[1])
    assert table == tested
