"""The install: a plain ``pip install .`` into a fresh virtual environment gives a working command line;
``environment.txt`` and ``environment-instructors.txt`` pin every distribution they install; on a Python
outside 3.11-3.13, README's first command stops with one line saying which Pythons are needed.

For the plain install, the package's files (``kfcal_helpers/``, ``lab_settings/``, ``pyproject.toml``, ``README.md``) are copied to a
temporary folder, so the build leaves nothing in the working copy; the venv is made without pip
(``venv --without-pip``) and filled by this interpreter's pip through ``pip --python``, from the
warm pip cache, without byte-compiling the installed packages (``--no-compile``: the third of the
install's time; the command then compiles only the modules it imports, as Python does).  The command runs with its progress bar on (no ``KFCAL_QUIET``/``CI``), so every
module the default path imports (tqdm included) must come from the declared dependencies.  The install
is in the slow tier (``pytest -m slow``; ``.ci/run`` runs it after ``pytest``), and so is the real ``pip install
-r environment.txt`` of a Python 3.10 found on the machine.  The pins are checked against the running
environment (the student's, or the instructors' when nbgrader is installed): ``.ci/run`` runs this file in
both and on the newest Python.
"""

import os
import shutil
import subprocess
import sys
import sysconfig
import tomllib
from importlib import metadata
from pathlib import Path

import pytest
from packaging.markers import Marker
from packaging.requirements import Requirement
from packaging.tags import compatible_tags, cpython_tags
from packaging.utils import canonicalize_name, parse_wheel_filename

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


# ------------------------------------------------------------------------------------------------
# the pins: every distribution the environment files install is pinned, at the version installed


def requirement_lines(path):
    """The requirement lines of a pip requirements file, ``-r`` files read in place (comments, blanks dropped)."""
    lines = []
    for raw in path.read_text().splitlines():
        line = raw.split(" #")[0].strip()
        if not line or line.startswith("#"):
            continue
        if line.startswith("-r "):
            lines += requirement_lines(path.parent / line[3:].strip())
        else:
            lines.append(line)
    return lines


def pins(path):
    """``{canonical name: (version, marker or None)}`` of the ``name==version`` lines of a requirements file."""
    found = {}
    for line in requirement_lines(path):
        if line.startswith(("-e ", "file:")):
            continue
        req = Requirement(line)
        (spec,) = req.specifier
        assert spec.operator == "==", f"{path.name}: {line!r} is not an exact pin"
        name = canonicalize_name(req.name)
        assert name not in found, f"{path.name}: {req.name} pinned twice"
        found[name] = (spec.version, req.marker)
    return found


def test_environment_files_pin_exact_versions_once():
    students = pins(ROOT / "environment.txt")
    instructors = pins(ROOT / "environment-instructors.txt")
    assert set(students) < set(instructors)
    # README: "about 150 packages" (Linux; a few more or fewer on macOS and Windows)
    assert 145 <= sum(marker is None for _, marker in students.values()) <= 155
    assert {n: v for n, v in instructors.items() if n in students} == students
    # the project's deliberate choices stay: matplotlib 3.10 (the demos' redraw), nbgrader 0.9.6
    assert students["matplotlib"][0] == "3.10.9" and instructors["nbgrader"][0] == "0.9.6"
    # what only some systems install is pinned too, with its marker
    for name in ("appnope", "colorama", "overrides", "pexpect", "ptyprocess", "pywinpty"):
        assert students[name][1] is not None, name
    windows = {"sys_platform": "win32", "os_name": "nt", "platform_system": "Windows"}
    mac = {"sys_platform": "darwin", "os_name": "posix", "platform_system": "Darwin"}
    assert students["pywinpty"][1].evaluate(windows) and not students["pywinpty"][1].evaluate(mac)
    assert students["appnope"][1].evaluate(mac) and not students["appnope"][1].evaluate(windows)
    assert not students["pexpect"][1].evaluate(windows) and students["pexpect"][1].evaluate(mac)


def test_every_installed_distribution_is_pinned():
    """Every distribution in the running environment is pinned, at its installed version (pip excepted).

    The running environment is the student's (``environment.txt``) or, with nbgrader installed, the
    instructors'; a venv's own setuptools counts only where the file pins it.
    """
    try:
        metadata.version("nbgrader")
        path = ROOT / "environment-instructors.txt"
    except metadata.PackageNotFoundError:
        path = ROOT / "environment.txt"
    wanted = {n: v for n, (v, marker) in pins(path).items() if marker is None or marker.evaluate()}
    # what pip installed into the environment's site-packages: not what a package vendors and puts on sys.path
    # when imported (setuptools adds its _vendor folder, with jaraco.*, wheel, tomli, ..., to sys.path)
    site = sorted({sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]})
    installed = {canonicalize_name(d.metadata["Name"]): d.version for d in metadata.distributions(path=site)}
    installed.pop("kfcal-helpers", None)  # the project itself (-e .)
    installed.pop("pip", None)  # the installer
    if "setuptools" not in wanted:
        installed.pop("setuptools", None)  # Python 3.11's venv brings one
    unpinned = sorted(f"{n}=={v}" for n, v in installed.items() if n not in wanted)
    assert not unpinned, f"installed but not pinned in {path.name} (pin them, or uninstall what was installed by hand): {unpinned}"
    other = sorted(f"{n} {installed[n]} (pinned {v})" for n, v in wanted.items() if n in installed and installed[n] != v)
    assert not other, f"installed at another version than {path.name} pins: {other}"
    missing = sorted(n for n in wanted if n not in installed)
    assert not missing, f"pinned in {path.name} but not installed: {missing}"


# ------------------------------------------------------------------------------------------------
# another Python: README's first command says, in one line, which Pythons the course needs


def python_guard():
    """The first requirement line of environment.txt: a wheel name no pip installs, for other Pythons only."""
    first = requirement_lines(ROOT / "environment.txt")[0]
    url, marker = first.split(" ; ")
    assert url.startswith("file:") and url.endswith(".whl")
    return url[len("file:"):], Marker(marker)


def test_the_first_requirement_stops_other_pythons_only():
    wheel, marker = python_guard()
    assert "Python_3.11_3.12_or_3.13_is_needed" in wheel
    for version, other in (("3.9", True), ("3.10", True), ("3.11", False), ("3.12", False), ("3.13", False),
                           ("3.14", True), ("3.15", True)):
        assert marker.evaluate({"python_version": version, "python_full_version": version + ".0"}) == other, version
        # pip refuses a wheel whose tags the Python does not accept, before it looks for any file
        major, minor = map(int, version.split("."))
        accepted = set(cpython_tags((major, minor))) | set(compatible_tags((major, minor), f"cp{major}{minor}"))
        assert bool(parse_wheel_filename(wheel)[3] & accepted) == (not other), version


def python_310():
    """A Python 3.10 on this machine (PATH or pyenv), or None."""
    found = shutil.which("python3.10")
    pyenv = Path(os.environ.get("PYENV_ROOT", Path.home() / ".pyenv")) / "versions"
    candidates = [found] if found else []
    candidates += [str(p) for p in sorted(pyenv.glob("3.10*/bin/python3.10"))]
    for cand in candidates:
        probe = subprocess.run([cand, "-c", "import sys, ensurepip; print(sys.version_info[:2])"],
                               capture_output=True, text=True)
        if probe.returncode == 0 and probe.stdout.strip() == "(3, 10)":
            return cand
    return None


@pytest.mark.slow
def test_readme_install_on_python_310_says_so_in_one_line(tmp_path):
    python = python_310()
    if python is None:
        pytest.skip("no Python 3.10 on this machine (PATH or pyenv)")
    venv = tmp_path / "venv"
    subprocess.run([python, "-m", "venv", str(venv)], check=True)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["PIP_DISABLE_PIP_VERSION_CHECK"] = "1"
    # README's command, from the clone's folder, with the venv's own pip (the one Python 3.10 comes with)
    pip = subprocess.run([str(venv / "bin" / "pip"), "install", "-r", "environment.txt"], cwd=ROOT,
                         capture_output=True, text=True, env=env, timeout=300)
    assert pip.returncode == 1
    assert pip.stderr.splitlines() == [f"ERROR: {python_guard()[0]} is not a supported wheel on this platform."]
    # it stopped before anything was fetched, built or installed
    assert "Collecting" not in pip.stdout and "Obtaining" not in pip.stdout
    freeze = subprocess.run([str(venv / "bin" / "pip"), "freeze"], capture_output=True, text=True, env=env)
    assert freeze.stdout == ""
