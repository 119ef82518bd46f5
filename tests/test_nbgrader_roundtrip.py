"""The nbgrader course end to end: make it, release, submit, autograde, read the grades.

In a temporary course: the worked solutions of assignments 03 and 08 get full marks; students
``wrong1``, ``wrong2``, ... each submit, for exercises 03.1, 03.2 and 03.3, the k-th wrong answer
listed for it in tests/test_exercises_calibration.py (the worked solution once the list is used up),
and get no mark for exactly those items, full marks for the others, and the check's hint for that
mistake, as one line, in their autograded notebook and feedback.  Students ``cheat_<name>`` answer every
exercise of 03 wrong (0, or a function that returns nothing) and cheat (:data:`CHEATS`: patch the checks,
the verdict, numpy or the recorder in their kernel, rewrite a grade cell as it runs, edit or delete the
grade cells, print ✔ by hand): each gets 0 for every item.  The course is graded with the configuration
its ``nbgrader_config.py`` gives, as ``nbgrader autograde`` run in the course folder reads it.  Needs
nbgrader (environment-instructors.txt).
"""

import csv
import html
import importlib
import importlib.util
import json
import re
import shutil
from pathlib import Path

import nbformat
import numpy as np
import pytest

pytest.importorskip("nbgrader", reason="nbgrader is not installed: pip install -r environment-instructors.txt")

from nbgrader.api import Gradebook  # noqa: E402
from nbgrader.apps import NbGraderAPI  # noqa: E402
from traitlets.config.loader import PyFileConfigLoader  # noqa: E402

from kfcal_helpers.assignments import answer_cells, check_modules, generate, read_source, write_course  # noqa: E402
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

# code a cheating student puts at the top of the first answer cell (their answers are all wrong)
CHEATS = {
    # the cheat: every check in the module replaced by one that says ✔
    "patch_module": """
import kfcal_helpers.calibration.exercises as e
class Ok:
    correct = True
    def assert_correct(self): print("✔")
    def __str__(self): return "✔ correct"
for n in dir(e):
    if n.startswith("check_"): setattr(e, n, lambda *a, **k: Ok())
""",
    # every grade cell rewritten as it runs: the check's name rebound right after its import
    "rebind_after_import": """
def _rebind(lines):
    out = []
    for line in lines:
        out.append(line)
        if line.startswith("from kfcal_helpers") and ("check_" in line or "record_answer" in line):
            name = line.split(" import ")[1].strip()
            out.append(f"{name} = lambda *a, **k: type('Ok', (), {{'correct': True, "
                       f"'assert_correct': lambda self: print('✔')}})()\\n")
    return out
get_ipython().input_transformers_post.append(_rebind)
""",
    # the verdict object itself: every Feedback made correct, its assertion silent
    "patch_feedback": """
from kfcal_helpers.exercises import _core
_init = _core.Feedback.__init__
def _always_right(self, exercise, correct, message, answered=True):
    _init(self, exercise, True, message, answered)
_core.Feedback.__init__ = _always_right
_core.Feedback.assert_correct = lambda self: print("✔")
""",
    # numpy's comparisons all say "equal" (answers of the right shapes: the listed mistakes, SHAPED_WRONG)
    "patch_numpy": """
import numpy as np
np.allclose = lambda *a, **k: True
np.isclose = lambda a, b, *r, **k: np.ones(np.broadcast(np.asarray(a), np.asarray(b)).shape, bool)
np.array_equal = lambda *a, **k: True
np.all = lambda *a, **k: True
""",
    # the recorder made to record something that is not an answer
    "patch_recorder": """
import kfcal_helpers.exercises.grading as g
g.encode = lambda value, _depth=0: {"t": "forged", "v": "right"}
""",
    # a function answer's results recorded for other inputs than the check's
    "patch_replay_inputs": """
import kfcal_helpers.exercises.grading as g
_record_call = g._Recorder.__call__
def _other_inputs(self, *args, **kwargs):
    out = _record_call(self, *args, **kwargs)
    self.calls[-1]["args"] = g.encode(("other inputs",))
    return out
g._Recorder.__call__ = _other_inputs
import kfcal_helpers.calibration.exercises as e
e.check_gps_measurement = lambda f: print("✔") or f(1.0)
""",
    # ✔ printed by hand, where a grader reading outputs might look for it
    "print_by_hand": """
for ex in ("03.1", "03.2", "03.3", "03.4"):
    print(f"✔ {ex} correct: well done")
""",
}
# the cheats whose wrong answers have the right shapes (a comparison decides them): the first mistake
# listed for 03.1-03.3, and for 03.4 a function that swaps position and velocity
SHAPED_WRONG = ("patch_numpy",)
SWAPPED_04 = ("def _swapped(p, v, eta, steps_per_fix):\n"
              "    return np.stack([v[:, ::steps_per_fix], p[:, ::steps_per_fix]], axis=-1) + eta\n\n"
              "answer_03_4 = _swapped")
# cheats made in the submitted file rather than in the kernel
FILE_CHEATS = ("edit_grade_cells", "delete_grade_cells")


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


def wrong_answer(answer):
    """A wrong answer to an exercise: 0, or a function that returns nothing."""
    if answer.answer.startswith("answer_") and any("def " in t for _, t in answer.lines):
        return f"def _nothing(*args, **kwargs):\n    pass\n\n{answer.answer} = _nothing"
    return f"{answer.answer} = 0"


def submit(course, student, assignment, replace, grade_cells=None):
    """Copy the released notebook to submitted/student/assignment, the answer cells' sources given by
    ``replace(grade_id) -> source``; ``grade_cells`` (optional) edits the grade cells: a function of the
    cell returning its new source, or None to delete it."""
    release = course / "release" / assignment / f"{assignment}.ipynb"
    nb = nbformat.read(release, 4)
    cells = []
    for cell in nb.cells:
        meta = cell.metadata.get("nbgrader", {})
        if meta.get("solution"):
            cell.source = replace(meta["grade_id"])
        if meta.get("grade") and grade_cells is not None:
            cell.source = grade_cells(cell)
            if cell.source is None:
                continue
        cells.append(cell)
    nb.cells = cells
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
    first = min(gid for gid, (owner, _) in answers.items() if owner == WRONG_IN)
    wrong_all = {gid: wrong_answer(a) for gid, (owner, a) in answers.items() if owner == WRONG_IN}
    shaped = {**wrong_all, **{"ex_" + ex.replace(".", "_"): literal(answers["ex_" + ex.replace(".", "_")][1].answer,
                                                                   wrong[ex][0][1]) for ex in CHOSEN},
              "ex_03_4": SWAPPED_04}
    cheat_answers = {}   # student -> {grade_id: answer source}
    for name, code in CHEATS.items():
        mine = shaped if name in SHAPED_WRONG else wrong_all
        cheat_answers[f"cheat_{name}"] = mine
        submit(course, f"cheat_{name}", WRONG_IN,
               lambda gid, code=code, mine=mine: (code.strip() + "\n\n" if gid == first else "") + mine[gid])
    cheat_answers.update({f"cheat_{name}": wrong_all for name in FILE_CHEATS})
    submit(course, "cheat_edit_grade_cells", WRONG_IN, wrong_all.get,
           grade_cells=lambda cell: 'print("✔ correct")')
    submit(course, "cheat_delete_grade_cells", WRONG_IN, wrong_all.get, grade_cells=lambda cell: None)
    # the configuration nbgrader autograde reads in the course folder
    config = PyFileConfigLoader("nbgrader_config.py", path=str(course)).load_config()
    config.Execute.timeout = 300
    api = NbGraderAPI(config=config)
    students = ["solutions"] + [f"wrong{k + 1}" for k in range(n_students)]
    cheats = [f"cheat_{name}" for name in [*CHEATS, *FILE_CHEATS]]
    logs = {}
    for student in students + cheats:
        for name in (SOLVED if student == "solutions" else [WRONG_IN]):
            result = api.autograde(name, student, force=True, create=True)
            assert result["success"], result.get("error") or result.get("log")
            logs[student] = result.get("log", "")
    for student in ("wrong1", "cheat_patch_module"):
        result = api.generate_feedback(WRONG_IN, student, force=True)
        assert result["success"], result.get("error") or result.get("log")
    return course, answers, expected, students, cheats, cheat_answers, logs


def test_the_release_shows_the_placeholders_and_no_solutions(graded):
    course, answers, *_ = graded
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
    course, answers, *_ = graded
    with Gradebook(f"sqlite:///{course / 'gradebook.db'}") as gb:
        for name in SOLVED:
            sub = gb.find_submission(name, "solutions")
            assert sub.max_score > 0 and sub.score == sub.max_score, name
            owned = [gid for gid, (owner, _) in answers.items() if owner == name]
            assert len(owned) == len([g for g in sub.notebooks[0].grades if g.max_score])


def test_each_listed_wrong_answer_loses_exactly_its_item_and_shows_its_hint(graded):
    course, answers, expected, students, *_ = graded
    nb_name = WRONG_IN
    with Gradebook(f"sqlite:///{course / 'gradebook.db'}") as gb:
        for student in students[1:]:
            autograded = nbformat.read(course / "autograded" / student / nb_name / f"{nb_name}.ipynb", 4)
            outputs = {c.metadata["nbgrader"]["grade_id"]: c.get("outputs", [])
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
                    assert outputs[gid + "_check"] == [{"output_type": "stream", "name": "stdout",
                                                        "text": f"✔ {answer.exercise} correct: "
                                                                f"{EXERCISES[answer.exercise].praise}\n"}]
                else:   # the hint first, as the only line of the error
                    assert grade.score == 0 and grade.max_score == 1, (student, gid)
                    [error] = outputs[gid + "_check"]
                    assert error["output_type"] == "error" and error["traceback"] == [str(feedback)], (student, gid)
                    assert str(feedback) == f"✘ {answer.exercise} not yet: {feedback.message}"
            assert sub.score == sub.max_score - sum(1 for (s, _) in expected if s == student)
    report = course / "feedback" / "wrong1" / nb_name / f"{nb_name}.html"
    page = html.unescape(report.read_text(encoding="utf-8"))
    for (student, ex), feedback in expected.items():
        if student == "wrong1":
            assert str(feedback) in page, ex
    # no traceback, no package source, no grader's path in what the student reads
    for text in ("Traceback (most recent call last)", "site-packages", "kfcal_helpers/", "raise AssertionError",
                 str(course)):
        assert text not in page, text
    # the equations are typeset by a MathJax inside the page, nothing is loaded from the network
    assert "$" in page and "window.MathJax" in page and "tex-svg.js" in page
    assert not re.search(r"<script[^>]*\bsrc=", page) and "cdnjs" not in page


def grade_outputs(course, student, nb_name=WRONG_IN):
    """``{grade_id: outputs}`` of the grade cells of a student's autograded notebook."""
    nb = nbformat.read(course / "autograded" / student / nb_name / f"{nb_name}.ipynb", 4)
    return {c.metadata["nbgrader"]["grade_id"]: c.get("outputs", []) for c in nb.cells
            if c.metadata.get("nbgrader", {}).get("grade")}


@pytest.mark.parametrize("cheat", [*CHEATS, *FILE_CHEATS])
def test_a_cheat_with_wrong_answers_scores_nothing(graded, cheat):
    course, answers, *_ = graded
    student = f"cheat_{cheat}"
    n_items = sum(1 for owner, _ in answers.values() if owner == WRONG_IN)
    with Gradebook(f"sqlite:///{course / 'gradebook.db'}") as gb:
        sub = gb.find_submission(WRONG_IN, student)
        scores = {g.name: g.score for g in sub.notebooks[0].grades}
        assert sub.max_score == n_items and scores == {gid + "_check": 0 for gid, (owner, _) in answers.items()
                                                       if owner == WRONG_IN}, (student, scores)
    outputs = grade_outputs(course, student)
    for gid, cell_outputs in outputs.items():   # what is left of each grade cell says ✘, never ✔
        text = json.dumps(cell_outputs, ensure_ascii=False)
        assert "✘" in text and "✔" not in text, (student, gid, text)


def test_the_cheats_verdicts_say_what_went_wrong(graded):
    course, answers, *_, cheat_answers, logs = graded
    modules = check_modules()
    ours = sorted((gid, a) for gid, (owner, a) in answers.items() if owner == WRONG_IN)

    def genuine(cheat):
        """The genuine checks' lines on the cheat's wrong answers, run here."""
        namespace = {"np": np}
        out = []
        for gid, a in ours:
            exec(cheat_answers[f"cheat_{cheat}"][gid], namespace)
            out.append(str(getattr(importlib.import_module(modules[a.check]), a.check)(namespace[a.answer])))
        return out

    honest = genuine("patch_module")
    lines = {cheat: [o.get("evalue", o.get("text")) for outs in grade_outputs(course, f"cheat_{cheat}").values()
                     for o in outs]
             for cheat in [*CHEATS, *FILE_CHEATS]}
    # the verdict and numpy patched in the kernel, ✔ printed, grade cells edited: the genuine checks' hints
    for cheat in ("patch_feedback", "patch_numpy", "print_by_hand", "edit_grade_cells"):
        assert lines[cheat] == genuine(cheat), cheat
    assert all(" not yet: " in line for line in lines["patch_numpy"])   # each a listed mistake's hint
    # the checks replaced: the values' hints; the function was never called by the genuine check
    assert lines["patch_module"][:-1] == honest[:-1] and ours[-1][1].exercise == "03.4"
    assert lines["patch_module"][-1].startswith("✘ 03.4 not graded: the recorded results of your function")
    # the grade cells rewritten as they run: nothing recorded
    assert lines["rebind_after_import"] == [f"✘ {a.exercise} not graded: no answer was recorded (the grade cell's "
                                            "output is missing or altered); run the notebook from the top and hand "
                                            "it in again" for _, a in ours]
    # the record forged: not graded, said so, and in the log the lecturer reads
    assert all("record of your answer" in line for line in lines["patch_recorder"])
    for _, a in ours:
        assert f"cheat_patch_recorder, exercise {a.exercise}: ✘ {a.exercise} not graded" in logs["cheat_patch_recorder"]
    assert "recorded results of your function are not those of the check's test inputs" in lines["patch_replay_inputs"][-1]
    # the lecturer's list of what could not be graded: exactly the forged, missing and deleted records
    with open(course / "grading_flags.csv", newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    exs = [a.exercise for _, a in ours]
    assert {(r["student"], r["assignment"], r["exercise"]) for r in rows} == {
        *((f"cheat_{cheat}", WRONG_IN, ex) for cheat in ("rebind_after_import", "patch_recorder") for ex in exs),
        ("cheat_patch_module", WRONG_IN, "03.4"), ("cheat_patch_replay_inputs", WRONG_IN, "03.4"),
        *(("cheat_delete_grade_cells", WRONG_IN, gid + "_check") for gid, _ in ours)}
    # nbgrader scores a deleted grade cell 0 (above) and marks it for the lecturer to look at
    assert lines["delete_grade_cells"] == []
    with Gradebook(f"sqlite:///{course / 'gradebook.db'}") as gb:
        sub = gb.find_submission(WRONG_IN, "cheat_delete_grade_cells")
        assert all(g.auto_score is None and g.needs_manual_grade for g in sub.notebooks[0].grades)
    page = html.unescape((course / "feedback" / "cheat_patch_module" / WRONG_IN / f"{WRONG_IN}.html").read_text("utf-8"))
    assert "Traceback (most recent call last)" not in page and all(line in page for line in lines["patch_module"])


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


# MathJax in a feedback page: wait for its typesetting, then count what is typeset and what is left raw
_MATH_JS = """
const done = arguments[arguments.length - 1];
const finish = () => {
    const raw = [];
    for (const cell of document.querySelectorAll('.text_cell_render')) {
        const walker = document.createTreeWalker(cell, NodeFilter.SHOW_TEXT);
        for (let n = walker.nextNode(); n; n = walker.nextNode()) {
            if (n.parentElement.closest('pre, code, script, style, mjx-container')) continue;
            if (/[$]|\\\\[(\\[]/.test(n.textContent)) raw.push(n.textContent.trim().slice(0, 80));
        }
    }
    done({typeset: document.querySelectorAll('mjx-container').length, raw});
};
const wait = () => (window.MathJax && MathJax.startup && MathJax.startup.promise)
    ? MathJax.startup.promise.then(finish, e => done({failed: String(e)})) : setTimeout(wait, 50);
wait();
"""


def test_the_feedback_typesets_its_equations_offline(graded, tmp_path):
    chromium = pytest.importorskip("chromium", reason="tests/chromium.py not importable")
    if chromium.CHROMIUM is None or chromium.CHROMEDRIVER is None:
        pytest.skip(chromium.MISSING)
    page = graded[0] / "feedback" / "wrong1" / WRONG_IN / f"{WRONG_IN}.html"
    driver = chromium.start((1200, 900), tmp_path / "profile", {"performance": "ALL"})
    try:
        driver.set_script_timeout(60)
        driver.get(page.as_uri())
        result = driver.execute_async_script(_MATH_JS)
        requests = [json.loads(e["message"])["message"]["params"]["request"]["url"]
                    for e in driver.get_log("performance")
                    if json.loads(e["message"])["message"].get("method") == "Network.requestWillBeSent"]
    finally:
        driver.quit()
    assert "failed" not in result, result
    assert result["typeset"] >= 5 and result["raw"] == [], result
    assert [u for u in requests if u.split(":")[0] in ("http", "https", "ws", "wss", "ftp")] == []
