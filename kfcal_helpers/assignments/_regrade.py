"""The grader's re-check of a graded notebook's answers, outside the student's kernel.

:class:`RecheckAnswers` is an nbconvert preprocessor that nbgrader's ``autograde`` runs right after it
has executed the student's notebook (:func:`autograde_preprocessors`, set by the course's
``nbgrader_config.py``).  Each grade cell's source (which nbgrader has restored from its gradebook) names
the exercise and its check (``record_answer("03.1", "<module>", "check_xxx", answer)``); the cell's output
holds the record of the student's answer (:func:`kfcal_helpers.exercises.grading.record_answer`).  All
records of the notebook are re-checked in one fresh Python process (``python -P -m
kfcal_helpers.exercises.grading``, started from an empty folder, so nothing of the submission's folder is
imported), and each grade cell's outputs are replaced by the verdict: the check's ✔ line (full marks), or
an error whose only line is the check's ✘ line with its hint (no marks).  A grade cell without exactly one
record that decodes, or whose record is forged or altered, scores 0, and is reported in nbgrader's log and
in the course's ``grading_flags.csv`` (``RecheckAnswers.report``: student, assignment, notebook,
exercise, why), which the lecturer reads after ``nbgrader autograde``.
"""

from __future__ import annotations

import ast
import csv
import json
import os
import subprocess
import sys
import tempfile

from nbconvert.preprocessors import Preprocessor
from nbformat.v4 import new_output
from traitlets import Bool, Unicode

__all__ = ["RECORD_CALL", "REPORT_COLUMNS", "RecheckAnswers", "autograde_preprocessors", "grade_cell_call",
           "update_report"]

#: the function a grade cell calls
RECORD_CALL = "record_answer"
_TIMEOUT = 600   # seconds for the re-check of one notebook


def grade_cell_call(source: str) -> tuple[str, str, str] | None:
    """``(exercise, module, check)`` of the ``record_answer("NN.k", "module", "check_xxx", answer)`` call in a
    grade cell's source, or None when there is no such call (with string literals)."""
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return None
    for node in ast.walk(tree):
        if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == RECORD_CALL
                and len(node.args) == 4 and all(isinstance(a, ast.Constant) and isinstance(a.value, str)
                                                for a in node.args[:3])):
            return tuple(a.value for a in node.args[:3])
    return None


def _recheck(items: list[dict]) -> list[dict]:
    """The verdicts of a fresh process on ``items`` (see :mod:`kfcal_helpers.exercises.grading`)."""
    if not items:
        return []
    env = dict(os.environ, KFCAL_QUIET="1", PYTHONIOENCODING="utf-8")
    with tempfile.TemporaryDirectory(prefix="kfcal-recheck-") as empty:
        done = subprocess.run([sys.executable, "-P", "-m", "kfcal_helpers.exercises.grading"],
                              input=json.dumps(items).encode("utf-8"), capture_output=True, cwd=empty, env=env,
                              timeout=_TIMEOUT)
    if done.returncode != 0:
        tail = done.stderr.decode("utf-8", "replace").strip().splitlines()[-1:] or ["no message"]
        raise RuntimeError(f"the re-check of the answers failed (exit {done.returncode}): {tail[0]}")
    verdicts = json.loads(done.stdout.decode("utf-8"))
    if len(verdicts) != len(items):
        raise RuntimeError("the re-check of the answers returned a wrong number of verdicts")
    return verdicts


class RecheckAnswers(Preprocessor):
    """Re-checks the recorded answers of an executed graded notebook outside the student's kernel and puts
    each verdict in its grade cell's outputs (see the module's docstring)."""

    enabled = Bool(True, help="nbconvert runs a preprocessor only when enabled")
    report = Unicode("", help="a CSV file listing the grade cells not graded (student, assignment, notebook, "
                              "exercise, reason); '' for none").tag(config=True)

    def preprocess(self, nb, resources):
        from ..exercises.grading import RECORD_MIME, exercise_of

        who = resources.get("nbgrader", {}).get("student", "?")
        flags = []
        cells, items = [], []
        for cell in nb.cells:
            meta = cell.get("metadata", {}).get("nbgrader", {})
            if cell.cell_type != "code" or not meta.get("grade"):
                continue
            call = grade_cell_call(cell.source)
            if call is None:
                continue
            exercise, module, check = call
            records = [o for o in cell.get("outputs", []) if o.get("output_type") in ("display_data", "execute_result")
                       and RECORD_MIME in o.get("data", {})]
            errors = [o for o in cell.get("outputs", []) if o.get("output_type") == "error"]
            if len(records) == 1:
                record = records[0]["data"][RECORD_MIME]
                items.append({"exercise": exercise, "module": module, "check": check, "record": record})
                cells.append((cell, exercise, None))
                if exercise_of(record) != exercise:
                    self.log.warning("%s, exercise %s: the grade cell's record names another exercise", who, exercise)
                continue
            if errors:
                why = f"your code raised {errors[0].get('ename', 'an error')}: {str(errors[0].get('evalue', ''))[:100]}"
            elif records:
                why = "the grade cell's output holds more than one record"
            else:
                why = "the grade cell's output is missing or altered"
            self.log.warning("%s, exercise %s: no answer recorded (%s): 0 points", who, exercise, why)
            cells.append((cell, exercise, f"✘ {exercise} not graded: no answer was recorded ({why}); run the "
                                          "notebook from the top and hand it in again"))
        for grade_id in self._missing_grade_cells(nb, resources):
            self.log.warning("%s, grade cell %s: deleted from the hand-in: 0 points", who, grade_id)
            flags.append((grade_id, "the grade cell was deleted from the hand-in"))
        verdicts = iter(_recheck(items))
        for cell, exercise, failed in cells:
            if failed is None:
                verdict = next(verdicts)
                correct, line = verdict["correct"] is True, str(verdict["line"])
                if line.startswith(f"✘ {exercise} not graded"):
                    self.log.warning("%s, exercise %s: %s", who, exercise, line)
                    flags.append((exercise, line))
            else:
                correct, line = False, failed
                flags.append((exercise, line))
            if correct:
                cell.outputs = [new_output("stream", name="stdout", text=line + "\n")]
            else:   # an error whose only line is the hint: nbgrader scores it 0 and shows the line
                cell.outputs = [new_output("error", ename="AssertionError", evalue=line, traceback=[line])]
        if self.report:
            info = resources.get("nbgrader", {})
            update_report(self.report, (info.get("student", "?"), info.get("assignment", "?"), info.get("notebook", "?")),
                          flags)
        return nb, resources

    def _missing_grade_cells(self, nb, resources) -> list[str]:
        """The grade ids of the gradebook's grade cells of this notebook that the hand-in lacks."""
        info = resources.get("nbgrader", {})
        if not all(info.get(k) for k in ("db_url", "notebook", "assignment")):
            return []
        from nbgrader.api import Gradebook

        present = {c.get("metadata", {}).get("nbgrader", {}).get("grade_id") for c in nb.cells}
        with Gradebook(info["db_url"]) as gb:
            expected = [c.name for c in gb.find_notebook(info["notebook"], info["assignment"]).grade_cells]
        return sorted(set(expected) - present)


REPORT_COLUMNS = ("student", "assignment", "notebook", "exercise", "reason")


def update_report(path, submission: tuple[str, str, str], flags) -> None:
    """Replace the rows of ``submission`` (student, assignment, notebook) in the CSV file ``path`` by one row
    per ``(exercise, reason)`` of ``flags`` (the file is made with its header when missing)."""
    rows = []
    if os.path.exists(path):
        with open(path, newline="", encoding="utf-8") as f:
            rows = [r for r in csv.reader(f)][1:]
    rows = [r for r in rows if tuple(r[:3]) != tuple(submission)]
    rows += [[*submission, exercise, reason] for exercise, reason in flags]
    partial = f"{path}.tmp"
    with open(partial, "w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(REPORT_COLUMNS)
        writer.writerows(sorted(rows))
    os.replace(partial, path)


def autograde_preprocessors() -> list:
    """nbgrader's ``Autograde.autograde_preprocessors`` with :class:`RecheckAnswers` right after ``Execute``
    (for the course's ``nbgrader_config.py``).  Needs nbgrader."""
    from nbgrader.converters import Autograde
    from nbgrader.preprocessors import Execute

    default = list(Autograde.class_traits()["autograde_preprocessors"].default())
    if RecheckAnswers in default:
        return default
    at = default.index(Execute) + 1
    return default[:at] + [RecheckAnswers] + default[at:]
