"""Table-driven fuzz test of the public API: a bad value raises ValueError whose message names the
argument and what is allowed (never TypeError, IndexError, LinAlgError, OverflowError, ZeroDivisionError
or FileExistsError), nonsense is not accepted silently, and no RuntimeWarning escapes (the test
session turns RuntimeWarnings from kfcal_helpers into errors)."""

import numpy as np
import pytest
import scipy.sparse
from scipy.io import savemat

from kfcal_helpers.calibration import (CalibrationParams, covariance_sequence, outage_mask, parse_outage,
                                       run_monte_carlo, simulate)
from kfcal_helpers.calibration.error_model import phi_power
from kfcal_helpers.consistency import chi2_bounds, inside_fraction, nees, nis
from kfcal_helpers.coop import (CoopParams, MeasurementModel, fit_q_scale, load_log, run_filter, truth_model_test,
                                write_log_csv, write_log_mat)
from kfcal_helpers.coop.filters import log_summary
from kfcal_helpers.coop import simulate as coop_simulate
from kfcal_helpers.coop.model import MAX_STEPS, dynamics, jacobian_C, measure, step, wrap_state

import log_files as lf

P = CalibrationParams()
X0 = CoopParams().x0
U0 = CoopParams().u0


def _missing(keep):
    m = np.ones(P.n_gps, bool)
    m[list(keep)] = False
    return m


@pytest.fixture(scope="module")
def small_log():
    return coop_simulate(CoopParams(duration=1.0), seed=1).log()


def _mat(tmp, **change):
    lg = coop_simulate(CoopParams(duration=1.0), seed=1).log()
    raw = {"ydata": lg.y.T, "tvec": lg.t[None, :], "Qtrue": lg.Qtrue, "Rtrue": lg.Rtrue}
    raw.update(change)
    savemat(tmp / "log.mat", raw)
    return tmp / "log.mat"


def _folder(tmp, **files):
    folder = tmp / "log"
    write_log_csv(coop_simulate(CoopParams(duration=1.0), seed=1).log(), folder)
    for name, text in files.items():
        (folder / f"{name}.csv").unlink()
        if text is None:
            (folder / f"{name}.csv").mkdir()
        else:
            (folder / f"{name}.csv").write_text(text)
    return folder


def _file(tmp):
    (tmp / "a_file").write_text("x")
    return tmp / "a_file"


# (id, call(tmp_path, log) -> anything, regex the ValueError message must match)
BAD = [
    # run_monte_carlo
    ("mc seed str", lambda t, lg: run_monte_carlo(P, n_runs=2, seed="x"), r"seed must be None or an integer in \[0, 2\*\*63 - 1\]"),
    ("mc seed huge", lambda t, lg: run_monte_carlo(P, n_runs=2, seed=2**70), r"seed must be"),
    ("mc seed float", lambda t, lg: run_monte_carlo(P, n_runs=2, seed=1.5), r"seed must be"),
    ("mc seed negative", lambda t, lg: run_monte_carlo(P, n_runs=2, seed=-1), r"seed must be"),
    ("mc seed bool", lambda t, lg: run_monte_carlo(P, n_runs=2, seed=True), r"seed must be"),
    ("mc runs 1e30", lambda t, lg: run_monte_carlo(P, n_runs=10**30), r"n_runs: .* about .* h, more than"),
    ("mc runs 1e9", lambda t, lg: run_monte_carlo(P, n_runs=10**9), r"n_runs: 1000000000 realizations .* h"),
    ("mc runs float", lambda t, lg: run_monte_carlo(P, n_runs=1e3), r"n_runs must be an integer"),
    ("mc one fix left", lambda t, lg: run_monte_carlo(P, n_runs=3, missing_fixes=_missing([150])),
     r"missing_fixes must leave at least 2 of the 151 GPS fixes, got 1"),
    ("mc no fix left", lambda t, lg: run_monte_carlo(P, n_runs=3, missing_fixes=np.ones(151, bool)),
     r"missing_fixes must leave at least 2"),
    ("mc float mask", lambda t, lg: run_monte_carlo(P, n_runs=3, missing_fixes=np.zeros(151)), r"missing_fixes"),
    ("mc too big", lambda t, lg: run_monte_carlo(P.replace(gps_rate=200.0), n_runs=2), r"params: .* MB, more than"),
    ("mc huge samples", lambda t, lg: run_monte_carlo(P.replace(imu_rate=1e7), n_runs=2), r"params: .* MB"),
    ("mc params", lambda t, lg: run_monte_carlo("default", 2), r"params must be a CalibrationParams"),
    # CalibrationParams
    ("params replace bogus", lambda t, lg: P.replace(bogus=1), r"changes must name fields of CalibrationParams"),
    ("params omega huge", lambda t, lg: CalibrationParams(omega=1e308), r"omega must be at most pi \* imu_rate"),
    ("params omega 1e160", lambda t, lg: CalibrationParams(omega=1e160), r"omega must be at most"),
    ("params duration huge", lambda t, lg: CalibrationParams(duration=1e300), r"duration \* imu_rate must be at most"),
    ("params rates tiny", lambda t, lg: CalibrationParams(imu_rate=1e300, gps_rate=1e-300, omega=0.2),
     r"imu_rate / gps_rate must be at most 1e\+12 IMU samples per GPS period"),
    ("params omega str", lambda t, lg: CalibrationParams(omega="fast"), r"omega must be a finite real number"),
    # phi_power, covariance_sequence, simulate, outages
    ("phi_power 1.5", lambda t, lg: phi_power(P, 1.5), r"k must be an integer"),
    ("phi_power str", lambda t, lg: phi_power(P, "a"), r"k must be an integer"),
    ("phi_power array", lambda t, lg: phi_power(P, [1, 2.5]), r"k must be an integer"),
    ("phi_power nan", lambda t, lg: phi_power(P, np.nan), r"k must be an integer"),
    ("phi_power bool", lambda t, lg: phi_power(P, True), r"k must be an integer"),
    ("phi_power params", lambda t, lg: phi_power(None, 1), r"params must be a CalibrationParams"),
    ("covariance_sequence float mask", lambda t, lg: covariance_sequence(P, np.zeros(151)),
     r"missing_fixes must be None or a bool array of shape \(151,\)"),
    ("covariance_sequence int mask", lambda t, lg: covariance_sequence(P, np.ones(151, int)), r"missing_fixes"),
    ("simulate 0 runs", lambda t, lg: simulate(P, 0, np.random.default_rng(0)), r"n_runs must be an integer >= 1"),
    ("simulate seed", lambda t, lg: simulate(P, 2, "0"), r"seed must be an integer in \[0, 2\*\*63 - 1\] or a numpy.random.Generator"),
    ("outage_mask pair", lambda t, lg: outage_mask(P, [(1, 2, 3)]), r"windows: each window must be a \(start, end\)"),
    ("outage_mask text", lambda t, lg: outage_mask(P, [("a", "b")]), r"windows: window bounds must be numbers"),
    ("outage_mask outside", lambda t, lg: outage_mask(P, [(-5, 3)]), r"windows: window -5:3 s is outside"),
    ("outage_mask scalar", lambda t, lg: outage_mask(P, 5), r"windows must be a sequence"),
    ("parse_outage", lambda t, lg: parse_outage("1-2"), r"--outage must be START:END"),
    # consistency
    ("nees singular", lambda t, lg: nees(np.ones(3), np.zeros((3, 3))), r"cov must be non-singular"),
    ("nis singular batch", lambda t, lg: nis(np.ones((4, 2)), np.ones((4, 2, 2))), r"cov must be non-singular"),
    ("nees nan", lambda t, lg: nees(np.array([np.nan, 0, 0]), np.eye(3)), r"finite"),
    ("nees shapes", lambda t, lg: nees(np.ones(3), np.eye(2)), r"err must have shape"),
    ("chi2_bounds alpha", lambda t, lg: chi2_bounds(2, 10, alpha=1.5), r"alpha must be a number in \[1e-14, 1\)"),
    ("chi2_bounds dim", lambda t, lg: chi2_bounds(0.5, 10), r"dim must be an integer"),
    ("inside_fraction nan", lambda t, lg: inside_fraction([np.nan], 0, 1), r"values must hold"),
    # coop model
    ("dynamics x shape", lambda t, lg: dynamics(np.zeros(5), U0), r"x must have shape \(\.\.\., 6\)"),
    ("dynamics u shape", lambda t, lg: dynamics(X0, np.zeros(3)), r"u must have shape \(\.\.\., 4\)"),
    ("dynamics x nan", lambda t, lg: dynamics(np.full(6, np.nan), U0), r"x must hold only finite"),
    ("dynamics scalar", lambda t, lg: dynamics(1.0, U0), r"x must have shape"),
    ("wrap_state short", lambda t, lg: wrap_state(np.zeros(5)), r"x must have shape \(\.\.\., 6\)"),
    ("wrap_state 2d", lambda t, lg: wrap_state(np.zeros((2, 7))), r"x must have shape"),
    ("wrap_state scalar", lambda t, lg: wrap_state(3.0), r"x must have shape"),
    ("jacobian_C nan", lambda t, lg: jacobian_C(np.full(6, np.nan)), r"x must hold only finite"),
    ("jacobian_C shape", lambda t, lg: jacobian_C(np.zeros(4)), r"x must have shape"),
    ("jacobian_C range 0", lambda t, lg: jacobian_C(np.zeros(6)), r"range 0"),
    ("step dt", lambda t, lg: step(X0, U0, dt=-1), r"dt must be > 0"),
    ("measure range 0", lambda t, lg: measure(np.zeros(6)), r"range 0"),
    ("coop params dt", lambda t, lg: CoopParams(dt=-1), r"dt must be > 0"),
    ("coop subset rows", lambda t, lg: MeasurementModel(np.eye(5)).subset((0, 5)), r"idx must be a non-empty sequence"),
    ("coop simulate seed", lambda t, lg: coop_simulate(seed=-1), r"seed must be an integer"),
    ("coop mc alpha", lambda t, lg: truth_model_test(CoopParams(duration=1.0), 2, alpha=1.0), r"alpha must be a number in"),
    # coop logs
    ("load_log None", lambda t, lg: load_log(None), r"path must be a folder of CSVs or a \.mat file path, got None"),
    ("load_log number", lambda t, lg: load_log(3.5), r"path must be a folder"),
    ("load_log empty str", lambda t, lg: load_log(""), r"path must be a folder"),
    ("load_log missing", lambda t, lg: load_log(t / "nothing.mat"), r"path: .* does not exist"),
    ("load_log ydata dir", lambda t, lg: load_log(_folder(t, ydata=None)), r"path: .*ydata.csv is a directory"),
    ("load_log empty csv", lambda t, lg: load_log(_folder(t, ydata="")), r"ydata: .* is empty"),
    ("load_log blank csv", lambda t, lg: load_log(_folder(t, tvec="\n\n")), r"tvec: .* is empty"),
    ("load_log text csv", lambda t, lg: load_log(_folder(t, ydata="hello\n")), r"ydata: .* is not a numeric CSV"),
    ("load_log binary csv", lambda t, lg: (lambda f: ((f / "Qtrue.csv").write_bytes(b"\xff\xfe\x00"), load_log(f)))(
        _folder(t)), r"Qtrue: .* not a numeric CSV"),
    ("load_log all nan", lambda t, lg: load_log(_folder(t, ydata=(",".join(["NaN"] * 11) + "\n") * 5)),
     r"ydata holds no measurement"),
    ("mat string", lambda t, lg: load_log(_mat(t, ydata="hello")), r"ydata must be a numeric matrix, got text"),
    ("mat struct", lambda t, lg: load_log(_mat(t, ydata={"a": 1.0})), r"ydata must be a numeric matrix, got a struct"),
    ("mat cell", lambda t, lg: load_log(_mat(t, Qtrue=np.array([np.eye(6), "x"], dtype=object))),
     r"Qtrue must be a numeric matrix"),
    ("mat complex", lambda t, lg: load_log(_mat(t, ydata=np.ones((5, 11)) * 1j)), r"ydata must hold real numbers"),
    ("mat complex tvec", lambda t, lg: load_log(_mat(t, tvec=np.arange(11)[None, :] * (1 + 1j))), r"tvec must hold real"),
    ("mat all nan", lambda t, lg: load_log(_mat(t, ydata=np.full((5, 11), np.nan))), r"ydata holds no measurement"),
    ("mat huge", lambda t, lg: load_log(_mat(t, ydata=np.full((5, 11), 1e300))), r"ydata values must be at most 1e\+06"),
    ("mat inf", lambda t, lg: load_log(_mat(t, ydata=np.full((5, 11), np.inf))), r"ydata"),
    ("mat garbage", lambda t, lg: (lambda f: (f.write_bytes(b"garbage" * 50), load_log(f)))(t / "g.mat"),
     r"path: .* is not a readable MATLAB file"),
    ("write_log_csv into a file", lambda t, lg: write_log_csv(lg, _file(t)), r"folder: .* is an existing file"),
    ("write_log_csv under a file", lambda t, lg: write_log_csv(lg, _file(t) / "sub"), r"folder: cannot write into"),
    ("write_log_csv None", lambda t, lg: write_log_csv(lg, None), r"folder must be a directory path"),
    ("write_log_csv not a log", lambda t, lg: write_log_csv("log", t / "x"), r"log must be a CoopLog"),
    ("write_log_mat missing dir", lambda t, lg: write_log_mat(lg, t / "missing" / "x.mat"),
     r"file: the folder .*missing does not exist"),
    ("write_log_mat a dir", lambda t, lg: write_log_mat(lg, t), r"file: .* is a directory"),
    ("write_log_mat None", lambda t, lg: write_log_mat(lg, None), r"file must be a file path"),
]


# --- course-log reader and public API edges (log-api) ---
def _fit(**kw):
    return fit_q_scale("ekf", coop_simulate(CoopParams(duration=1.0), seed=1).log().y, (0.5, 1.0),
                       CoopParams(duration=1.0), **kw)


def _y(value, rows=5):
    y = np.full((rows, 5), float(value))
    y[0] = np.nan
    return y


def _eye_csv(n, value):
    return "".join(",".join(repr(value) if i == j else "0" for j in range(n)) + "\n" for i in range(n))


def _long(name):
    return "a" * 256 + name


LOG_API_BAD = [
    # special files and bombs as the log
    ("log fifo ydata", lambda t, lg: load_log(lf.folder_with(t, "ydata", lf.fifo)),
     r"path: .*ydata.csv is a FIFO \(named pipe\); a log is read from regular files only"),
    ("log fifo mat", lambda t, lg: load_log(lf.fifo(t / "log.mat")), r"path: .*log.mat is a FIFO"),
    ("log fifo Rtrue", lambda t, lg: load_log(lf.folder_with(t, "Rtrue", lf.fifo)), r"path: .*Rtrue.csv is a FIFO"),
    ("log ydata link to /dev/zero", lambda t, lg: load_log(lf.folder_with(t, "ydata", lambda f: lf.link("/dev/zero", f))),
     r"path: .*ydata.csv \(a link to /dev/zero\) is a character device"),
    ("log mat link to /dev/zero", lambda t, lg: load_log(lf.link("/dev/zero", t / "log.mat")),
     r"path: .*log.mat \(a link to /dev/zero\) is a character device"),
    ("log Qtrue link to /dev/null", lambda t, lg: load_log(lf.folder_with(t, "Qtrue", lambda f: lf.link("/dev/null", f))),
     r"path: .*Qtrue.csv \(a link to /dev/null\) is a character device"),
    ("log link to a link to a FIFO", lambda t, lg: load_log(lf.folder_with(
        t, "tvec", lambda f: lf.link(lf.link(lf.fifo(t / "pipe"), t / "hop"), f))), r"path: .*tvec.csv .* is a FIFO"),
    ("log socket ydata", lambda t, lg: load_log(lf.folder_with(t, "ydata", lf.unix_socket)),
     r"path: .*ydata.csv is a socket"),
    ("log mat bomb", lambda t, lg: load_log(lf.mat_bomb(t / "bomb.mat")),
     r"ydata: 20000000 steps, more than the \d+ allowed: .* about 41750 MB .* 500 MB memory limit"),
    ("log mat too long", lambda t, lg: load_log(lf.long_mat(t)), r"ydata: 168270 steps, more than the 168269 allowed"),
    ("log mat long tvec", lambda t, lg: load_log(_mat(t, tvec=np.zeros((1, 10**6)))), r"tvec: 1000000 steps"),
    ("log mat sparse Qtrue", lambda t, lg: load_log(_mat(t, Qtrue=scipy.sparse.eye(6, format="csc"))),
     r"Qtrue must be a numeric matrix, got a sparse matrix"),
    ("log csv too long", lambda t, lg: load_log(lf.long_log(t)), r"ydata: 168270 steps, more than the 168269 allowed"),
    ("log csv sparse 100 MB", lambda t, lg: load_log(lf.folder_with(t, "ydata", lf.sparse_file)),
     r"ydata: .*ydata.csv is larger than the 27.0 MB a log of at most 168269 steps needs"),
    ("log csv 1 MB Qtrue", lambda t, lg: load_log(lf.folder_with(t, "Qtrue", lambda f: f.write_text("1.0\n" * 300000))),
     r"Qtrue: .*Qtrue.csv is larger than the 0.1 MB"),
    ("log sparse mat", lambda t, lg: load_log(lf.sparse_file(t / "log.mat", 200_000_000)), r"path: .*log.mat is larger than"),
    ("log csv 8.9 million short lines", lambda t, lg: load_log(lf.folder_with(t, "ydata", lf.short_lines)),
     r"ydata: .*ydata.csv has 8900000 lines, more than a 5 x K matrix can have \(5 rows\)"),
    ("log csv tvec of 1.5 million lines", lambda t, lg: load_log(lf.folder_with(t, "tvec", lambda f: lf.short_lines(f, 1_500_000))),
     r"tvec: .*tvec.csv has 1500000 lines, more than a 1 x K vector can have"),
    ("log csv one line of 13 million values", lambda t, lg: load_log(lf.folder_with(t, "ydata", lf.one_long_line)),
     r"ydata: 13000000 steps, more than the 168269 allowed"),
    ("log csv Qtrue of 7 columns", lambda t, lg: load_log(_folder(t, Qtrue="1,0,0,0,0,0,0\n" * 6)),
     r"Qtrue: .*Qtrue.csv has a line of 7 values; a 6 x 6 matrix has 6"),
    # arguments and messages (inputs): a NaN time, absurd noise covariances, a thinning that keeps nothing
    ("log NaN in tvec", lambda t, lg: load_log(lf.retimed_log(t, np.r_[np.nan, 0.1 * np.arange(1, 11)])),
     r"tvec must hold only finite times, got nan at column 0"),
    ("log inf in tvec", lambda t, lg: load_log(lf.retimed_log(t, np.r_[0.1 * np.arange(10), np.inf])),
     r"tvec must hold only finite times, got inf at column 10"),
    ("log Qtrue 1e300 I", lambda t, lg: load_log(_folder(t, Qtrue=_eye_csv(6, 1e300))),
     r"Qtrue variances must be at most 1e\+12 \(a standard deviation of 1e\+06\), got 1e\+300"),
    ("log Rtrue 1e20 I", lambda t, lg: load_log(_folder(t, Rtrue=_eye_csv(5, 1e20))), r"Rtrue variances must be at most 1e\+12"),
    ("coop params Qtrue 1e300 I", lambda t, lg: CoopParams(Qtrue=1e300 * np.eye(6)), r"Qtrue variances must be at most"),
    ("log every keeps nothing", lambda t, lg: lg.every(100000), r"m must be at most 10 \(the log has 11 steps\), got 100000"),
    ("fit_q_scale no measurement", lambda t, lg: fit_q_scale("ekf", np.full((11, 5), np.nan), (1.0,),
                                                            CoopParams(duration=1.0)),
     r"y holds no measurement \(every row is NaN\)"),
    ("log csv semicolons", lambda t, lg: load_log(lf.spreadsheet_log(t, bom=False, newline="\n", sep=";")),
     r"not a numeric CSV \(.*\); it looks semicolon-separated: save it comma-separated"),
    ("log csv semicolons with a BOM", lambda t, lg: load_log(lf.spreadsheet_log(t, sep=";")),
     r"it looks semicolon-separated"),
    ("coop params dt 5e-324", lambda t, lg: CoopParams(dt=5e-324), r"duration / dt must be at most 1e\+09 steps, got 100 s / 4.94066e-324 s = inf steps"),
    ("coop params duration 1e300", lambda t, lg: CoopParams(duration=1e300), r"duration / dt must be at most 1e\+09 steps, got 1e\+300 s"),
    ("run_filter too many rows", lambda t, lg: run_filter("ekf", _y(1.0, MAX_STEPS + 1)), r"y: 168270 steps"),
    # timestamps
    ("log epoch step below the float spacing", lambda t, lg: load_log(lf.retimed_log(t, lf.EPOCH + 1e-4 * np.arange(11))),
     r"tvec: the step 0.0001 s is too small for times near 1.7e\+09 s \(their float spacing is 2.38e-07 s\)"),
    ("log epoch jitter", lambda t, lg: load_log(lf.retimed_log(t, lf.EPOCH + 0.1 * np.arange(11) + np.r_[0, 0, 0.01, [0] * 8])),
     r"tvec must be increasing with a constant step \(a step differs from the mean step 0.1 s by 0.01 s\)"),
    # significance levels
    ("mc alpha 1e-300", lambda t, lg: run_monte_carlo(P, 2, alpha=1e-300), r"alpha must be a number in \[1e-06, 1\)"),
    ("mc alpha 1e-12", lambda t, lg: run_monte_carlo(P, 2, alpha=1e-12), r"alpha must be a number in \[1e-06, 1\)"),
    ("coop mc alpha 1e-300", lambda t, lg: truth_model_test(CoopParams(duration=1.0), 2, alpha=1e-300),
     r"alpha must be a number in \[1e-06, 1\)"),
    ("coop mc alpha 5e-324", lambda t, lg: truth_model_test(CoopParams(duration=1.0), 2, alpha=5e-324),
     r"alpha must be a number in \[1e-06"),
    ("chi2_bounds alpha 1e-300", lambda t, lg: chi2_bounds(2, 10, alpha=1e-300), r"alpha must be a number in \[1e-14, 1\)"),
    ("log_summary alpha 1e-300", lambda t, lg: log_summary(run_filter("ekf", lg.y), alpha=1e-300), r"alpha must be a number in"),
    ("fit_q_scale alpha 1e-300", lambda t, lg: _fit(alpha=1e-300), r"alpha must be a number in"),
    # measurements that overflow the filter
    ("run_filter y 1e300", lambda t, lg: run_filter("ekf", _y(1e300)), r"y values must be at most 1e\+06 in magnitude"),
    ("run_filter y -1e7 lkf", lambda t, lg: run_filter("lkf", _y(-1e7)), r"y values must be at most 1e\+06"),
    ("run_filter y 1e200 ukf", lambda t, lg: run_filter("ukf", _y(1e200)), r"y values must be at most 1e\+06"),
    ("fit_q_scale y 1e300", lambda t, lg: fit_q_scale("ekf", _y(1e300), (1.0,)), r"y values must be at most"),
    # unknown keywords
    ("run_filter unknown keyword", lambda t, lg: run_filter("ekf", lg.y, bogus=1),
     r"bogus is not a filter setting; the settings are R, measurements, Q, x0, P0, points, wrap_innovations"),
    ("run_filter misspelt keyword", lambda t, lg: run_filter("lkf", lg.y, q=np.eye(6)), r"q is not a filter setting"),
    ("truth_model_test unknown keyword", lambda t, lg: truth_model_test(CoopParams(duration=1.0), 2, Qscale=2.0),
     r"Qscale is not a filter setting"),
    ("fit_q_scale unknown keyword", lambda t, lg: _fit(every=2), r"every is not a filter setting"),
    # names too long for the file system
    ("write_log_csv 256-char name", lambda t, lg: write_log_csv(lg, t / _long("")), r"folder: cannot write into"),
    ("write_log_csv under a 256-char name", lambda t, lg: write_log_csv(lg, t / _long("") / "x"), r"folder: cannot write"),
    ("write_log_mat 256-char name", lambda t, lg: write_log_mat(lg, t / _long(".mat")), r"file: cannot write"),
    ("load_log 256-char name", lambda t, lg: load_log(t / _long(".mat")), r"path: cannot read"),
]
BAD += LOG_API_BAD


@pytest.mark.parametrize("times", [lf.EPOCH + 0.1 * np.arange(21), -lf.EPOCH + 0.1 * np.arange(21),
                                   1e3 * lf.EPOCH + 100.1 * np.arange(21), 6e5 + 0.1 * np.arange(21)],
                         ids=["epoch s", "negative epoch s", "epoch ms", "GPS seconds of week"])
def test_log_with_rounded_timestamps_is_accepted(times, tmp_path):
    """Times far from 0 carry float rounding in their steps: a constant step is judged against the float
    spacing of the largest |t|; dt is the mean step, and the filters run on the log."""
    lg = load_log(lf.retimed_log(tmp_path, times))
    step = (times[-1] - times[0]) / (times.size - 1)
    assert lg.dt == pytest.approx(step, rel=1e-12)
    assert np.array_equal(lg.t, times)
    params = lg.params()
    assert params.n_samples == times.size and params.dt == pytest.approx(step, rel=1e-12)
    assert np.isfinite(run_filter("ekf", lg.y, params).x).all()


@pytest.mark.parametrize("bom, newline", [(True, "\r\n"), (True, "\n"), (False, "\r\n"), (False, "\r")],
                         ids=["BOM CRLF", "BOM LF", "CRLF", "CR"])
def test_log_saved_by_a_spreadsheet_is_read(bom, newline, tmp_path):
    """A log re-saved by a spreadsheet (a UTF-8 byte-order mark, CRLF or CR line ends) reads as the original."""
    want = load_log(lf.log_folder(tmp_path / "plain"))
    got = load_log(lf.spreadsheet_log(tmp_path / "sheet", bom=bom, newline=newline))
    assert (tmp_path / "sheet" / "log" / "ydata.csv").read_bytes().startswith(b"\xef\xbb\xbf") == bom
    for name in ("t", "y", "Qtrue", "Rtrue"):
        assert np.array_equal(getattr(got, name), getattr(want, name), equal_nan=True), name


def test_mat_bomb_is_refused_unread(tmp_path):
    """The 780 kB compressed .mat that expands to 5 x 2e7 doubles (800 MB) is refused from its header:
    the reader's peak allocation stays under 10 MB (tracemalloc; numpy reports its buffers)."""
    import tracemalloc

    path = lf.mat_bomb(tmp_path / "bomb.mat")
    assert path.stat().st_size < 1_000_000
    tracemalloc.start()
    try:
        with pytest.raises(ValueError, match=r"ydata: 20000000 steps"):
            load_log(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 10e6, f"peak {peak / 1e6:.0f} MB"


def test_log_at_the_step_limit_is_accepted(tmp_path):
    """MAX_STEPS steps load (one more is refused, in the table above); the estimate at the limit is
    within the 500 MB memory limit."""
    from kfcal_helpers.coop.model import MAX_STEPS, run_bytes
    from kfcal_helpers.montecarlo import MEMORY_LIMIT

    assert run_bytes(MAX_STEPS) <= MEMORY_LIMIT < run_bytes(MAX_STEPS + 1)
    assert load_log(lf.long_log(tmp_path, MAX_STEPS)).n_samples == MAX_STEPS


def test_significance_limits_keep_every_band_finite():
    """The smallest accepted alpha, Bonferroni-split over more entries than fit in memory, still gives
    finite chi-square and t bands; the smallest band level gives finite quantiles."""
    from scipy import stats

    from kfcal_helpers.validation import MIN_ALPHA, MIN_BAND_ALPHA, require_significance

    assert require_significance("alpha", MIN_ALPHA) == MIN_ALPHA
    split = MIN_ALPHA / (500e6 / 8)  # more entries than an accepted run keeps
    assert split >= MIN_BAND_ALPHA
    for dim, n in ((1, 2), (6, 10**4), (5, 10**6)):
        assert np.all(np.isfinite(chi2_bounds(dim, n, MIN_BAND_ALPHA)))
        assert np.all(np.isfinite(chi2_bounds(dim, n, split)))
    assert np.isfinite(stats.t.ppf(1 - MIN_BAND_ALPHA / 2, 1))
    mc = run_monte_carlo(P, 3, seed=1, alpha=MIN_ALPHA)
    for check in mc.checks().values():
        assert np.all(np.isfinite(check.sim_upper)) and np.all(np.isfinite(check.upper)), check.name


@pytest.mark.parametrize("call, match", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_values_raise_value_error_naming_the_argument(call, match, tmp_path, small_log):
    with pytest.raises(ValueError, match=match) as info:
        call(tmp_path, small_log)
    assert type(info.value) is ValueError
    assert "\n" not in str(info.value)  # the CLI shows it as one line


def test_nothing_written_when_refused(tmp_path, small_log):
    with pytest.raises(ValueError):
        write_log_mat(small_log, tmp_path / "missing" / "x.mat")
    assert list(tmp_path.iterdir()) == []


def test_valid_edges_still_accepted(tmp_path, small_log):
    """The checks refuse nonsense only: integral floats, bool masks, batches and the limits pass."""
    assert np.allclose(phi_power(P, 40.0), phi_power(P, 40))
    assert phi_power(P, np.arange(3)).shape == (3, 3, 3)
    assert wrap_state(np.zeros((2, 6))).shape == (2, 6)
    assert dynamics(np.zeros((3, 6)), U0).shape == (3, 6)
    assert jacobian_C(X0).shape == (5, 6)
    assert float(nees(np.ones(3), np.eye(3))) == pytest.approx(3.0)
    assert CalibrationParams(omega=np.pi * 200.0).omega == pytest.approx(628.3185307)
    assert P.replace(omega=0.5).omega == 0.5
    mc = run_monte_carlo(P, n_runs=3, seed=np.int64(2), missing_fixes=_missing([149, 150]))  # 2 fixes, 3 runs
    assert np.all(np.isfinite(mc.nees)) and mc.checks()["residual_independence"].statistic.size == 4
    assert run_monte_carlo(P, n_runs=2, seed=None).n_runs == 2
    f = write_log_mat(small_log, tmp_path / "ok.mat")
    assert np.array_equal(load_log(f).y, small_log.y, equal_nan=True)
    assert write_log_csv(small_log, tmp_path / "new" / "deeper") == tmp_path / "new" / "deeper"
