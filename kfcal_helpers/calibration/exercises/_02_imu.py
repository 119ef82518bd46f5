"""Exercise checks of notebook 02 (the IMU model): 02.1-02.5."""

from __future__ import annotations



import numpy as np
from scipy import stats

from ...exercises._core import (BAND_NAMES, Exercise, Feedback, as_array, chi2_average_bounds)
from ...validation import (require_finite, require_int, require_positive,
                          require_probability)
from ..simulation import integrate_left
from ._shared import call_once, close, numeric, as_pair


_IMU_DRIFT = Exercise(
    "02.1",
    praise="the bias drift is linear in velocity and quadratic in position",
    hint="integrate the bias once for δv and twice for δp, starting from the initial errors (bias only, no noise), "
         "and check each term and its sign",
    hints={
        "sign": "check the sign of the bias terms: a positive bias makes the IMU over-read, so p_c and v_c run "
                "ahead of the truth",
        "no_half": "the bias enters the position like a constant acceleration: t²/2, not t²",
        "no_dv0_t": "the initial velocity error also moves the position: it adds δv0·t to δp",
        "swapped": "give [δp, δv] in this order: position first",
        "no_initial": "the initial errors δp0 and δv0 are still in δp and δv: the bias only adds to them",
    },
    components=("δp", "δv"),
)


def check_imu_drift(answer, *, b: float = 0.05, dp0: float = 2.0, dv0: float = -0.3, t: float = 20.0) -> Feedback:
    """Exercise 02.1: bias-only dead-reckoning drift ``[δp(t), δv(t)]`` (m, m/s), shape (2,),
    for bias ``b`` (m/s²), initial errors ``dp0`` (m), ``dv0`` (m/s), after ``t`` seconds."""
    b, dp0, dv0 = (require_finite(n, x) for n, x in (("b", b), ("dp0", dp0), ("dv0", dv0)))
    t = require_positive("t", t)
    dv = dv0 - b * t
    dp = dp0 + dv0 * t - b * t**2 / 2
    wrong = [("sign", [dp0 + dv0 * t + b * t**2 / 2, dv0 + b * t]), ("no_half", [dp0 + dv0 * t - b * t**2, dv]),
             ("no_dv0_t", [dp0 - b * t**2 / 2, dv]), ("swapped", [dv, dp]), ("no_initial", [-b * t**2 / 2, -b * t])]
    return numeric(_IMU_DRIFT, answer, [dp, dv], wrong)


_IMU_RANDOM_WALK = Exercise(
    "02.2",
    praise="the random walk grows like √t in velocity and t^(3/2) in position",
    hint="build both variances from the per-sample variance W, the exercise's Δt and the number of noise samples "
         "before t, as in the notebook's derivation; then take square roots",
    hints={
        "variance": "these are variances: the exercise asks for standard deviations",
        "rate": "use the exercise's IMU rate (100 Hz): Δt changes, W is per sample",
        "no_dt": "W is a variance per sample: the velocity random walk after n steps has variance n W Δt²",
        "linear": "independent noise samples add in variance, not in amplitude: a random walk grows like √t",
        "swapped": "give [σ_p, σ_v] in this order: position first",
        "no_third": "check the constant in the position variance: Σ(m + 1/2)² over m < j is about j³/3",
        "steps": "check the step count: the noise samples before t number n = t/Δt (samples 0 … n-1), not one "
                 "more or one less",
    },
    components=("σ_p", "σ_v"),
)


def check_imu_random_walk(answer, *, imu_rate: float = 100.0, W: float = 4e-4, t: float = 20.0) -> Feedback:
    """Exercise 02.2: random-walk standard deviations ``[σ_p(t), σ_v(t)]`` (m, m/s), shape (2,),
    of the dead reckoning for IMU noise variance ``W`` ((m/s²)² per sample) at ``imu_rate`` (Hz)
    after ``t`` seconds. Accepts the exact σ_p or σ_p ≈ √(WΔt t³/3) (rtol 1e-4)."""
    imu_rate, W, t = (require_positive(n, x) for n, x in (("imu_rate", imu_rate), ("W", W), ("t", t)))

    def exact(dt, extra=0):
        j = t / dt + extra
        return np.array([np.sqrt(W * dt**4 * (j**3 / 3 - j / 12)), np.sqrt(W * dt**2 * j)])

    dt = 1.0 / imu_rate
    right = exact(dt)
    wrong = [("variance", right**2), ("rate", exact(0.005)), ("no_dt", [np.sqrt(W * t**3 / 3), np.sqrt(W * t)]),
             ("linear", [np.sqrt(W) * t**2 / 2, np.sqrt(W) * t]), ("swapped", right[::-1]),
             ("no_third", [np.sqrt(W * dt * t**3), right[1]]), ("steps", exact(dt, -1)), ("steps", exact(dt, 1))]
    return numeric(_IMU_RANDOM_WALK, answer, right, wrong, rtol=1e-4)


_IMU_STD_BAND = Exercise(
    "02.3",
    praise="the sample std of n samples has n - 1 degrees of freedom",
    hint="(n-1)s²/σ² ~ χ²_{n-1}: take the 2.5 % and 97.5 % quantiles and solve for s",
    hints={
        "n_dof": "the sample std subtracts the estimated mean (ddof=1): that uses up one degree of freedom",
        "variance": "this is the band of the sample variance: the exercise asks for the standard deviation",
        "one_sided": "a two-sided 95 % band puts α/2 = 2.5 % in each tail, not 5 %",
        "no_divide": "(n-1)s²/σ² is χ²: divide the quantiles by the degrees of freedom before taking the root",
        "normal": "close, but that is the normal approximation σ(1 ± z/√(2(n-1))): use the exact chi-square "
                  "quantiles",
    },
    components=BAND_NAMES,
)


def check_imu_std_band(answer, *, sigma: float = 0.02, n: int = 50, alpha: float = 0.05) -> Feedback:
    """Exercise 02.3: the two-sided ``1 - alpha`` band ``[lower, upper]`` (m/s²), shape (2,), of the
    sample standard deviation (ddof=1) of ``n`` i.i.d. N(0, sigma²) samples."""
    sigma = require_positive("sigma", sigma)
    n = require_int("n", n, minimum=2)
    alpha = require_probability("alpha", alpha)
    right = sigma * np.sqrt(chi2_average_bounds(1, n - 1, alpha))
    z = stats.norm.ppf(1 - alpha / 2)
    wrong = [("n_dof", sigma * np.sqrt(chi2_average_bounds(1, n, alpha))),
             ("variance", sigma**2 * chi2_average_bounds(1, n - 1, alpha)),
             ("one_sided", sigma * np.sqrt(chi2_average_bounds(1, n - 1, alpha, one_sided=True))),
             ("no_divide", sigma * np.sqrt(chi2_average_bounds(1, n - 1, alpha, divide_by=1))),
             ("normal", sigma * (1 + np.array([-z, z]) / np.sqrt(2 * (n - 1)))),
             ("normal", sigma * (1 + np.array([-1.96, 1.96]) / np.sqrt(2 * (n - 1)))),  # with the usual 1.96
             ("normal", sigma * (1 + np.array([-2.0, 2.0]) / np.sqrt(2 * (n - 1))))]  # or the two-sigma rule
    return numeric(_IMU_STD_BAND, answer, right, wrong)


#: test input of the dead-reckoning exercise: IMU output a_c (3 realizations x 7 samples, m/s²),
#: the prior means p_init (m), v_init (m/s), dt (s).  3 != 7, so an integration along the wrong axis shows.
_DEAD_RECKON_TEST = (np.array([[0.5, -1.0, 2.0, 0.0, 3.0, -2.0, 1.5],
                               [1.0, 1.0, -0.5, 0.25, 0.0, 2.0, -1.0],
                               [-2.0, 0.5, 0.5, 1.5, -1.0, 0.0, 4.0]]), 1.0, 2.0, 0.1)


def _reckon_variant(a_c, p_init, v_init, dt, kind: str = "ok"):
    """The dead reckoning of ``a_c`` (n, n_t) along time by a plain loop, right or with one known mistake."""
    if kind == "axis":  # integrated across the realizations (axis 0) instead of along time
        p, v = _reckon_variant(a_c.T, p_init, v_init, dt)
        return p.T, v.T
    n, n_t = a_c.shape
    p, v = np.empty((n, n_t)), np.empty((n, n_t))
    p[:, 0] = p_init
    v[:, 0] = v_init
    for j in range(n_t - 1):
        aj = a_c[:, j + 1] if kind == "right" else a_c[:, j]
        v[:, j + 1] = v[:, j] + aj * dt
        vel = v[:, j + 1] if kind == "new_v" else v[:, j]
        acc = {"no_acc": 0.0, "dt2": aj * dt**2}.get(kind, aj * dt**2 / 2)
        p[:, j + 1] = p[:, j] + vel * dt + acc
    return p, v


_DEAD_RECKON = Exercise(
    "02.4",
    praise="your loop is the IMU dead reckoning: the same numbers as the notebook's cumulative sums",
    hint="compare your loop with the recursion: v_c[:, j+1] = v_c[:, j] + a_c[:, j] Δt, "
         "p_c[:, j+1] = p_c[:, j] + v_c[:, j] Δt + a_c[:, j] Δt²/2, from p_c[:, 0] = p̄0, v_c[:, 0] = v̄0",
    hints={
        "new_v": "the position step uses the velocity at t_j (before the update), not the new velocity v_c[:, j+1]",
        "no_acc": "the position step is missing the acceleration term a_c[:, j]Δt²/2",
        "dt2": "the acceleration term of the position step is a_c[:, j]Δt²/2, with the 1/2",
        "right": "left Riemann: the step from t_j to t_{j+1} uses a_c[:, j], not a_c[:, j+1]",
        "axis": "a_c has one row per realization and one column per sample: integrate along the columns "
                "(axis 1, time), each row on its own",
        "swapped": "return (p_c, v_c) in this order: position first",
        "shape": "p_c and v_c have the shape of a_c: one row per realization, one column per sample, starting "
                 "with p_c[:, 0] = p̄0 and v_c[:, 0] = v̄0",
        "tuple": "return a tuple (p_c, v_c) of two arrays",
    },
)


def check_dead_reckoning(func) -> Feedback:
    """Exercise 02.4: ``func(a_c, p_init, v_init, dt) -> (p_c, v_c)``, the IMU dead reckoning of
    ``a_c`` (n, n_imu) m/s² from the prior means ``p_init`` (m) and ``v_init`` (m/s), each (n, n_imu).

    Called on a test input of 3 realizations of 7 samples, p_init = 1 m, v_init = 2 m/s, dt = 0.1 s;
    compared with :func:`~kfcal_helpers.calibration.integrate_left` (rtol 1e-9).
    """
    ex = _DEAD_RECKON
    a_c, p_init, v_init, dt = _DEAD_RECKON_TEST
    out, fb = call_once(ex, func, "dead_reckon(a_c, p_init, v_init, dt)", (a_c.copy(), p_init, v_init, dt))
    if fb is not None:
        return fb
    pair = as_pair(out)
    if pair is None:
        return ex.mistake("tuple")
    p, v = pair
    if p.shape != a_c.shape or v.shape != a_c.shape:
        return ex.mistake("shape")
    p_ok, v_ok = integrate_left(a_c, p_init, v_init, dt)
    if close(p, p_ok) and close(v, v_ok):
        return ex.feedback(True)
    if close(p, v_ok) and close(v, p_ok):
        return ex.mistake("swapped")
    for kind in ("right", "new_v", "no_acc", "dt2", "axis"):
        pw, vw = _reckon_variant(a_c, p_init, v_init, dt, kind)
        if close(p, pw) and close(v, vw):
            return ex.mistake(kind)
    slip = ex.output_slip([p, v], [p_ok, v_ok], ("p_c", "v_c"))
    if slip is not None:
        return slip
    if close(v, v_ok):
        return ex.feedback(False, "v_c is right, p_c is not: " + ex.hint)
    return ex.feedback(False)


#: test input of the IMU-output exercise: a (5 samples, m/s²), b (3 realizations, m/s²), w (3 x 5, m/s²)
_IMU_OUTPUT_TEST = (np.array([0.0, 1.0, 2.0, -1.5, 0.5]), np.array([0.1, -0.2, 0.05]),
                    np.array([[0.01, -0.02, 0.03, 0.0, -0.01],
                              [0.02, 0.01, -0.03, 0.015, 0.0],
                              [-0.01, 0.0, 0.02, -0.02, 0.03]]))

_IMU_OUTPUT = Exercise(
    "02.5",
    praise="that is the IMU output a_c = a + b + w: one constant bias per realization, new noise at every sample",
    hint="a_c[l, j] = a[j] + b[l] + w[l, j]: the truth of sample j, the bias of realization l, the noise of both",
    hints={
        "bias_sign": "the IMU reports the truth PLUS its bias: check the sign of b",
        "noise_sign": "the IMU reports the truth plus the noise w, not minus it",
        "no_bias": "the bias b is missing: every sample of realization l carries the same b[l]",
        "no_noise": "the white noise w is missing",
        "broadcast": "b has one entry per realization (rows of w): give it a column axis, b[:, None], before "
                     "adding it to the (n, n_imu) array",
        "shape": "a_c has one row per realization and one column per sample: the shape of w",
        "transposed": "your a_c is transposed: one row per realization and one column per sample, as w",
    },
)


def check_imu_output(func) -> Feedback:
    """Exercise 02.5: ``func(a, b, w) -> a_c``, the IMU output ``a_c[l, j] = a[j] + b[l] + w[l, j]`` (m/s²),
    shape (n, n_imu), for ``a`` (n_imu,), ``b`` (n,) and ``w`` (n, n_imu).

    Called on 3 realizations of 5 samples (3 != 5, so a bias added along the wrong axis shows).
    """
    ex = _IMU_OUTPUT
    a, b, w = _IMU_OUTPUT_TEST
    out, fb = call_once(ex, func, "imu_output(a, b, w)", (a.copy(), b.copy(), w.copy()))
    if fb is not None:
        if fb.answered and "broadcast" in fb.message:
            return ex.mistake("broadcast")
        return fb
    got = as_array(out)
    if got is None or isinstance(out, (str, bytes)):
        return ex.mistake("shape")
    right = a + b[:, None] + w
    if got.shape == w.T.shape and close(got.T, right):
        return ex.mistake("transposed")
    if got.shape != w.shape:
        return ex.mistake("broadcast" if got.shape == w.T.shape else "shape")
    if close(got, right):
        return ex.feedback(True)
    variants = [("bias_sign", a - b[:, None] + w), ("noise_sign", a + b[:, None] - w),
                ("no_bias", a + w), ("no_noise", np.broadcast_to(a + b[:, None], w.shape))]
    for key, value in variants:
        if close(got, value):
            return ex.mistake(key)
    slip = ex.output_slip([got], [right], ("a_c",))
    return ex.feedback(False) if slip is None else slip


#: the exercise records of this lesson, in notebook order
RECORDS = (_IMU_DRIFT, _IMU_RANDOM_WALK, _IMU_STD_BAND, _DEAD_RECKON, _IMU_OUTPUT)
