"""Headless Chromium for the browser tests (the live demos in JupyterLab, the course site), offline.

``CHROMIUM`` and ``CHROMEDRIVER`` are the binaries found (``KFCAL_CHROMIUM`` / ``KFCAL_CHROMEDRIVER``
select others), or None; :func:`start` opens a driver with the flags that keep Chromium off the network
(this machine has none: without them it retries connections at every start)."""

from __future__ import annotations

import os
import shutil


def _binary(env: str, *names: str) -> str | None:
    if os.environ.get(env):
        return os.environ[env] if os.access(os.environ[env], os.X_OK) else None
    for name in names:
        found = shutil.which(name)
        if found:
            return found
    return None


CHROMIUM = _binary("KFCAL_CHROMIUM", "chromium", "chromium-browser")
CHROMEDRIVER = _binary("KFCAL_CHROMEDRIVER", "chromedriver")
MISSING = ("no Chromium/chromedriver found "
           f"(chromium: {CHROMIUM or 'missing'}, chromedriver: {CHROMEDRIVER or 'missing'}; "
           "Debian: apt-get install chromium chromium-driver)")


def start(window: tuple[int, int], profile_dir, logging_prefs: dict | None = None):
    """A headless Chromium driver with a ``window`` (width, height) in px and a fresh profile in
    ``profile_dir``; ``logging_prefs`` becomes the ``goog:loggingPrefs`` capability."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for arg in ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                "--disable-background-networking", "--disable-component-update", "--disable-sync",
                "--disable-dev-shm-usage", f"--window-size={window[0]},{window[1]}",
                f"--user-data-dir={profile_dir}"):
        options.add_argument(arg)
    if logging_prefs:
        options.set_capability("goog:loggingPrefs", logging_prefs)
    return webdriver.Chrome(service=Service(executable_path=CHROMEDRIVER), options=options)
