"""The calibration lecture figures (``kfcal_helpers.calibration.figures``): every entry drawn as a
slide PNG (1280x720) by the shared ``save_figures``, the registry entry of the problem, the seeded
realization with outages; and ``calibrate --figures`` / ``--json`` (the outages drawn and listed)."""

import json
import struct

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pytest

from kfcal_helpers.calibration import PROBLEM, CalibrationParams, run_monte_carlo
from kfcal_helpers.calibration import cli as calibration_cli
from kfcal_helpers.calibration.figures import (FIGURES, OUTAGE_WINDOWS, CalibrationCase,
                                               CalibrationFigureData, calibration_realization, figure_data)
from kfcal_helpers.cli import main
from kfcal_helpers.figures import save_figures
from kfcal_helpers.registry import LectureFigure
from kfcal_helpers.style import SLIDE_DPI, SLIDE_SIZE

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
SLIDE_PX = (round(SLIDE_SIZE[0] * SLIDE_DPI), round(SLIDE_SIZE[1] * SLIDE_DPI))


def png_size(path):
    """(width, height) in pixels of a PNG, read from its header; asserts it is a complete PNG."""
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE and data[12:16] == b"IHDR", f"{path.name} is not a PNG"
    assert data[-8:-4] == b"IEND", f"{path.name} is truncated"
    return struct.unpack(">II", data[16:24])


def test_registry_entries():
    assert PROBLEM.figures is FIGURES and PROBLEM.figure_data is figure_data
    assert all(isinstance(f, LectureFigure) for f in FIGURES)
    names = [f.name for f in FIGURES]
    assert len(set(names)) == len(names) >= 9 and all(n.startswith("calib_") for n in names)
    assert all(f.description.startswith("calibration") for f in FIGURES)
    data = figure_data()
    assert isinstance(data, CalibrationFigureData) and "mc" not in vars(data.calibration)  # nothing computed yet


def test_every_figure_written_as_slide_png(tmp_path):
    before = {k: matplotlib.rcParams[k] for k in ("font.size", "figure.figsize", "lines.linewidth", "savefig.bbox")}
    open_figures = plt.get_fignums()
    data = CalibrationFigureData(CalibrationCase(n_runs=200))
    written = save_figures(FIGURES, tmp_path / "slides", data)
    assert written == [tmp_path / "slides" / f"{f.name}.png" for f in FIGURES]
    for path in written:
        assert path.stat().st_size > 10_000, path.name  # a drawn figure, not an empty canvas
        assert png_size(path) == SLIDE_PX == (1280, 720), path.name
    image = plt.imread(tmp_path / "slides" / "calib_errors.png")
    assert image.shape[:2] == (720, 1280) and image.std() > 0.01
    assert plt.get_fignums() == open_figures
    assert {k: matplotlib.rcParams[k] for k in before} == before
    # the outage scenario: the calibration's parameters and seed with the lecture's windows
    assert data.outage.spans == [tuple(w) for w in OUTAGE_WINDOWS] and data.outage.seed == data.calibration.seed
    assert data.calibration.mc.n_runs == 200 and data.calibration.mc.filter == "kf" and data.calibration.mc.engine == "batch"


@pytest.mark.parametrize("kwargs, name", [({"params": {}}, "params"), ({"missing_fixes": np.zeros(3, bool)},
                                          "missing_fixes"), ({"truth": "exact"}, "truth"), ({"seed": -1}, "seed"),
                                          ({"n_runs": 1}, "n_runs"), ({"filter": "ukf"}, "filter"),
                                          ({"engine": "ukf"}, "engine")])
def test_case_validates(kwargs, name):
    with pytest.raises(ValueError, match=name):
        CalibrationCase(**kwargs)


# ---------------------------------------------------------------------------
# calibrate --figures with --outage, and --json's "outages"
PARAMS = CalibrationParams()
# fixes every 0.2 s; the window 5:10 s removes the fixes at 5.0, 5.2, ..., 9.8 s (indices 25..49)
GAP = np.arange(25, 50)


def test_realization_has_the_outage():
    missing = np.zeros(PARAMS.n_gps, bool)
    missing[GAP] = True
    sim, fr = calibration_realization(PARAMS, missing, seed=4)
    sim0, fr0 = calibration_realization(PARAMS, None, seed=4)
    assert np.isnan(sim.z[0, GAP]).all() and not np.isnan(np.delete(sim.z[0], GAP, axis=0)).any()
    assert not np.isnan(sim0.z).any()
    assert np.all(fr.K[GAP] == 0) and np.all(fr0.K[GAP] != 0)  # no update inside the gap
    j0, j1 = GAP[0] * PARAMS.steps_per_fix, (GAP[-1] + 1) * PARAMS.steps_per_fix
    assert np.all(np.diff(fr.P[j0:j1, 0, 0]) > 0)  # position variance grows through the gap
    # the same draws: identical before the gap, different from its first missing fix on
    np.testing.assert_array_equal(fr.x[:j0], fr0.x[:j0])
    assert np.abs(fr.x[j0 + 1:] - fr0.x[j0 + 1:]).max() > 0


def test_calibrate_figures_draw_the_outage(tmp_path, capsys, monkeypatch):
    cases = []
    original = calibration_cli.figure_case

    def recording_figure_case(mc, seed=0):
        cases.append(original(mc, seed))
        return cases[-1]

    monkeypatch.setattr(calibration_cli, "figure_case", recording_figure_case)
    assert main(["calibrate", "--runs", "20", "--seed", "4", "--outage", "5:10", "--figures", str(tmp_path),
                 "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["outages"] == [[5.0, 10.0]] and d["filter"] == "kf" and d["engine"] == "batch"
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "calib_checks.png", "calib_errors.png", "calib_sigma_sawtooth.png"]
    assert png_size(tmp_path / "calib_errors.png") == SLIDE_PX
    (case,) = cases
    sim, fr = case.realization  # the realization the figures drew
    assert np.flatnonzero(np.isnan(sim.z[0, :, 0])).tolist() == GAP.tolist()
    assert np.all(fr.K[GAP] == 0)
    assert case.spans == [(5.0, 10.0)]  # shaded in the figures
    # the same realization as the function builds directly, with the same seed and gap
    np.testing.assert_array_equal(fr.x, calibration_realization(PARAMS, case.missing, seed=4)[1].x)


def test_calibrate_json_lists_the_outages(capsys):
    assert main(["calibrate", "--runs", "5", "--outage", "14:29", "--outage", "2.5:4", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["outages"] == [[14.0, 29.0], [2.5, 4.0]]
    assert main(["calibrate", "--runs", "5", "--engine", "filterpy", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["outages"] == [] and d["filter"] == "kf" and d["engine"] == "filterpy"
    mc = run_monte_carlo(PARAMS, 2, 0)
    assert calibration_cli.result_to_dict(mc)["outages"] == []


def test_calibrate_figures_into_a_file_fails_before_the_monte_carlo(tmp_path, capsys):
    (tmp_path / "f").write_text("x")
    assert main(["calibrate", "--runs", "100000000", "--figures", str(tmp_path / "f")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--figures" in err
