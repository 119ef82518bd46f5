"""The course folder of ``python -m kfcal_helpers assignments --course DIR``, through the real command lines.

Where a course may go (never inside the repository, never over other files; made again, it keeps the hand-ins,
autograded notebooks, feedback and gradebook), that it is made with the environment's Python when the
environment is not activated (nbgrader starts ``alembic`` by name), that the real ``nbgrader`` command reads
the ``nbgrader_config.py`` it writes, which lessons are graded, and how a graded class gets its notebooks
without the solutions (README, *For lecturers*).  The tests that make a course need nbgrader
(environment-instructors.txt) and skip without it; ``.ci/run`` runs this file after installing it.
"""

import contextlib
import io
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import nbformat
import pytest

from kfcal_helpers.cli import main

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = ROOT / "notebooks"
LESSON = "01_truth_model"
SCRIPTS = Path(sys.executable).parent   # this environment's scripts folder: nbgrader, alembic, jupyter

try:
    import nbgrader  # noqa: F401
    HAVE_NBGRADER = True
except ImportError:
    HAVE_NBGRADER = False
needs_nbgrader = pytest.mark.skipif(not HAVE_NBGRADER, reason="nbgrader is not installed: "
                                    "pip install -r environment-instructors.txt")


def environment(path_with_scripts=True):
    """This process's environment for a child: this worktree's package first on PYTHONPATH, and PATH with or
    without this environment's scripts folder (as in an activated environment, or a bare ``.venv/bin/python``)."""
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV",)}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])
    path = [p for p in os.environ.get("PATH", "").split(os.pathsep) if p and Path(p).resolve() != SCRIPTS.resolve()]
    env["PATH"] = os.pathsep.join([str(SCRIPTS)] * path_with_scripts + path)
    env["KFCAL_QUIET"] = "1"
    return env


def assignments(*args, cwd=ROOT, path_with_scripts=True):
    """``python -m kfcal_helpers assignments ARGS`` in a child process (the real entry point)."""
    return subprocess.run([sys.executable, "-m", "kfcal_helpers", "assignments", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, env=environment(path_with_scripts), timeout=600)


def cli(*args):
    """``python -m kfcal_helpers assignments ARGS`` through ``kfcal_helpers.cli.main`` in this process (what the
    entry point runs): ``CompletedProcess``-like ``(returncode, stdout, stderr)``."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["assignments", *map(str, args)])
    return subprocess.CompletedProcess(args, code, out.getvalue(), err.getvalue())


def nbgrader_cli(course, *args):
    """The real ``nbgrader`` command line, run in the course folder."""
    return subprocess.run([str(SCRIPTS / "nbgrader"), *args], cwd=course, capture_output=True, text=True,
                          env=environment(), timeout=600)


def one_error_line(proc):
    lines = proc.stderr.splitlines()
    assert proc.returncode == 2, (proc.returncode, proc.stdout[-500:], proc.stderr[-2000:])
    assert len(lines) == 1 and lines[0].startswith("python -m kfcal_helpers assignments: error: "), proc.stderr
    return lines[0]


def snapshot(folder):
    """``{relative path: bytes}`` of every file under ``folder``."""
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture
def one_lesson(tmp_path):
    """A notebooks folder holding lesson 01's source only (a course of one assignment)."""
    folder = tmp_path / "notebooks"
    (folder / "source").mkdir(parents=True)
    shutil.copy(NOTEBOOKS / "source" / f"{LESSON}.md", folder / "source")
    return folder


# ------------------------------------------------------------------------------------------------
# where a course may go (no nbgrader needed: refused before it is asked for)
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("inside", ["notebooks", "notebooks/kf-course", ".", "build/kf-course-test"])
def test_course_inside_the_repository_is_refused(inside, monkeypatch):
    monkeypatch.chdir(ROOT)
    before = snapshot(NOTEBOOKS / "source"), sorted(p.name for p in NOTEBOOKS.iterdir())
    target = ROOT / inside
    existed = target.exists()
    try:
        for given in (inside, target):   # relative to the repository, and absolute
            line = one_error_line(cli("--course", given))
            assert "--course" in line and "outside the repository" in line and str(ROOT) in line
    finally:
        if not existed and target.exists():   # the old command wrote a course there: take it away again
            shutil.rmtree(target)
    assert (snapshot(NOTEBOOKS / "source"), sorted(p.name for p in NOTEBOOKS.iterdir())) == before
    assert not (NOTEBOOKS / "nbgrader_config.py").exists() and not (NOTEBOOKS / "release").exists()


def test_course_in_the_notebooks_folder_given_is_refused(one_lesson):
    line = one_error_line(assignments("--notebooks", one_lesson, "--course", one_lesson / "course"))   # a real process
    assert "outside the repository" in line and str(one_lesson) in line
    assert not (one_lesson / "course").exists()


def test_course_over_other_files_is_refused(tmp_path, one_lesson):
    folder = tmp_path / "thesis"
    (folder / "chapter1").mkdir(parents=True)
    (folder / "chapter1" / "notes.txt").write_text("mine")
    (folder / "nbgrader_config.py").write_text("c = get_config()\n")   # someone else's nbgrader course
    before = snapshot(folder)
    line = one_error_line(cli("--notebooks", one_lesson, "--course", folder))
    assert "--course" in line and "not a course made by this command" in line
    assert snapshot(folder) == before and not (folder / "release").exists()


def test_course_folder_that_cannot_be_listed_is_one_line(tmp_path, one_lesson, monkeypatch):
    folder = tmp_path / "locked"
    folder.mkdir()
    iterdir = Path.iterdir

    def refuse(self):   # what a folder without read permission does (this test may run as root)
        if self == folder:
            raise PermissionError(13, "Permission denied", str(self))
        return iterdir(self)

    monkeypatch.setattr(Path, "iterdir", refuse)
    line = one_error_line(cli("--notebooks", one_lesson, "--course", folder))
    assert "--course" in line and "cannot be read (Permission denied)" in line


# ------------------------------------------------------------------------------------------------
# which lessons are graded (no nbgrader needed: write_course does not import it)
# ------------------------------------------------------------------------------------------------
def test_the_demos_self_checks_are_not_graded(tmp_path):
    """17.1 and 18.1 accept the expression their text gives and 17.2 the band the lesson prints: the demos'
    exercises stay self-checks in the lessons and are not assignments of the graded course."""
    from kfcal_helpers.assignments import answer_cells, read_source, write_course

    demos = [NOTEBOOKS / "source" / "17_calibration_live_demo.md", NOTEBOOKS / "source" / "18_coop_live_demo.md"]
    assert all(answer_cells(read_source(path)) for path in demos)   # they still have exercises (self-checks)
    names = write_course(tmp_path / "course", [NOTEBOOKS / "source" / f"{LESSON}.md", *demos])
    assert names == [LESSON]
    assert sorted(p.name for p in (tmp_path / "course" / "source").iterdir()) == [LESSON]
    sources = sorted((NOTEBOOKS / "source").glob("*.md"))
    every = write_course(tmp_path / "all", sources)
    # every lesson with exercises (06b has none) but the two demos
    lessons = [p.stem for p in sources if answer_cells(read_source(p)) and not p.stem.startswith(("17_", "18_"))]
    assert every == lessons and len(every) >= 17 and "21_orbit_lkf" in every


def test_a_misspelt_graded_flag_is_an_error_naming_the_file(tmp_path, one_lesson):
    from kfcal_helpers.assignments import write_course

    path = one_lesson / "source" / f"{LESSON}.md"
    for flag in ("kfcal:\n  grade: false\n", "kfcal:\n  graded: no way\n"):
        text = (NOTEBOOKS / "source" / f"{LESSON}.md").read_text(encoding="utf-8")
        path.write_text(text.replace("---\n", "---\n" + flag, 1), encoding="utf-8")
        with pytest.raises(ValueError, match=f"{LESSON}.md: the front matter's kfcal must be"):
            write_course(tmp_path / "course", [path])
    assert not (tmp_path / "course").exists()


# ------------------------------------------------------------------------------------------------
# the course made for real (nbgrader)
# ------------------------------------------------------------------------------------------------
@needs_nbgrader
def test_course_without_an_activated_environment(tmp_path, one_lesson):
    """``.venv/bin/python -m kfcal_helpers assignments --course`` with the environment's scripts folder not on
    PATH: nbgrader's ``alembic`` (started by name to make the gradebook) is found all the same."""
    if shutil.which("alembic", path=environment(path_with_scripts=False)["PATH"]):
        pytest.skip("another alembic is on PATH: the environment's own scripts folder is not needed here")
    course = tmp_path / "course"
    proc = assignments("--notebooks", one_lesson, "--course", course, path_with_scripts=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr and f"released {LESSON}" in proc.stdout
    assert (course / "gradebook.db").is_file() and (course / "release" / LESSON / f"{LESSON}.ipynb").is_file()


@needs_nbgrader
def test_course_without_alembic_says_what_to_do(tmp_path, one_lesson):
    """When no ``alembic`` can be found even in the interpreter's own scripts folder (a Python whose
    environment lacks nbgrader's dependencies), one line says what to install."""
    bare = tmp_path / "bin"   # an empty scripts folder, as if it were the interpreter's
    bare.mkdir()
    code = ("import sys, sysconfig; bare = sys.argv.pop(1); get_path = sysconfig.get_path; "
            "sysconfig.get_path = lambda name, *a, **k: bare if name == 'scripts' else get_path(name, *a, **k); "
            "sys.executable = bare + '/python'; from kfcal_helpers.cli import main; sys.exit(main(sys.argv[1:]))")
    env = environment(path_with_scripts=False)
    proc = subprocess.run([sys.executable, "-c", code, str(bare), "assignments", "--notebooks",
                           str(one_lesson), "--course", str(tmp_path / "course")], cwd=ROOT, capture_output=True,
                          text=True, env=env, timeout=600)
    line = one_error_line(proc)
    assert "alembic" in line and "pip install -r environment-instructors.txt" in line
    assert not (tmp_path / "course" / "gradebook.db").exists()


@needs_nbgrader
def test_the_real_nbgrader_command_line_reads_the_course_config(tmp_path, one_lesson):
    """``nbgrader`` run in the course folder loads ``nbgrader_config.py`` without an error (it used to print
    ``NameError: name 'os' is not defined`` and ignore the file): ``generate_assignment --force`` keeps the
    lesson's placeholders (no ``raise NotImplementedError()`` stubs), and autograde and feedback run."""
    course = tmp_path / "course"
    made = assignments("--notebooks", one_lesson, "--course", course)
    assert made.returncode == 0, made.stderr[-2000:]
    gen = nbgrader_cli(course, "generate_assignment", LESSON, "--force")
    assert gen.returncode == 0, gen.stderr[-3000:]
    assert "Error" not in gen.stderr and "Traceback" not in gen.stderr, gen.stderr[-3000:]
    release = nbformat.read(course / "release" / LESSON / f"{LESSON}.ipynb", 4)
    answers = [c.source for c in release.cells if c.metadata.get("nbgrader", {}).get("solution")]
    assert answers and all("NotImplementedError" not in a and "...   # replace ... with your" in a
                           for a in answers)
    # a hand-in of the release as it is (placeholders): autograded to 0 by the real command line
    hand_in = course / "submitted" / "s1" / LESSON
    hand_in.mkdir(parents=True)
    shutil.copy(course / "release" / LESSON / f"{LESSON}.ipynb", hand_in)
    for step in (["autograde", LESSON], ["generate_feedback", LESSON]):
        proc = nbgrader_cli(course, *step)
        assert proc.returncode == 0, proc.stderr[-3000:]
        assert "NameError" not in proc.stderr and "Traceback" not in proc.stderr, proc.stderr[-3000:]
    from nbgrader.api import Gradebook
    with Gradebook(f"sqlite:///{course / 'gradebook.db'}", course_id="kfcal") as gb:
        sub = gb.find_submission(LESSON, "s1")
        assert sub.score == 0 and sub.max_score == len(answers)
    assert (course / "feedback" / "s1" / LESSON / f"{LESSON}.html").is_file()


@needs_nbgrader
def test_making_the_course_again_keeps_hand_ins_grades_and_feedback(tmp_path, one_lesson):
    course = tmp_path / "course"
    assert assignments("--notebooks", one_lesson, "--course", course).returncode == 0
    hand_in = course / "submitted" / "s1" / LESSON
    hand_in.mkdir(parents=True)
    shutil.copy(course / "release" / LESSON / f"{LESSON}.ipynb", hand_in)
    for step in (["autograde", LESSON], ["generate_feedback", LESSON]):
        assert nbgrader_cli(course, *step).returncode == 0
    (course / "grades.csv").write_text("the grader's export\n")
    kept = {name: snapshot(course / name) for name in ("submitted", "autograded", "feedback")}
    kept["grades.csv"] = (course / "grades.csv").read_bytes()
    gradebook = (course / "gradebook.db").stat().st_size
    assert all(kept.values()) and gradebook > 0

    again = assignments("--notebooks", one_lesson, "--course", course)
    assert again.returncode == 0, again.stderr[-2000:]
    assert {name: snapshot(course / name) for name in ("submitted", "autograded", "feedback")} == {
        k: v for k, v in kept.items() if k != "grades.csv"}
    assert (course / "grades.csv").read_bytes() == kept["grades.csv"]
    from nbgrader.api import Gradebook
    with Gradebook(f"sqlite:///{course / 'gradebook.db'}", course_id="kfcal") as gb:
        assert [s.name for s in gb.assignments] == [LESSON]
        sub = gb.find_submission(LESSON, "s1")
        assert sub.max_score > 0 and sub.score == 0
    assert (course / "release" / LESSON / f"{LESSON}.ipynb").is_file()


# ------------------------------------------------------------------------------------------------
# what a graded class receives (README, For lecturers: "Handing out a graded course")
# ------------------------------------------------------------------------------------------------
def readme_archive_command():
    """The ``git archive`` line of README's hand-out paragraph, as a list of arguments."""
    lines = [line.strip() for line in (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
             if line.strip().startswith("git archive ")]
    assert len(lines) == 1, lines
    return lines[0].split()


@needs_nbgrader
@pytest.mark.slow
def test_a_graded_class_gets_the_release_and_the_package_without_the_answers(tmp_path):
    """README's archive holds the package and no notebook; installed from it into a fresh venv (the package, as
    ``pip install -r environment.txt`` installs it there, plus a kernel), a released notebook whose answer cells
    hold the worked answers runs through every graded check with that package, not the repository's."""
    from kfcal_helpers.assignments import generate, write_course

    if subprocess.run(["git", "rev-parse", "--verify", "HEAD"], cwd=ROOT, capture_output=True).returncode:
        pytest.skip("not a git checkout: README's git archive needs one")
    command = readme_archive_command()
    assert command[2] == "-o" and command[3].endswith(".zip")
    archive = tmp_path / "kf-package.zip"
    made = subprocess.run([*command[:3], str(archive), *command[4:]], cwd=ROOT, capture_output=True, text=True)
    assert made.returncode == 0, made.stderr
    with zipfile.ZipFile(archive) as zf:
        names = zf.namelist()
        zf.extractall(tmp_path / "package")
    assert "environment.txt" in names and "kfcal_helpers/assignments/_nbgrader.py" in names
    assert not [n for n in names if n.startswith(("notebooks/", "docs/", "tests/")) or n.endswith(".ipynb")]
    assert [n for n in names if n.endswith(".md")] == ["README.md"]
    package = tmp_path / "package"
    assert "-e .\n" in (package / "environment.txt").read_text()   # Start here's install takes the package from it

    # a fresh venv: the package from the archive, editable as environment.txt installs it, and a kernel
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    python = venv / ("Scripts/python.exe" if os.name == "nt" else "bin/python")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV", "CI")}
    env["KFCAL_QUIET"] = "1"
    pins = {line.split("==")[0]: line.strip() for line in (package / "environment.txt").read_text().splitlines()
            if "==" in line and not line.startswith("#")}
    pip = subprocess.run([sys.executable, "-m", "pip", "--python", str(python), "install", "-q",
                          "--disable-pip-version-check", "--no-compile", "-e", str(package), pins["ipykernel"],
                          *(pins[name] for name in ("filterpy", "numpy", "scipy", "matplotlib", "nbformat",
                                                    "nbclient", "tqdm"))],
                         capture_output=True, text=True, env=env, timeout=900)
    assert pip.returncode == 0, pip.stderr[-2000:]

    # the release of lesson 01, its answer cells given the worked answers (the instructor's version)
    course = tmp_path / "course"
    assert write_course(course, [NOTEBOOKS / "source" / f"{LESSON}.md"]) == [LESSON]
    generate(course, [LESSON], log=lambda line: None)
    solved = {c.metadata["nbgrader"]["grade_id"]: c.source
              for c in nbformat.read(course / "source" / LESSON / f"{LESSON}.ipynb", 4).cells
              if c.metadata.get("nbgrader", {}).get("solution")}
    release = nbformat.read(course / "release" / LESSON / f"{LESSON}.ipynb", 4)
    graded = [c for c in release.cells if c.metadata.get("nbgrader", {}).get("grade")]
    assert graded
    for cell in release.cells:
        if cell.metadata.get("nbgrader", {}).get("solution"):
            assert "BEGIN SOLUTION" not in cell.source   # the release holds placeholders only
            cell.source = solved[cell.metadata["nbgrader"]["grade_id"]]
    release.cells.append(nbformat.v4.new_code_cell("import kfcal_helpers; print(kfcal_helpers.__file__)"))
    student = tmp_path / "student"
    student.mkdir()
    nbformat.write(release, student / f"{LESSON}.ipynb")
    run = subprocess.run(
        [str(python), "-c", "import sys, nbformat, nbclient; nb = nbformat.read(sys.argv[1], 4); "
         "nbclient.NotebookClient(nb, timeout=600, kernel_name='python3').execute(); nbformat.write(nb, sys.argv[1])",
         str(student / f"{LESSON}.ipynb")], cwd=student, capture_output=True, text=True, env=env, timeout=900)
    assert run.returncode == 0, run.stderr[-3000:]
    done = nbformat.read(student / f"{LESSON}.ipynb", 4)
    assert not [o for c in done.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "error"]
    where = "".join(o.get("text", "") for o in done.cells[-1].outputs)
    assert Path(where.strip()).resolve().is_relative_to(package.resolve()), where
