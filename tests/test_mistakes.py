"""The mistakes table of notebook 14, joined over the problems: each mistake is caught by the checks
the notebook names and the correct filters pass them all.  Each problem's mistakes (the one-line
variants, the cases) are tested in tests/test_<problem>_mistakes.py."""

import pytest

from kfcal_helpers.mistakes import all_mistakes, format_mistake_table, mistake_table, table_checks

from mistake_expectations import CALIBRATION_CAUGHT_BY, CHECK_NAMES, COOP_ALL, COOP_CAUGHT_BY, ORBIT_CAUGHT_BY

CALIBRATION_MISTAKES = tuple(CALIBRATION_CAUGHT_BY)
COOP_MISTAKES = tuple(COOP_CAUGHT_BY)
ORBIT_MISTAKES = tuple(ORBIT_CAUGHT_BY)
MISTAKES = (*CALIBRATION_MISTAKES, *COOP_MISTAKES, *ORBIT_MISTAKES)
#: what notebook 14 says, check by check (the orbit rows: tests/test_orbit_mistakes.py)
CAUGHT_BY = {**CALIBRATION_CAUGHT_BY, **COOP_CAUGHT_BY, **ORBIT_CAUGHT_BY}


@pytest.fixture(scope="module")
def table(mistakes_table):
    """mistake_table() at its defaults (tests/conftest.py: computed once, shared with the problems' row tests)."""
    return mistakes_table


def test_table_rows_and_columns(table):
    assert tuple(table) == MISTAKES == all_mistakes()
    assert table_checks(table) == CHECK_NAMES
    for mistake, row in table.items():
        expected = set(CHECK_NAMES) if mistake in CALIBRATION_MISTAKES else COOP_ALL
        assert set(row.checks) == expected
    text = format_mistake_table(table)
    assert len(text.splitlines()) == 2 + len(MISTAKES) and "FAIL" in text and "pass" in text


@pytest.mark.parametrize("mistake", MISTAKES)
def test_caught_by_the_checks_the_notebook_names(table, mistake):
    assert set(table[mistake].failed) == CAUGHT_BY[mistake]
    assert table[mistake].passed == (not CAUGHT_BY[mistake])


def test_large_mistakes_fail_by_orders_of_magnitude(table):
    for mistake in ("no_propagation", "gps_interval_0_02", "ekf_no_wrap", "lkf_no_nominal"):
        assert table[mistake].checks["nees"].worst > 100


@pytest.mark.parametrize("bad", ["wrong_sign", "", None])
def test_unknown_mistake_is_a_value_error(bad):
    with pytest.raises(ValueError, match="mistakes must be one of"):
        mistake_table([bad])
