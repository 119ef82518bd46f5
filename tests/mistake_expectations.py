"""What notebook 14 says about each mistake, check by check: one table, used by the tests of each
problem's rows (tests/test_<problem>_mistakes.py) and of the joined table (tests/test_mistakes.py)."""

CHECK_NAMES = ("mean_error", "covariance", "orthogonality", "residual_independence", "residual_variance", "nees", "nis")
ALL_BUT_MEAN = set(CHECK_NAMES) - {"mean_error"}
COOP_ALL = {"mean_error", "nees", "nis"}

CALIBRATION_CAUGHT_BY = {
    "correct": set(),
    "no_propagation": ALL_BUT_MEAN,
    "phi02_sign": set(),  # at the table's 1000 realizations; the orthogonality check catches it at 5000
    "m0_swapped": ALL_BUT_MEAN,
    "w_is_gps_velocity_var": {"covariance", "nees"},
    "gps_interval_0_02": ALL_BUT_MEAN,
    "v0_zero": {"mean_error", "residual_independence", "residual_variance", "nees", "nis"},
}

COOP_CAUGHT_BY = {
    "ekf_correct": set(),
    "ekf_no_wrap": COOP_ALL,
    "ekf_omega_identity": set(),
    "lkf_correct": set(),
    "lkf_no_nominal": COOP_ALL,
}

ORBIT_ALL = {"mean_error", "nees", "nis"}

ORBIT_CAUGHT_BY = {
    "orbit_ekf_correct": set(),
    "orbit_nis_fixed_dof": {"nis"},
    "orbit_no_rotation": ORBIT_ALL,
    "orbit_inertial_rhodot": set(),  # 0.46 km/s at most, under rhodot's 1 km/s noise: no check sees it
    "orbit_no_wrap": {"nis"},
    "orbit_visibility": set(),  # the data lose passes; what remains is consistent
    "orbit_omega_gamma": {"nees", "nis"},
}
