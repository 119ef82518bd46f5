"""Expensive results that several test files use, computed once per pytest-xdist worker.

``pytest`` runs on two workers with ``--dist loadfile``: a session fixture is computed once in each
worker that runs a test using it.  The files sharing a fixture here are therefore scheduled on the
same worker (``SHARED_SCOPES`` in the root ``conftest.py``), so each is computed once per run.
"""

import pytest

from kfcal_helpers.mistakes import mistake_table


@pytest.fixture(scope="session")
def mistakes_table():
    """Notebook 14's table, every problem's mistake rows at their defaults (``mistake_table()``: the
    calibration rows 1000 realizations each, the coop rows each problem's own count and seed).
    Shared by tests/test_mistakes.py (the joined table) and each problem's row tests
    (tests/test_calibration_mistakes.py, tests/test_coop_mistakes.py); treat it as read-only."""
    return mistake_table()
