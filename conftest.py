"""Test-session settings shared by the unit tests and the notebooks run under nbval."""

import os

# Notebooks run under nbval inherit this environment: no progress bars.
os.environ["KFCAL_QUIET"] = "1"
