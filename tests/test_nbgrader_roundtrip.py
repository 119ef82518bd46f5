"""The nbgrader course end to end: make it, release, submit, autograde, read the grades.

In a temporary course: the worked solutions of assignments 03 and 08 get full marks; students
``wrong1``, ``wrong2``, ... each submit, for exercises 03.1, 03.2 and 03.3, the k-th wrong answer
listed for it in tests/test_exercises_calibration.py (the worked solution once the list is used up),
and get no mark for exactly those items, full marks for the others, and the check's hint for that
mistake in their autograded notebook and feedback.  Needs nbgrader (environment-instructors.txt).
"""

import html
import importlib.util
import json
import shutil
from pathlib import Path

import nbformat
import numpy as np
import pytest

pytest.importorskip("nbgrader", reason="nbgrader is not installed: pip install -r environment-instructors.txt")

from nbgrader.api import Gradebook  # noqa: E402
from nbgrader.apps import NbGraderAPI  # noqa: E402
from traitlets.config import Config  # noqa: E402

from kfcal_helpers.assignments import answer_cells, generate, read_source, write_course  # noqa: E402
from kfcal_helpers.calibration.exercises import EXERCISES  # noqa: E402

# nbgrader 0.9.6's gradebook warns about its SQLAlchemy sessions (SAWarning: "... add operation along
# 'Assignment.submissions' will not proceed") with every SQLAlchemy 2 (2.0.58 and the pinned 2.1.9 alike):
# SQLAlchemy 1.4.54 does not, but has no wheels for Python 3.13; not ours to fix
pytestmark = pytest.mark.filterwarnings("ignore::sqlalchemy.exc.SAWarning")

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ROOT / "notebooks" / "source"
SOLVED = ["03_gps_model", "08_coop_nonlinear_model"]
WRONG_IN = "03_gps_model"
CHOSEN = ["03.1", "03.2", "03.3"]


def listed_wrong_answers():
    """``{exercise: [(mistake key, value), ...]}`` of the chosen exercises, from the checks' unit tests."""
    spec = importlib.util.spec_from_file_location("_calibration_cases", ROOT / "tests" / "test_exercises_calibration.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    table = module.cases()
    return {ex: [(key, value) for key, value in table[ex][2]] for ex in CHOSEN}, {ex: table[ex][0] for ex in CHOSEN}


def literal(name, value):
    arr = np.asarray(value)
    return f"{name} = np.array({arr.tolist()!r}, dtype={arr.dtype.str!r})"


def instructor_cells(course, assignment):
    """``{grade_id: source}`` of the instructor's answer cells (nbgrader's source notebook): the worked answers."""
    nb = nbformat.read(course / "source" / assignment / f"{assignment}.ipynb", 4)
    return {c.metadata["nbgrader"]["grade_id"]: c.source for c in nb.cells
            if c.metadata.get("nbgrader", {}).get("solution")}


def submit(course, student, assignment, replace):
    """Copy the released notebook to submitted/student/assignment, the answer cells' sources given by
    ``replace(grade_id) -> source``."""
    release = course / "release" / assignment / f"{assignment}.ipynb"
    nb = nbformat.read(release, 4)
    for cell in nb.cells:
        meta = cell.metadata.get("nbgrader", {})
        if meta.get("solution"):
            cell.source = replace(meta["grade_id"])
    folder = course / "submitted" / student / assignment
    folder.mkdir(parents=True)
    nbformat.write(nb, folder / f"{assignment}.ipynb")


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    course = tmp_path_factory.mktemp("course")
    names = write_course(course, [SOURCES / f"{n}.md" for n in SOLVED])
    assert names == SOLVED
    generate(course, names, log=lambda line: None)
    answers = {}
    for name in SOLVED:
        for _, a in answer_cells(read_source(SOURCES / f"{name}.md")):
            answers["ex_" + a.exercise.replace(".", "_")] = (name, a)
    worked = {}
    for name in SOLVED:
        worked.update(instructor_cells(course, name))
        submit(course, "solutions", name, worked.get)
    wrong, checks = listed_wrong_answers()
    n_students = max(len(v) for v in wrong.values())
    expected = {}   # (student, exercise) -> the check's Feedback for the wrong answer
    for k in range(n_students):
        student = f"wrong{k + 1}"
        chosen = {}
        for ex in CHOSEN:
            if k < len(wrong[ex]):
                key, value = wrong[ex][k]
                feedback = checks[ex](value)
                assert not feedback.correct and feedback.message == EXERCISES[ex].hints[key], (ex, key, str(feedback))
                expected[(student, ex)] = feedback
                chosen["ex_" + ex.replace(".", "_")] = literal(answers["ex_" + ex.replace(".", "_")][1].answer, value)
        submit(course, student, WRONG_IN, lambda gid: chosen.get(gid) or worked[gid])
    config = Config()
    config.CourseDirectory.root = str(course)
    config.Execute.timeout = 300
    api = NbGraderAPI(config=config)
    students = ["solutions"] + [f"wrong{k + 1}" for k in range(n_students)]
    for student in students:
        for name in (SOLVED if student == "solutions" else [WRONG_IN]):
            result = api.autograde(name, student, force=True, create=True)
            assert result["success"], result.get("error") or result.get("log")
    result = api.generate_feedback(WRONG_IN, "wrong1", force=True)
    assert result["success"], result.get("error") or result.get("log")
    return course, answers, expected, students


def test_the_release_shows_the_placeholders_and_no_solutions(graded):
    course, answers, _, _ = graded
    for name in SOLVED:
        nb = nbformat.read(course / "release" / name / f"{name}.ipynb", 4)
        text = "\n".join(c.source for c in nb.cells)
        assert "solutions/" not in text and "BEGIN SOLUTION" not in text and "**Solution.**" not in text
        placeholders = {c.metadata["nbgrader"]["grade_id"]: c.source for c in nb.cells
                        if c.metadata.get("nbgrader", {}).get("solution")}
        assert placeholders and all("replace ... with your" in s for s in placeholders.values())
        for gid, (owner, answer) in answers.items():
            if owner == name:   # the release's answer cell is the lesson's placeholder, without the check call
                lesson = [t for r, t in answer.lines[:-1] if r in (None, "placeholder")]
                assert [t for t in placeholders[gid].split("\n") if t.strip()] == [t for t in lesson if t.strip()]


def test_worked_solutions_get_full_marks(graded):
    course, answers, _, _ = graded
    with Gradebook(f"sqlite:///{course / 'gradebook.db'}") as gb:
        for name in SOLVED:
            sub = gb.find_submission(name, "solutions")
            assert sub.max_score > 0 and sub.score == sub.max_score, name
            owned = [gid for gid, (owner, _) in answers.items() if owner == name]
            assert len(owned) == len([g for g in sub.notebooks[0].grades if g.max_score])


def test_each_listed_wrong_answer_loses_exactly_its_item_and_shows_its_hint(graded):
    course, answers, expected, students = graded
    nb_name = WRONG_IN
    with Gradebook(f"sqlite:///{course / 'gradebook.db'}") as gb:
        for student in students[1:]:
            autograded = nbformat.read(course / "autograded" / student / nb_name / f"{nb_name}.ipynb", 4)
            outputs = {c.metadata["nbgrader"]["grade_id"]: json.dumps(c.get("outputs", []), ensure_ascii=False)
                       for c in autograded.cells if c.metadata.get("nbgrader", {}).get("grade")}
            sub = gb.find_submission(nb_name, student)
            assert sub.max_score == len(outputs)
            for gid, (owner, answer) in answers.items():
                if owner != nb_name:
                    continue
                grade = gb.find_grade(gid + "_check", nb_name, nb_name, student)
                feedback = expected.get((student, answer.exercise))
                if feedback is None:
                    assert grade.score == grade.max_score == 1, (student, gid)
                    assert "AssertionError" not in outputs[gid + "_check"]
                else:
                    assert grade.score == 0 and grade.max_score == 1, (student, gid)
                    assert "AssertionError" in outputs[gid + "_check"]
                    assert feedback.message in outputs[gid + "_check"], (student, gid, feedback.message)
            assert sub.score == sub.max_score - sum(1 for (s, _) in expected if s == student)
    report = course / "feedback" / "wrong1" / nb_name / f"{nb_name}.html"
    page = html.unescape(report.read_text(encoding="utf-8"))
    for (student, ex), feedback in expected.items():
        if student == "wrong1":
            assert feedback.message in page, ex


def test_the_course_can_be_made_again_in_place(graded, tmp_path):
    course = tmp_path / "again"
    shutil.copytree(graded[0] / "source", course / "source")
    notebook = course / "source" / SOLVED[0] / f"{SOLVED[0]}.ipynb"
    before = notebook.read_bytes()
    names = write_course(course, [SOURCES / f"{SOLVED[0]}.md"])
    assert names == SOLVED[:1] and (course / "nbgrader_config.py").read_text().count("code_stub") == 1
    # the same source makes the same notebook, cell ids included (a text source's ids come from its cells)
    assert notebook.read_bytes() == before
    nb = nbformat.read(notebook, 4)
    nbformat.validate(nb)
    assert len({c.id for c in nb.cells}) == len(nb.cells)
