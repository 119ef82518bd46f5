"""Test-session settings shared by the unit tests and the notebooks run under nbval, and how
pytest-xdist groups the test files (files sharing a session fixture run on one worker)."""

import os

# Notebooks run under nbval inherit this environment: no progress bars.
os.environ["KFCAL_QUIET"] = "1"


#: test files that share a session fixture of tests/conftest.py, by the work unit they form: pytest-xdist
#: (``--dist loadfile``) gives each unit to one worker, so the fixture is computed once per run
SHARED_SCOPES = {
    "tests/test_mistakes.py": "mistakes table",
    "tests/test_calibration_mistakes.py": "mistakes table",
    "tests/test_coop_mistakes.py": "mistakes table",
}


def pytest_xdist_make_scheduler(config, log):
    """``--dist loadfile`` with the files of :data:`SHARED_SCOPES` joined into one work unit each."""
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling

    class SharedFixtureScheduling(LoadFileScheduling):
        def _split_scope(self, nodeid):
            file = super()._split_scope(nodeid)
            return SHARED_SCOPES.get(file, file)

    return SharedFixtureScheduling(config, log)
