"""Exercise checks of notebook 16 (minimum variance): 16.1-16.2."""

from __future__ import annotations



import numpy as np

from ...exercises._core import (Exercise, Feedback, as_array)
from ...validation import (require_positive)
from ..batch_estimate import batch_conditioning
from ..error_model import error_state_model, phi_power
from ..filters import covariance_sequence
from ..params import CalibrationParams
from ._shared import close, numeric
from ._15_outages import propagate


#: the data of exercise 16.1: dz_0 (row 0) and dz_1 (row 1), [position (m), velocity (m/s)]
BATCH_TWO_FIXES_DZ = np.array([[3.0, -0.5], [2.5, -0.45]])

_BATCH_TWO_FIXES = Exercise(
    "16.1",
    praise="one Gaussian conditioning on both fixes gives the filter's estimate at 0.2 s",
    hint="build Π_0, Π_1 and Cov(δx_1, δx_0) = Φ^40 Π_0, then Σ_zz (4×4), Σ_xz (3×4), and the mean Σ_xz Σ_zz⁻¹ z "
         "with z = [δz_0; δz_1]",
    hints={
        "only_last": "condition on BOTH fixes, δz_0 and δz_1 (Σ_zz is 4×4), not only on the last one",
        "no_v": "the measurements are noisy: Σ_zz = H C Hᵀ + I ⊗ V",
        "sign": "the conditional mean ADDS the correction: μ + Σ_xz Σ_zz⁻¹ (z − Hμ)",
        "prior": "that is the estimate before the fix at 0.2 s is used (the filter's a priori estimate, "
                 "conditioned on δz_0 only)",
        "unconditioned": "that is the prior mean μ_1 = 0, before any conditioning: condition on the data",
        "swapped": "stack the data in the order of Σ_zz's blocks: z = [δz_0; δz_1], row 0 of dz_16_1 first",
        "no_q_sum": "close, but a difference of method: Π_1 lacks the process noise that the IMU steps between the "
                    "two fixes add (each step adds Q, carried on by Φ); propagate Π_0 step by step",
    },
    components=("δp", "δv", "b"),
)


def check_batch_two_fixes(answer) -> Feedback:
    """Exercise 16.1: the conditional mean (3,) of δx(t_1) (t_1 = 0.2 s; m, m/s, m/s^2) given
    δz_0 and δz_1 = the rows of :data:`BATCH_TWO_FIXES_DZ` by one Gaussian conditioning, defaults
    (prior mean zero)."""
    params = CalibrationParams()
    m = error_state_model(params)
    H, V = m.H, m.V
    z = BATCH_TWO_FIXES_DZ.reshape(-1)
    F = phi_power(params, params.steps_per_fix)
    Pi0 = m.M0
    Pi1 = propagate(m.M0, params.steps_per_fix)

    def mean(Pi1, z, with_v=True):
        C10 = F @ Pi0
        Sxz = np.hstack([C10 @ H.T, Pi1 @ H.T])
        Szz = np.block([[H @ Pi0 @ H.T, H @ C10.T @ H.T], [H @ C10 @ H.T, H @ Pi1 @ H.T]])
        return Sxz @ np.linalg.solve(Szz + (np.kron(np.eye(2), V) if with_v else 0), z)

    dz = np.zeros((params.n_gps, 2))
    dz[:2] = BATCH_TWO_FIXES_DZ                  # batch_conditioning(params, 1, dz) reads rows 0 and 1 only
    right = batch_conditioning(params, 1, dz)[0]
    K0 = Pi0 @ H.T @ np.linalg.inv(H @ Pi0 @ H.T + V)
    wrong = [("only_last", Pi1 @ H.T @ np.linalg.solve(H @ Pi1 @ H.T + V, BATCH_TWO_FIXES_DZ[1])),
             ("sign", -right), ("prior", F @ K0 @ BATCH_TWO_FIXES_DZ[0]), ("unconditioned", np.zeros(3)),
             ("swapped", mean(Pi1, BATCH_TWO_FIXES_DZ[::-1].reshape(-1))),
             ("no_q_sum", mean(F @ Pi0 @ F.T, z))]  # Φ^40 Π_0 Φ^40ᵀ without the 40 steps' process noise
    fb = numeric(_BATCH_TWO_FIXES, answer, right, wrong, rtol=1e-6, atol=1e-12)
    # without V, Σ_zz has condition number about 3e11: two correct ways of computing that mistake agree
    # only to about 1e-5 (it depends on the machine's BLAS), so it is recognised at rtol 1e-3; it lies
    # about 10 % from the right answer, so nothing right or rounded comes that close to it
    a = as_array(answer)
    if fb.correct or fb.message != _BATCH_TWO_FIXES.hint or a is None or a.size != 3 or not np.all(np.isfinite(a)):
        return fb
    with np.errstate(all="ignore"):
        try:
            no_v = mean(Pi1, z, with_v=False)
        except np.linalg.LinAlgError:  # singular without V: nobody gets that answer
            return fb
    return _BATCH_TWO_FIXES.mistake("no_v") if close(a.ravel(), no_v, rtol=1e-3) else fb


_SMOOTHED_BIAS_SIGMA = Exercise(
    "16.2",
    praise="offline, the bias is known from t = 0 with the filter's final accuracy",
    hint="the bias is constant with no process noise: look at how the smoothed σ_b varies over the recording in "
         "the notebook's table",
    hints={
        "full_run": "the recording is 10 s long here, not 30 s",
        "prior": "the smoother conditions on every fix of the recording, also the last one",
        "filtered": "that is the filtered σ_b at t = 0; the smoother uses all fixes of the recording",
        "variance": "this is a variance: the exercise asks for a standard deviation",
    },
)


def check_smoothed_bias_sigma(answer, *, duration: float = 10.0) -> Feedback:
    """Exercise 16.2: the RTS-smoothed σ_b (m/s²) at t = 0 for a recording of ``duration`` s
    (defaults otherwise: 200 Hz, 5 Hz, a fix at every 0.2 s)."""
    p = CalibrationParams(duration=require_positive("duration", duration))
    P, P_prior, _, _ = covariance_sequence(p)
    right = np.sqrt(P[-1, 2, 2])
    full = covariance_sequence(CalibrationParams())[0][-1, 2, 2]
    wrong = [("full_run", np.sqrt(full)), ("prior", np.sqrt(P_prior[-1, 2, 2])),
             ("filtered", np.sqrt(P[0, 2, 2])), ("variance", right**2)]
    if abs(p.duration - 30.0) < 1e-9:
        wrong = wrong[1:]
    return numeric(_SMOOTHED_BIAS_SIGMA, answer, right, wrong, rtol=1e-6)


#: the exercise records of this lesson, in notebook order
RECORDS = (_BATCH_TWO_FIXES, _SMOOTHED_BIAS_SIGMA)
