"""Every exported function (and parameter, setup or log class) of the problems ``kfcal_helpers.calibration``,
``kfcal_helpers.coop`` and ``kfcal_helpers.orbit`` and of the shared modules (``consistency``, ``montecarlo``,
``angles``, ``files``, ``output``, ``style``, ``progress``, ``problems``, ``mistakes``, ``demos``, ``figures``,
``unscented``, ``kernels``), called with each argument in turn replaced by ``None``, NaN, an int of 10**400, an
array of a wrong shape and a text ("x"): it raises ``ValueError`` or ``TypeError`` whose one-line message names the
argument (never ``AttributeError``, ``IndexError``, ``OverflowError``...), or, where that value is valid (``None``
for an argument whose default is ``None``, any shape for an elementwise function, NaN for a missing measurement, a
text for a name or a path), returns a result without NaN.
Left out: the exercise checks (``check_*``: a one-line verdict, never an error), ``kfcal_helpers.assignments``, the
command-line entries (``cli``, ``figures.add_parser`` and ``figures.run``: ``tests/test_fuzz_cli.py``), ``process``
(signals and streams of the running process; it imports only the standard library), ``kernels.over_ipc`` (starts a
server), the widget classes of ``demos``, classes that only hold results or registrations (``registry``,
``batching``, the results of each problem), and the inner-loop kernels listed in ``UNCHECKED_KERNELS``."""

import inspect
import io
import re
import warnings

import numpy as np
import pytest

from kfcal_helpers import (angles, calibration, consistency, coop, demos, figures, files, kernels, mistakes, montecarlo,
                           orbit, output, problems, progress, style, unscented)
from kfcal_helpers.calibration import CalibrationParams
from kfcal_helpers.coop import CoopParams, FilterSetup
from kfcal_helpers.orbit import OrbitParams

CP = CalibrationParams(duration=2.0)
KP = CoopParams(duration=1.0)
X0, U0 = KP.x0, KP.u0


def _coop_log():
    return coop.simulate(KP, seed=1).log()


def _calib_run():
    sim = calibration.simulate(CP, 1, 0)
    return calibration.run_filterpy(CP, sim.dz[0])


def _calib_dz():
    return calibration.simulate(CP, 1, 0).dz[0]


OP = OrbitParams(n_steps=4)
OX = OP.x0


def _orbit_sim(n_runs=None):
    return orbit.simulate(OP, n_runs, 1, first=True, integrator="rk4")


def _orbit_setup(filter="ekf"):
    return orbit.FilterSetup(filter, OP)


def _mistake_rows():
    return mistakes.mistake_table(("correct",), n_runs={"calibration": 2, "coop": 2}, params={"calibration": CP, "coop": KP})


def _folder():
    return "figures"  # in the test's temporary working folder


def _figure():
    from matplotlib.figure import Figure

    fig = Figure(figsize=(2.0, 1.5))
    fig.add_subplot().set_title("t")
    return fig


def _controls():
    import ipywidgets

    return {"a": ipywidgets.FloatSlider(value=1.0, description="a"), "b": ipywidgets.Checkbox(description="b")}


def _orbit_experiment():
    return orbit.OrbitExperiment(_orbit_setup(), 2, integrator="rk4")


#: {exported name: a valid call's keyword arguments (built lazily)}; every argument named here is fuzzed
VALID = {
    # calibration
    "simulate@calibration": lambda: dict(params=CP, n_runs=1, seed=0),
    "acceleration": lambda: dict(t=CP.t_imu[:5], params=CP),
    "analytic_truth": lambda: dict(t=CP.t_imu[:5], p0=0.0, v0=0.0, params=CP),
    "integrate_left": lambda: dict(acc=np.ones(5), p_init=0.0, v_init=0.0, dt=0.005),
    "error_state_model": lambda: dict(params=CP),
    "phi_power": lambda: dict(params=CP, k=3),
    "make_kalman_filter": lambda: dict(params=CP, model=calibration.error_state_model(CP)),
    "run_filterpy": lambda: dict(params=CP, dz=_calib_dz(), model=calibration.error_state_model(CP)),
    "between_fixes": lambda: dict(params=CP, model=calibration.error_state_model(CP)),
    "covariance_sequence": lambda: dict(params=CP, missing_fixes=np.zeros(CP.n_gps, bool)),
    "batch_filter": lambda: dict(params=CP, dz=_calib_dz()[None], full_rate=True),
    "run_monte_carlo": lambda: dict(params=CP, n_runs=2, seed=0, alpha=0.05),
    "outage_mask": lambda: dict(params=CP, windows=[(0.5, 1.0)]),
    "parse_outage": lambda: dict(text="1:2", name="text"),
    "batch_conditioning": lambda: dict(params=CP, i=3, dz=_calib_dz()),
    "batch_conditioning_covariance": lambda: dict(params=CP, i=3),
    "prior_covariances_at_fixes": lambda: dict(params=CP),
    "rts_smooth_fixes": lambda: (lambda r: dict(params=CP, x_prior=r.x_prior, x_post=r.x_post, P_prior=r.P_prior,
                                                P_post=r.P_post))(_calib_run()),
    # coop
    "course_log": lambda: dict(params=KP, seed=1),
    "is_course_log": lambda: dict(log=_coop_log(), params=KP),
    "course_log_path": lambda: dict(),
    "load_log": None,  # a path: its own rows in test_fuzz_api.py
    "write_log_csv": None,
    "write_log_mat": None,
    "fit_q_scale": lambda: dict(filter="ekf", y=_coop_log().y, scales=(1.0,), params=KP, alpha=0.05),
    "make_ekf": lambda: dict(setup=FilterSetup.build("ekf", KP)),
    "make_lkf": lambda: dict(setup=FilterSetup.build("lkf", KP)),
    "make_ukf": lambda: dict(setup=FilterSetup.build("ukf", KP)),
    "run": lambda: dict(y=_coop_log().y, setup=FilterSetup.build("ekf", KP)),
    "run_ekf": lambda: dict(y=_coop_log().y, setup=FilterSetup.build("ekf", KP)),
    "run_lkf": lambda: dict(y=_coop_log().y, setup=FilterSetup.build("lkf", KP)),
    "run_ukf": lambda: dict(y=_coop_log().y, setup=FilterSetup.build("ukf", KP)),
    "run_filter": lambda: dict(filter="ekf", y=_coop_log().y, params=KP),
    "tuned_Q": lambda: dict(filter="ekf", params=KP),
    "arc": lambda: dict(x=X0, u=U0, dt=0.1, L=0.5),
    "discretize": lambda: dict(A=coop.jacobian_A(X0, U0), B=coop.jacobian_B(X0, U0), C=coop.jacobian_C(X0), dt=0.1),
    "dynamics": lambda: dict(x=X0, u=U0, L=0.5),
    "jacobian_A": lambda: dict(x=X0, u=U0, L=0.5),
    "jacobian_B": lambda: dict(x=X0, u=U0, L=0.5),
    "jacobian_C": lambda: dict(x=X0),
    "measure": lambda: dict(x=X0),
    "measurement_mean": lambda: dict(sigmas=np.ones((3, 5)), weights=np.full(3, 1 / 3)),
    "measurement_residual": lambda: dict(a=np.ones(5), b=np.zeros(5)),
    "nominal_trajectory": lambda: dict(params=KP, n_samples=5),
    "observability_matrix": lambda: dict(F=np.broadcast_to(np.eye(6), (2, 6, 6)),
                                         H=np.broadcast_to(coop.jacobian_C(X0), (3, 5, 6))),
    "state_add": lambda: dict(x=X0, dx=np.ones(6)),
    "state_mean": lambda: dict(sigmas=np.ones((3, 6)), weights=np.full(3, 1 / 3)),
    "state_residual": lambda: dict(a=np.ones(6), b=np.zeros(6)),
    "step": lambda: dict(x=X0, u=U0, dt=0.1, L=0.5),
    "wrap_angle": lambda: dict(a=np.array([0.5, 4.0])),
    "wrap_measurement": lambda: dict(y=np.ones(5)),
    "wrap_state": lambda: dict(x=X0),
    "run_batch": lambda: dict(y=_coop_log().y[None], setup=FilterSetup.build("ekf", KP)),
    "truth_model_draws": lambda: dict(params=KP, n_runs=2, seed=0, every=1, run=0),
    "truth_model_test": lambda: dict(params=KP, n_runs=2, seed=0, filter="ekf", alpha=0.05, every=1),
    "simulate@coop": lambda: dict(params=KP, n_runs=2, seed=0, every=1),
    "simulate_measurements": lambda: dict(truth=coop.nominal_trajectory(KP), params=KP, seed=0),
    "simulate_truth": lambda: dict(params=KP, seed=0, n_runs=2),
    "format_matrix": lambda: dict(matrix=np.eye(2), digits=3),
    "format_number": lambda: dict(value=1.5, digits=3),
    "format_table": lambda: dict(rows=[[1.0, 2.0]], headers=["a", "b"], digits=3),
    "CalibrationParams": lambda: dict(),
    "CoopParams": lambda: dict(),
    "MeasurementModel": lambda: dict(R=np.eye(5)),
    "CoopLog": lambda: (lambda lg: dict(t=lg.t, y=lg.y, Qtrue=lg.Qtrue, Rtrue=lg.Rtrue, truth=lg.truth, source="x"))(
        _coop_log()),
    # consistency
    "chi2_bounds": lambda: dict(dim=2, n_samples=10, alpha=0.05),
    "chi2_sum_bounds": lambda: dict(dof=np.array([3, 6]), n=np.array([1, 2]), alpha=0.05),
    "step_checks": lambda: dict(nees=np.ones((2, 3)), nis=np.ones((2, 3)), dof=np.full((2, 3), 3), n_states=4,
                                alpha=0.05, extra_entries=0),
    "t_band": lambda: dict(sd=1.0, n=10, level=0.05),
    "normal_band": lambda: dict(var=1.0, n=10, level=0.05),
    "variance_band": lambda: dict(expected=1.0, dof=10, level=0.05),
    "correlation_band": lambda: dict(rho=0.1, n=10, level=0.05),
    "uncentred_correlation_band": lambda: dict(n=10, level=0.05),
    "normalized_squares": lambda: dict(err=np.ones(3), cov=np.eye(3)),
    "nees": lambda: dict(err=np.ones(3), cov=np.eye(3)),
    "nis": lambda: dict(err=np.ones(3), cov=np.eye(3)),
    "inside_fraction": lambda: dict(values=[0.5, 2.0], lower=0.0, upper=1.0),
    "format_checks": lambda: dict(checks=_mistake_rows()["correct"].checks),
    "Check": lambda: dict(name="nees", description="d", statistic=np.ones(3), expected=np.ones(3), lower=np.zeros(3),
                          upper=np.full(3, 2.0), sim_lower=np.zeros(3), sim_upper=np.full(3, 3.0)),
    # montecarlo (estimate and run take an Experiment: their rows are in test_montecarlo_core.py)
    "default_workers": lambda: dict(),
    "chunk_sizes": lambda: dict(chunk=3, n_runs=10),
    "chunk_generators": lambda: dict(chunk=3, n_runs=10, seed=0),
    "estimate": lambda: dict(experiment=_orbit_experiment(), n_runs=2, workers=1, extra_bytes=0.0, runs_name="n_runs",
                             params_name="params", what="one run", scenario_advice="use fewer steps"),
    "run@montecarlo": lambda: dict(experiment=_orbit_experiment(), n_runs=2, seed=0, workers=1, progress=False,
                                   desc="d", extra_bytes=0.0, runs_name="n_runs", params_name="params", what="one run",
                                   scenario_advice="use fewer steps"),
    "FilterSetup@coop": lambda: dict(filter="ukf", params=KP, Q=coop.tuned_Q("ukf", KP), measurement=coop.MeasurementModel(KP.Rtrue),
                                     x0=KP.x0, P0=KP.P0, wrap_innovations=True, subtract_nominal=True),
    # angles
    "angle_slice": lambda: dict(angles=(2, 5)),
    "AngleLayout": lambda: dict(n=6, angles=(2, 5), labels=tuple("abcdef")),
    "StateDescriptor": None,  # coop's name of angles.AngleLayout: the rows above
    # files, output
    "file_kind": lambda: dict(mode=0o100644),
    "named": lambda: dict(path="a_file"),
    "read_regular": lambda: dict(path=__file__, limit=10**6, argname="path", regular_only="give a file",
                                 too_large="too large"),
    "dumps_json": lambda: dict(obj={"a": [1.0, 2]}),
    "require_printable": lambda: dict(name="x", text="abc", stream=io.StringIO()),
    "path_text": lambda: dict(path="a_file", stream=io.StringIO()),
    # style, progress, problems
    "style_params": lambda: dict(target="slides"),
    "use_style": lambda: dict(target="notebook"),
    "line_width": lambda: dict(scale=2.0),
    "marker_size": lambda: dict(scale=2.0),
    "progress_enabled": lambda: dict(),
    "progress@progress": lambda: dict(iterable=[1, 2], total=2, desc="d", enabled=False),
    "progress_bar": lambda: dict(total=2, desc="d", enabled=False),
    "problem": lambda: dict(name="coop"),
    # mistakes
    "all_mistakes": lambda: dict(),
    "mistake_table": lambda: dict(mistakes=("correct",), n_runs={"calibration": 2, "coop": 2, "orbit": 2},
                                  params={"calibration": CP, "coop": KP}, alpha=0.05),
    "table_checks": lambda: dict(rows=_mistake_rows()),
    "format_mistake_table": lambda: dict(rows=_mistake_rows(), checks=None),
    # demos (the widget classes LiveDemo and CachedBackground are not fuzzed)
    "new_figure": lambda: dict(figure=None, figsize=(2.0, 1.5)),
    "figure_png": lambda: dict(fig=_figure(), drawn=False),
    "smallest_text": lambda: dict(fig=_figure()),
    "error_lines": lambda: dict(ax=_figure().add_subplot()),
    "show_errors": lambda: (lambda fig: dict(lines=demos.error_lines(fig.add_subplot()), t=np.arange(3.0),
                                            error=np.zeros(3), sigma2=np.ones(3), skip=0))(_figure()),
    "failure_message": lambda: dict(error=ValueError("x")),
    "describe_controls": lambda: (lambda c: dict(controls=c, values={"a": 2.0}))(_controls()),
    "require_finite_demo": None,  # takes any object: it checks the arrays its class lists in finite_fields
    # figures (the cheapest lecture figure, written to a fresh temporary folder)
    "all_figures": lambda: dict(),
    "save_figures": lambda: dict(figures=figures.all_figures()[:1], directory=_folder(), data=None, svg=False,
                                 argname="directory"),
    "write_figures": lambda: dict(directory=_folder(), svg=False, names=[figures.all_figures()[0].name], data=None),
    # kernels (over_ipc starts a manager server: not fuzzed)
    "socket_folder": lambda: dict(),
    # orbit
    "BatchResult@orbit": None,  # results the package builds (as are FilterResult, MonteCarloResult and Simulation)
    "FilterResult@orbit": None,
    "MonteCarloResult@orbit": None,
    "Simulation@orbit": None,
    "run_batch@orbit": lambda: (lambda sim: dict(y=sim.y, setup=_orbit_setup(), truth=sim.truth,
                                                 keep_estimates=True))(_orbit_sim(2)),
    "OrbitExperiment@orbit": lambda: dict(setup=_orbit_setup(), n_runs=2, alpha=0.05, every=1, integrator="rk4"),
    "truth_model_test@orbit": lambda: dict(params=OP, n_runs=2, seed=0, filter="ekf", alpha=0.05, every=1,
                                           integrator="rk4", workers=1),
    "FilterSetup@orbit": lambda: dict(filter="ukf", params=OP, Q=OP.Qtrue, R=OP.Rtrue, x0=OP.x0, P0=OP.P0,
                                      transition="expm", substeps=2, alpha=1.0, beta=2.0, kappa=0.0),
    "OrbitEKF@orbit": lambda: dict(setup=_orbit_setup()),
    "log_params": lambda: dict(log=_orbit_sim().log(), base=OP),
    "course_log@orbit": lambda: dict(params=OP, seed=1),
    "write_generated_log": None,  # writes a file: its rows in tests/test_orbit_data.py
    "print_summary": lambda: dict(out={"n": 1}, as_json=False, tail=None),
    "figure_size": lambda: dict(),
    "run@orbit": lambda: (lambda sim: dict(y=sim.y, setup=_orbit_setup(), truth=sim.truth))(_orbit_sim()),
    "run_ekf@orbit": lambda: (lambda sim: dict(y=sim.y, setup=_orbit_setup("ekf"), truth=sim.truth))(_orbit_sim()),
    "run_lkf@orbit": lambda: (lambda sim: dict(y=sim.y, setup=_orbit_setup("lkf"), truth=sim.truth))(_orbit_sim()),
    "run_ukf@orbit": lambda: (lambda sim: dict(y=sim.y, setup=_orbit_setup("ukf"), truth=sim.truth))(_orbit_sim()),
    "run_filter@orbit": lambda: (lambda sim: dict(filter="ekf", y=sim.y, params=OP, truth=sim.truth))(_orbit_sim()),
    "discretize@orbit": lambda: dict(A=orbit.jacobian_A(OX, OP), dt=10.0, transition="euler"),
    "dynamics@orbit": lambda: dict(x=OX, params=OP, w=np.zeros(2)),
    "jacobian_A@orbit": lambda: dict(x=OX, params=OP),
    "jacobian_C@orbit": lambda: dict(x=OX, t=0.0, params=OP),
    "measure@orbit": lambda: dict(x=OX, t=0.0, params=OP),
    "nominal_state@orbit": lambda: dict(t=np.array([0.0, 10.0]), params=OP),
    "nominal_trajectory@orbit": lambda: dict(params=OP, n_samples=3),
    "propagate@orbit": lambda: dict(x=OX, params=OP, dt=10.0, substeps=2),
    "station_angles@orbit": lambda: dict(t=np.array([0.0, 10.0]), params=OP),
    "station_states@orbit": lambda: dict(t=np.array([0.0, 10.0]), params=OP),
    "visible@orbit": lambda: dict(x=OX, t=0.0, params=OP),
    "wrap_phi@orbit": lambda: dict(z=np.array([7000.0, 0.1, 4.0])),
    "OrbitParams@orbit": lambda: dict(n_steps=4),
    "OrbitLog@orbit": lambda: (lambda lg: dict(t=lg.t, ydata=lg.ydata, Qtrue=lg.Qtrue, Rtrue=lg.Rtrue, n_stations=12,
                                               truth=lg.truth, source="x"))(_orbit_sim().log()),
    "from_columns@orbit": lambda: dict(ydata=_orbit_sim().log().ydata, n_stations=12),
    "integrate@orbit": lambda: dict(x=OX, params=OP, w=np.zeros(2), dt=10.0),
    "simulate@orbit": lambda: dict(params=OP, n_runs=2, seed=0, every=1, first=False, integrator="rk4"),
    "simulate_measurements@orbit": lambda: dict(truth=_orbit_sim().truth, params=OP, seed=0, first=False),
    "simulate_truth@orbit": lambda: dict(params=OP, seed=0, n_runs=2, x0=OX, process_noise=True, integrator="rk4"),
    "to_columns@orbit": lambda: dict(y=_orbit_sim().y),
}

#: (name, argument) that take any shape (elementwise), where a wrong shape is a valid call
ANY_SHAPE = {("wrap_angle", "a"), ("acceleration", "t"), ("integrate_left", "acc"), ("phi_power", "k"), ("inside_fraction", "values"),
             ("t_band", "sd"), ("normal_band", "var"), ("variance_band", "expected"), ("correlation_band", "rho"),
             ("format_number", "value"), ("arc", "dt"),
             # orbit: times of any shape, broadcast with the states' leading axes
             ("nominal_state", "t"), ("station_angles", "t"), ("station_states", "t"), ("jacobian_C", "t"),
             ("measure", "t"), ("visible", "t")}
#: (name, argument) where NaN is a valid value (a missing measurement)
NAN_OK = {("run", "y"), ("run_ekf", "y"), ("run_lkf", "y"), ("run_ukf", "y"), ("run_filter", "y"),
          ("fit_q_scale", "y"), ("run_batch", "y"), ("format_number", "value"), ("format_matrix", "matrix"),
          ("format_table", "rows"), ("inside_fraction", "values"),
          # elementwise arithmetic: NaN in, NaN out (a missing value stays missing)
          ("wrap_angle", "a"), ("wrap_state", "x"), ("wrap_measurement", "y"), ("state_add", "x"),
          ("state_add", "dx"), ("wrap_phi", "z"), ("state_residual", "a"), ("state_residual", "b"), ("measurement_residual", "a"),
          ("measurement_residual", "b")}

#: functions whose result holds NaN by design (no measurement at step 0)
RETURNS_NAN = {"simulate_measurements"}

#: (name, argument): further values that are valid there (a seed of None draws fresh entropy; ``progress``
#: None means "when the run is long"; an int prints as itself)
ALSO_VALID = {("run_monte_carlo", "seed"): {"None"}, ("truth_model_test", "seed"): {"None"},
              ("truth_model_draws", "seed"): {"None"}, ("chunk_generators", "seed"): {"None"}, ("run_monte_carlo", "progress"): {"None"},
              ("format_number", "value"): {"10**400"}, ("run", "seed"): {"None"},
              # strict JSON: None is null, NaN becomes null, an int has any size
              ("dumps_json", "obj"): {"None", "NaN", "10**400"},
              # an array of any shape is iterable
              ("progress", "iterable"): {"wrong shape"}, ("run", "progress"): {"None"},
              # a limit of any size; no argument name (the messages then start with the path)
              ("read_regular", "limit"): {"10**400"}, ("read_regular", "argname"): {"None"},
              # no figure yet: a new one, of matplotlib's default size when figsize is None
              ("new_figure", "figure"): {"None"}, ("new_figure", "figsize"): {"None"}}

#: (name, argument) that take any text: names, messages, descriptions, paths (a string is a valid value there)
TEXT_OK = {("outage_mask", "name"), ("print_summary", "tail"), ("parse_outage", "name"), ("CoopLog", "source"), ("OrbitLog", "source"),
           ("truth_model_test", "desc"), ("format_number", "value"), ("dumps_json", "obj"), ("named", "path"),
           ("require_printable", "name"), ("require_printable", "text"), ("path_text", "path"),
           ("progress", "iterable"), ("progress", "desc"), ("progress_bar", "desc"), ("run", "desc"),
           *((f, a) for f in ("estimate", "run") for a in ("runs_name", "params_name", "what", "scenario_advice")),
           *(("read_regular", a) for a in ("argname", "regular_only", "too_large")),
           ("save_figures", "directory"), ("save_figures", "argname"), ("write_figures", "directory"),
           ("Check", "name"), ("Check", "description")}

#: (name, argument): the name its messages use instead (a log's arrays carry the course's variable names)
SAID_AS = {("CoopLog", "t"): "tvec", ("CoopLog", "y"): "ydata", ("problem", "name"): "problem"}

BAD_VALUES = {"None": None, "NaN": float("nan"), "10**400": 10**400, "wrong shape": np.zeros((2, 3, 7)), "text": "x"}


#: the problems' parameter and data classes: every field is fuzzed (from the defaults, or a small valid log)
PARAMS_CLASSES = (CalibrationParams, CoopParams, coop.MeasurementModel, coop.CoopLog, orbit.OrbitParams,
                  orbit.OrbitLog, orbit.FilterSetup, orbit.OrbitEKF, orbit.OrbitExperiment, orbit.BatchResult,
                  orbit.FilterResult, orbit.MonteCarloResult, orbit.Simulation, FilterSetup, angles.AngleLayout,
                  consistency.Check)


def _exported():
    out = []
    for module, names in ((calibration, calibration.__all__), (coop, coop.__all__),
                          (consistency, consistency.__all__), (montecarlo, montecarlo.__all__),
                          (orbit, orbit.__all__), (angles, angles.__all__), (files, files.__all__),
                          (output, output.__all__), (style, style.__all__), (progress, progress.__all__),
                          (problems, problems.__all__), (mistakes, mistakes.__all__), (demos, demos.__all__),
                          (unscented, unscented.__all__), (kernels, ("socket_folder",)),
                          (figures, ("all_figures", "save_figures", "write_figures"))):
        for name in names:
            if name in UNCHECKED_KERNELS:
                continue
            obj = getattr(module, name)
            if (inspect.isfunction(obj) and not name.startswith("check_")) or obj in PARAMS_CLASSES:
                out.append((module.__name__.split(".")[-1], name, obj))
    return out


#: the filters' inner-loop numeric kernels, exported for the problems' filters but unchecked on purpose: the UKF
#: calls them per sigma point and step, on arrays its callers have checked
UNCHECKED_KERNELS = {"wrap_components", "weighted_mean", "robust_sqrt", "batch_sigma_points", "unscented_moments",
                     "gain_solve", "mT"}

EXPORTED = _exported()


def test_every_exported_function_has_a_row():
    """A new exported function needs its valid call here (or None, with the test that covers it)."""
    keys = {f"{n}@{m}" if f"{n}@{m}" in VALID else n for m, n, _ in EXPORTED}
    assert sorted(keys - set(VALID)) == []


def _cases():
    for module, name, fn in EXPORTED:
        key = f"{name}@{module}" if f"{name}@{module}" in VALID else name
        if VALID.get(key) is None:
            continue
        params = inspect.signature(fn).parameters
        for arg in params:
            if params[arg].kind in (inspect.Parameter.VAR_KEYWORD, inspect.Parameter.VAR_POSITIONAL):
                continue
            for label in BAD_VALUES:
                yield pytest.param(key, fn, arg, label, id=f"{module}.{name}({arg}={label})")


def _has_nan(value) -> bool:
    if isinstance(value, tuple):
        return any(_has_nan(v) for v in value)
    try:
        arr = np.asarray(value)
    except Exception:
        return False
    return arr.dtype.kind in "fc" and bool(np.isnan(arr).any())


@pytest.mark.parametrize("key, fn, arg, label", list(_cases()))
def test_bad_argument_is_named(key, fn, arg, label, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a text as a path ("x") is a valid folder, written here
    kwargs = VALID[key]()
    default = inspect.signature(fn).parameters[arg].default
    if arg not in kwargs and default is inspect.Parameter.empty:
        pytest.fail(f"VALID[{key!r}] lacks the required argument {arg}")
    kwargs[arg] = BAD_VALUES[label]
    name = key.split("@")[0]
    allowed = ((label == "None" and default is None) or (label == "wrong shape" and (name, arg) in ANY_SHAPE)
               or (label == "NaN" and (name, arg) in NAN_OK) or (label == "text" and (name, arg) in TEXT_OK)
               or label in ALSO_VALID.get((name, arg), ()))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            result = fn(**kwargs)
    except (ValueError, TypeError) as exc:
        message, said = str(exc), SAID_AS.get((name, arg), arg)
        assert re.search(rf"(^|[^\w]){re.escape(said)}([^\w]|$)", message), (type(exc).__name__, message)
        assert "\n" not in message
        return
    assert allowed, f"{name}({arg}={label}) was accepted"
    if label != "NaN" and name not in RETURNS_NAN:
        assert not _has_nan(result), f"{name}({arg}={label}) returned NaN"
