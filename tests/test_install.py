"""A plain ``pip install .`` into a fresh virtual environment gives a working command line.

The package's files (``kfcal_helpers/``, ``lab_settings/``, ``pyproject.toml``, ``README.md``) are copied to a
temporary folder, so the build leaves nothing in the working copy; the venv is made without pip
(``venv --without-pip``) and filled by this interpreter's pip through ``pip --python``, from the
warm pip cache, without byte-compiling the installed packages (``--no-compile``: the third of the
install's time; the command then compiles only the modules it imports, as Python does).  The command runs with its progress bar on (no ``KFCAL_QUIET``/``CI``), so every
module the default path imports (tqdm included) must come from the declared dependencies.  The install
is in the slow tier (``pytest -m slow``; ``.ci/run`` runs it after ``pytest``).
"""

import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_pyproject_declares_what_the_package_imports():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    deps = {d.split("[")[0].split("=")[0].split(">")[0].split("<")[0].strip().lower() for d in project["dependencies"]}
    assert {"filterpy", "numpy", "scipy", "matplotlib", "tqdm"} <= deps
    extras = {k: {d.lower() for d in v} for k, v in project["optional-dependencies"].items()}
    assert {"ipywidgets", "pillow"} <= extras["widgets"]


@pytest.mark.slow
def test_plain_pip_install_runs_calibrate(tmp_path):
    src = tmp_path / "src"
    shutil.copytree(ROOT / "kfcal_helpers", src / "kfcal_helpers",
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    # the build's own files too: the JupyterLab settings override and its editable-install command
    shutil.copytree(ROOT / "lab_settings", src / "lab_settings", ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, src / name)
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    python = venv / "bin" / "python"
    env = {k: v for k, v in os.environ.items() if k not in ("KFCAL_QUIET", "CI", "PYTHONPATH", "VIRTUAL_ENV")}
    pip = subprocess.run([sys.executable, "-m", "pip", "--python", str(python), "install", "-q",
                          "--disable-pip-version-check", "--no-compile", str(src)],
                         capture_output=True, text=True, env=env, timeout=600)
    assert pip.returncode == 0, pip.stderr[-2000:]
    run = subprocess.run([str(python), "-m", "kfcal_helpers", "calibrate", "--runs", "10"], cwd=tmp_path,
                         capture_output=True, text=True, env=env, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "10 realizations" in run.stdout and "nees" in run.stdout
    assert "Traceback" not in run.stderr
    # the installed copy is the one that ran, not the working copy
    where = subprocess.run([str(python), "-c", "import kfcal_helpers; print(kfcal_helpers.__file__)"], cwd=tmp_path,
                           capture_output=True, text=True, env=env)
    assert str(venv) in where.stdout
    # the install puts JupyterLab's settings override (no news question, no update check) where JupyterLab reads it
    override = venv / "share" / "jupyter" / "lab" / "settings" / "overrides.d" / "kfcal-helpers.json"
    assert override.read_text() == (ROOT / "lab_settings" / "overrides.d" / "kfcal-helpers.json").read_text()
