"""The coop lecture figures: the registry entries, their data and drawings."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pytest

from kfcal_helpers.coop import PROBLEM
from kfcal_helpers.coop.figures import COOP_RUNS, FIGURES, CoopCase, figure_data
from kfcal_helpers.registry import LectureFigure


def test_registry_entries():
    assert PROBLEM.figures is FIGURES and PROBLEM.figure_data is figure_data
    assert all(isinstance(f, LectureFigure) and f.name.startswith("coop_") for f in FIGURES)
    assert [f.name for f in FIGURES] == ["coop_paths", "coop_measurements", "coop_ekf_errors", "coop_ukf_errors",
                                         "coop_nees_nis", "coop_nis_comparison"]
    assert len({f.name for f in FIGURES}) == len(FIGURES) and all(f.description for f in FIGURES)


def test_case_is_lazy_and_seeded():
    c = figure_data()
    assert isinstance(c, CoopCase) and c.n_runs == COOP_RUNS and not c.__dict__.keys() & {"log", "results", "mc"}
    again = CoopCase()
    assert np.array_equal(c.log.y, again.log.y, equal_nan=True) and c.log.source == "simulated (seed 5044)"
    with pytest.raises(ValueError, match="n_runs"):
        CoopCase(n_runs=0)
    with pytest.raises(ValueError, match="log_seed"):
        CoopCase(log_seed=-1)


def test_every_figure_draws():
    data = CoopCase(n_runs=3)
    for f in FIGURES:
        fig = f.make(data)
        assert fig.axes and fig.get_size_inches()[0] > 0, f.name
    assert "N = 3 runs" in FIGURES[4].make(data).get_suptitle()
    plt.close("all")


def test_legend_below_leaves_one_legend_under_the_panels():
    from kfcal_helpers.coop.plots import legend_below, plot_states

    t = np.linspace(0, 1, 11)
    x = np.zeros((11, 6))
    fig = plot_states(t, x, truth=x + 1)
    assert sum(ax.get_legend() is not None for ax in fig.axes) + len(fig.legends) == 1
    leg = legend_below(fig)
    assert leg is not None and fig.legends == [leg]
    assert all(ax.get_legend() is None for ax in fig.axes)
    assert [t.get_text() for t in leg.get_texts()] == ["estimate", "truth"]
    single = plot_states(t, x)
    assert legend_below(single) is None and not single.legends
    plt.close("all")
