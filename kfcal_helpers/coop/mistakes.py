"""The cooperative-localization mistakes of the course reports, for the mistakes table of notebook 14.

Each row is a truth-model test (:func:`~kfcal_helpers.coop.montecarlo.truth_model_test`, 50 runs,
seed 11) of a filter with one mistake, after its correct filter:

* ``ekf_no_wrap`` -- EKF innovations without bearing wrapping (filterpy's default ``np.subtract``);
* ``ekf_omega_identity`` -- the noise entering as ``Omega = I`` in both the truth model and the filter
  (per-step state noise Qtrue instead of dt^2 Qtrue), with the Q the truth-model test picks there;
* ``lkf_no_nominal`` -- the LKF innovation without the nominal measurement subtracted.

The first entry of :data:`MISTAKES` is the correct EKF, which passes all its checks.
:func:`mistake_row` is the problem's ``mistake_row`` of :class:`kfcal_helpers.registry.Problem`.
"""

from __future__ import annotations

from dataclasses import replace

from ..registry import MistakeRow
from ..validation import require_choice, require_instance, require_int
from .model import CoopParams
from .montecarlo import truth_model_test

__all__ = ["MISTAKES", "N_RUNS", "SEED", "coop_case", "mistake_row"]

#: cooperative-localization mistakes, each after its correct filter: name -> what the filter does
MISTAKES = {
    "ekf_correct": "the correct EKF (Omega = dt I, Q = Qtrue, wrapped innovations)",
    "ekf_no_wrap": "EKF innovations without bearing wrapping",
    "ekf_omega_identity": "noise entering as Omega = I in truth model and filter (Q = 1.5 Qtrue)",
    "lkf_correct": "the correct LKF (small-perturbation truth model)",
    "lkf_no_nominal": "LKF innovation without the nominal measurement subtracted",
}

N_RUNS = 50  #: runs of a row's truth-model test by default
SEED = 11  #: seed of every row by default: the rows differ only by the mistake


def coop_case(mistake: str, params: CoopParams | None = None) -> tuple[str, CoopParams, dict]:
    """Filter name, truth-model parameters and filter settings of a coop row.

    The EKF rows use the course's truth model (``Omega = dt I``) and the tuned ``Q = Qtrue``, except
    ``ekf_omega_identity``, whose truth model and filter both use ``Omega = I`` with ``Q = 1.5 Qtrue``
    (the scale the truth-model test picks in that model: ``Qtrue`` is over-confident there); the LKF
    rows a truth that stays near the nominal (``Qtrue / 10^4``, P0 / 100), the regime where a correct
    LKF is consistent (notebook 10), with the filter's Q equal to it.
    """
    mistake = require_choice("mistake", mistake, tuple(MISTAKES))
    p = require_instance("params", params, CoopParams, allow_none=True) or CoopParams()
    if mistake == "ekf_omega_identity":
        return "ekf", replace(p, noise_model="identity"), {"Q": 1.5 * p.Qtrue}
    if mistake.startswith("ekf"):
        return "ekf", p, {"Q": p.Qtrue, "wrap_innovations": mistake == "ekf_correct"}
    near = replace(p, Qtrue=1e-4 * p.Qtrue, P0=0.01 * p.P0)
    return "lkf", near, {"Q": near.Qtrue, "subtract_nominal": mistake == "lkf_correct"}


def mistake_row(mistake: str, n_runs: int | None = None, params: CoopParams | None = None, alpha: float = 0.05,
                seed: int = SEED) -> MistakeRow:
    """Truth-model test of the coop filter with ``mistake`` (see :func:`coop_case`).

    n_runs : runs, >= 2 (None: :data:`N_RUNS`); params : CoopParams (None: the course's);
    alpha : family-wise level of the checks, in (0, 1); seed : int >= 0.
    Returns a :class:`~kfcal_helpers.registry.MistakeRow` whose ``checks`` are ``mc.checks()``.
    """
    filter, p, settings = coop_case(mistake, params)
    n_runs = N_RUNS if n_runs is None else require_int("n_runs", n_runs, minimum=2)
    mc = truth_model_test(p, n_runs, seed, filter=filter, alpha=alpha, **settings)
    return MistakeRow("coop", mistake, MISTAKES[mistake], mc.checks(), mc)
