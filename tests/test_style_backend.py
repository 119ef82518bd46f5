"""The notebooks show the same outputs whatever MPLBACKEND the user has: ``use_style()``, which
every notebook calls first, selects the inline backend in a Jupyter kernel."""

import os

import matplotlib
import nbformat
import pytest
from nbclient import NotebookClient

from kfcal_helpers.style import INLINE_BACKEND, use_style

CELLS = [
    "from kfcal_helpers.style import use_style\nuse_style()\nimport matplotlib.pyplot as plt\nimport numpy as np",
    "fig, ax = plt.subplots(figsize=(3, 2))\n_ = ax.plot(np.arange(5), np.arange(5) ** 2)\nplt.show()",
    "fig, ax = plt.subplots(figsize=(2, 2))\nax.set_title('returned, not shown')\nfig",
    "print(plt.get_backend())",
]


def _outputs(mplbackend, kernel_manager_class):
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(c) for c in CELLS])
    env = {k: v for k, v in os.environ.items() if k != "MPLBACKEND"}
    if mplbackend is not None:
        env["MPLBACKEND"] = mplbackend
    NotebookClient(nb, timeout=120, kernel_name="python3", kernel_manager_class=kernel_manager_class).execute(env=env)
    return [[(o["output_type"], o.get("name"), o.get("text"), dict(o.get("data", {}))) for o in cell.outputs]
            for cell in nb.cells]


@pytest.fixture(scope="module")
def reference(kernel_manager_class):
    return _outputs(None, kernel_manager_class)  # what ipykernel does with MPLBACKEND unset: the inline backend


def test_reference_shows_the_figures(reference):
    assert [len(c) for c in reference] == [0, 1, 2, 1]  # a returned figure: its repr and its image
    assert all("image/png" in c[0][3] for c in reference[1:3])
    assert reference[3][0][2].strip() == INLINE_BACKEND


@pytest.mark.parametrize("mplbackend", ["Agg", "svg"])
def test_same_outputs_whatever_mplbackend(reference, mplbackend, kernel_manager_class):
    assert _outputs(mplbackend, kernel_manager_class) == reference  # the same cells, the same PNG bytes, no warning on stderr


def test_outside_a_kernel_the_backend_is_left_alone():
    before = matplotlib.get_backend()
    use_style()
    assert matplotlib.get_backend() == before != INLINE_BACKEND
