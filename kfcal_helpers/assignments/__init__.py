"""Graded assignments from one source per lesson.

Each lesson ``notebooks/NN_name.ipynb`` and its worked solutions ``notebooks/solutions/NN_name.ipynb``
are rendered from one source notebook, ``notebooks/source/NN_name.md``, which holds the lesson, each
exercise's placeholder and its worked answer, and its points.  A source is a MyST Markdown notebook
(the text format of Jupyter Book and jupytext's ``md:myst``), read by myst-nb's reader
(:func:`read_source`) and kept as text, without outputs, so that instructors can read and diff it and
nobody opens an unexecuted notebook holding the solutions::

    ---
    kernelspec:
      display_name: Python 3 (ipykernel)
      language: python
      name: python3
    ---

    # 01 · The truth model

    ```{code-cell} ipython3
    import numpy as np
    ```

    +++ {"kfcal": {"role": "exercise"}}

    **Exercise 01.1 — ...** (the text, in the lesson and the solutions)

    ```{code-cell} ipython3
    ---
    {"kfcal": {"role": "answer", "exercise": "01.1", "points": 1}}
    ---
    ### BEGIN PLACEHOLDER
    answer_01_1 = ...   # replace ... with your answer
    ### END PLACEHOLDER
    ### BEGIN SOLUTION
    answer_01_1 = 42
    ### END SOLUTION
    check_xxx(answer_01_1)
    ```

A code cell's metadata is the ``---`` block at the top of its fence, a markdown cell's the JSON after
the ``+++`` line before it (written as JSON, which YAML reads exactly: ``"01.1"`` stays a string).  A
cell's ``metadata["kfcal"]`` says where it goes:

=========================================================  ==============================================
``kfcal`` metadata                                         the cell is
=========================================================  ==============================================
absent                                                     a lesson cell (lesson only)
``{"role": "exercise"}``                                   in both (the exercise's text, or another
                                                           cell the two share)
``{"role": "solution"}``                                   in the solutions only (header, setup,
                                                           "**Solution.**" text, extra code, closing line)
``{"role": "answer", "exercise": "03.2", "points": 1}``    an answer cell (code), in both
=========================================================  ==============================================

An answer cell's lines between ``### BEGIN PLACEHOLDER`` and ``### END PLACEHOLDER`` are the lesson's
placeholder; those between ``### BEGIN SOLUTION`` and ``### END SOLUTION`` (nbgrader's markers) the worked
answer; the lines outside both are common.  A placeholder region is followed directly by a solution
region; markers may be indented inside a function; the last line is the check call
``check_xxx(answer_NN_k)``::

    def euler_truth(a, p0, v0, dt):
        \"\"\"Euler truth: arrays p (m) and v (m/s), one entry per sample of a (m/s^2).\"\"\"
        ### BEGIN PLACEHOLDER
        ...   # replace ... with your code and return p, v
        ### END PLACEHOLDER
        ### BEGIN SOLUTION
        p, v = ...
        return p, v
        ### END SOLUTION

    answer_01_3 = euler_truth
    check_euler_truth(answer_01_3)

``python -m kfcal_helpers assignments`` writes the lessons and solutions that differ from what their
source renders (``--execute`` runs those whose code changed), ``--check`` lists them (exit 1), and
``--course DIR`` makes an nbgrader course of every graded lesson with exercises (:mod:`._nbgrader`; needs
``environment-instructors.txt``).  Only the standard library, nbformat and myst-nb (its
reader of the sources) are needed to render; nbclient to execute; nbgrader is imported only for
``--course``.
"""

from ._cli import add_parser
from ._feedback import feedback_template_dirs
from ._nbgrader import (COURSE_ID, INSTRUCTORS_FILE, autograde_preprocessors, check_modules, generate, nbgrader_notebook,
                        write_course)
from ._source import (MARKERS, MAX_CELLS, MAX_METADATA_BYTES, MAX_METADATA_DEPTH, MAX_SOURCE_BYTES, ROLES,
                      SOURCE_SUFFIX, AnswerCell, answer_cells, parse_answer, read_source, render,
                      render_lesson, render_solutions, validate)
from ._sync import (NOTEBOOKS, Target, comparable, differing, equal, execute, merge, render_source,
                    sources, sync, targets, write_notebook)

__all__ = ["ROLES", "MARKERS", "SOURCE_SUFFIX", "MAX_SOURCE_BYTES", "MAX_CELLS", "MAX_METADATA_BYTES", "MAX_METADATA_DEPTH",
           "AnswerCell", "read_source", "parse_answer", "validate",
           "answer_cells", "render", "render_lesson", "render_solutions", "NOTEBOOKS", "Target",
           "sources", "targets", "render_source", "comparable", "equal",
           "differing", "merge", "sync", "execute", "COURSE_ID", "INSTRUCTORS_FILE", "check_modules",
           "nbgrader_notebook", "write_course", "generate", "add_parser", "write_notebook", "autograde_preprocessors",
           "feedback_template_dirs"]
