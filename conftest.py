"""Test-session settings shared by the unit tests and the notebooks run under nbval, and how
pytest-xdist groups the test files (files sharing a session fixture run on one worker)."""

import os
import signal

import pytest

from kfcal_helpers.kernels import over_ipc

# Notebooks run under nbval inherit this environment: no progress bars.
os.environ["KFCAL_QUIET"] = "1"


def _notebook_kernels_over_ipc():
    """nbval's notebook kernels over IPC (:func:`kfcal_helpers.kernels.over_ipc`: no TCP port race)."""
    try:
        import nbval.kernel
    except ImportError:  # nbval not installed: no notebooks to run
        return
    nbval.kernel.KernelManager = over_ipc(nbval.kernel.KernelManager)  # what start_new_kernel instantiates


_notebook_kernels_over_ipc()


def _answer_ctrl_c():
    """SIGINT back to Python's default (KeyboardInterrupt) when this process started with it ignored.

    A job put in the background by a script (``bash .ci/run &``: a non-interactive shell) starts with
    SIGINT ignored, and every process it starts inherits that: the command line then rightly leaves
    SIGINT alone, and the Ctrl-C tests of ``tests/test_fuzz_cli.py`` fail with exit status 0.  Taken
    back here, in pytest and in each worker, the processes the tests start get SIGINT's default, as
    from a terminal.
    """
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


_answer_ctrl_c()


@pytest.fixture(scope="session")
def kernel_manager_class():
    """The kernel manager class for tests that run cells through nbclient: its async one over IPC,
    like nbval's kernels (:func:`kfcal_helpers.kernels.over_ipc`)."""
    from jupyter_client import AsyncKernelManager

    return over_ipc(AsyncKernelManager)


#: outputs of the notebooks nbval ran in this process, by notebook path: ``{"course_log": the
#: KFCAL_COURSE_LOG its kernel had, "quiet": its KFCAL_QUIET, "outputs": [each code cell's outputs],
#: "passed": whether every cell passed}``; see the ``nbval_runs`` fixture
NBVAL_RUNS: dict = {}


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """Keep what each nbval cell printed (:data:`NBVAL_RUNS`), in the order of its code cells."""
    outcome = yield
    if call.when != "call" or not (hasattr(item, "cell_num") and hasattr(item, "test_outputs")):
        return
    report = outcome.get_result()
    run = NBVAL_RUNS.setdefault(str(item.path), {"course_log": os.environ.get("KFCAL_COURSE_LOG"),
                                                 "quiet": os.environ.get("KFCAL_QUIET"),
                                                 "outputs": [], "passed": True})
    if item.cell_num != len(run["outputs"]):  # a cell left out (deselected, or run twice): not one whole run
        run["passed"] = False
    run["outputs"].append(list(item.test_outputs or []))
    run["passed"] = run["passed"] and report.passed and item.test_outputs is not None


@pytest.fixture(scope="session")
def nbval_runs():
    """The notebooks nbval has run so far in this process (:data:`NBVAL_RUNS`; read-only), so that a
    test needing the same notebook run in the same environment can check its outputs instead of
    running it once more (``tests/test_notebook13_modes.py``)."""
    return NBVAL_RUNS


#: test files that share a session fixture of tests/conftest.py (or a run above), by the work unit they
#: form: pytest-xdist (``--dist loadfile``) gives each unit to one worker, so the fixture is computed once
#: per run
SHARED_SCOPES = {
    "tests/test_mistakes.py": "mistakes table",
    "tests/test_calibration_mistakes.py": "mistakes table",
    "tests/test_coop_mistakes.py": "mistakes table",
    "tests/test_orbit_mistakes.py": "mistakes table",
    # nbval's run of notebook 13 is one of the modes tests/test_notebook13_modes.py checks (SLOW_FIRST:
    # the notebook first)
    "notebooks/13_coop_log_comparison.ipynb": "notebook 13",
    "tests/test_notebook13_modes.py": "notebook 13",
}


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    """One line at the end of a run without the slow tier (``-m 'not slow'``, the default of ``pyproject.toml``)."""
    if config.getoption("markexpr") == "not slow":
        terminalreporter.write_line("the slow tier (real child processes at full size: signals, streams, peak memory, "
                                    "a pip install) was left out: `pytest -m slow` runs it; .ci/run runs both")


#: the files that take one worker longest (a browser, a site build, notebook runs, child processes), handed
#: out first, longest first (worker seconds of each, measured on the 2-core machine on 2026-12-03), so that no
#: worker is left alone with one of them at the end (xdist's own order, by the number of tests in a file, would
#: hand them out last); the two files that drive Chromium (the demos, the site) are not the first two, so that
#: they do not start together
SLOW_FIRST = (
    "tests/test_browser_demos.py",  # about 80 s: JupyterLab and Chromium
    "tests/test_fuzz_cli.py",  # slow tier about 65 s: real processes (signals, streams); the rest about 13 s
    "notebooks/13_coop_log_comparison.ipynb",  # with the next: one unit (SHARED_SCOPES), about 60 s
    "tests/test_notebook13_modes.py",
    "tests/test_notebook23_modes.py",  # about 40 s: notebook 23 on five logs
    "tests/test_site.py",  # about 45 s: the site build and Chromium
    "tests/test_calibration_memory.py",  # slow tier about 35 s: child processes at the largest runs
    "tests/test_install.py",  # slow tier about 20 s: pip install into a fresh venv
    "tests/test_coop_memory.py",  # slow tier about 15 s
    "notebooks/06b_monte_carlo_bands_and_power.ipynb",  # about 13 s
    "tests/test_figures.py",
)


def pytest_collection_modifyitems(config, items):
    """The files of :data:`SLOW_FIRST` first, in that order; every other item keeps its place (a stable
    sort: the cells of a notebook stay in order)."""
    rank = {name: i for i, name in enumerate(SLOW_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::")[0], len(rank)))


def pytest_xdist_make_scheduler(config, log):
    """``--dist loadfile`` with the files of :data:`SHARED_SCOPES` joined into one work unit each, handed
    out in collection order (:data:`SLOW_FIRST` first)."""
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling

    config.option.loadscopereorder = False

    class SharedFixtureScheduling(LoadFileScheduling):
        def _split_scope(self, nodeid):
            file = super()._split_scope(nodeid)
            return SHARED_SCOPES.get(file, file)

    return SharedFixtureScheduling(config, log)
