"""Model of the cooperative-localization problem: closed form, wrapping, Jacobians, observability."""

from dataclasses import replace

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from kfcal_helpers.coop import (
    CoopParams,
    discretize,
    dynamics,
    jacobian_A,
    jacobian_B,
    jacobian_C,
    measure,
    measurement_mean,
    nominal_trajectory,
    observability_matrix,
    state_mean,
    state_residual,
    step,
    wrap_angle,
    wrap_state,
)

P = CoopParams()


def _fd(fun, x0, eps=1e-6):
    """Central finite-difference Jacobian of fun at x0 (residuals wrapped by the caller)."""
    cols = []
    for i in range(x0.size):
        dx = np.zeros_like(x0)
        dx[i] = eps
        cols.append(fun(x0 + dx, x0 - dx) / (2 * eps))
    return np.stack(cols, axis=-1)


@pytest.fixture(scope="module")
def random_states():
    rng = np.random.default_rng(7)
    xs = nominal_trajectory(P)[rng.integers(0, P.n_samples, 5)] + rng.normal(0, [3, 3, 1, 3, 3, 1], (5, 6))
    return wrap_state(xs)


def test_closed_form_matches_solve_ivp():
    sol = solve_ivp(lambda t, x: dynamics(x, P.u0, P.L), (0, P.duration), P.x0, t_eval=P.t, rtol=1e-10, atol=1e-10)
    err = np.abs(state_residual(sol.y.T, nominal_trajectory(P))).max()
    assert err < 1e-6
    # the one-step map applied repeatedly gives the same trajectory
    x = P.x0.copy()
    for _ in range(100):
        x = step(x, P.u0, P.dt, P.L)
    assert np.abs(state_residual(x, nominal_trajectory(P)[100])).max() < 1e-9


def test_straight_line_limit():
    u = np.array([2.0, 0.0, 12.0, 0.0])
    x1 = step(P.x0, u, 1.0, P.L)
    expected = P.x0 + np.array([2 * np.cos(np.pi / 2), 2.0, 0, 12 * np.cos(-np.pi / 2), -12.0, 0])
    assert np.allclose(x1, expected, atol=1e-12)
    # continuity: a tiny turn rate is close to the straight line
    u_eps = np.array([2.0, 1e-12, 12.0, 1e-12])
    assert np.allclose(step(P.x0, u_eps, 1.0, P.L), expected, atol=1e-9)


def test_nominal_rates_from_spec():
    wg = P.u0[0] * np.tan(P.u0[1]) / P.L
    assert wg == pytest.approx(-0.7053, abs=1e-4)
    assert P.u0[2] / P.u0[3] == pytest.approx(95.49, abs=0.01)


@pytest.mark.parametrize("angle, wrapped", [(np.pi, np.pi), (-np.pi, np.pi), (3 * np.pi, np.pi),
                                            (np.pi + 0.1, -np.pi + 0.1), (-np.pi - 0.1, np.pi - 0.1), (0.0, 0.0)])
def test_wrap_angle_at_pi(angle, wrapped):
    assert wrap_angle(angle) == pytest.approx(wrapped, abs=1e-12)


def test_wrap_keeps_range_and_residual_is_short():
    a = np.linspace(-20, 20, 4001)
    w = wrap_angle(a)
    assert np.all(w > -np.pi) and np.all(w <= np.pi)
    assert np.allclose(np.cos(w), np.cos(a)) and np.allclose(np.sin(w), np.sin(a))
    x1 = np.array([0, 0, np.pi - 0.05, 0, 0, -np.pi + 0.05])
    x2 = np.array([0, 0, -np.pi + 0.05, 0, 0, np.pi - 0.05])
    assert np.allclose(state_residual(x1, x2), [0, 0, -0.1, 0, 0, 0.1])


def test_measurement_bearings_wrapped():
    y = measure(nominal_trajectory(P))
    assert np.all(np.abs(y[:, [0, 2]]) <= np.pi)
    # the UGV circles every 8.9 s, so its bearing to the UAV crosses +-pi: jumps of ~2 pi
    assert np.sum(np.abs(np.diff(y[:, 0])) > np.pi) > 5


def test_circular_means_across_pi():
    pts = np.zeros((2, 6))
    pts[:, 2] = [np.pi - 0.1, -np.pi + 0.1]
    assert abs(abs(state_mean(pts, np.array([0.5, 0.5]))[2]) - np.pi) < 1e-12
    z = np.zeros((2, 5))
    z[:, 0] = [np.pi - 0.2, -np.pi + 0.1]
    assert measurement_mean(z, np.array([0.5, 0.5]))[0] == pytest.approx(np.pi - 0.05, abs=1e-12)


def test_jacobians_against_finite_differences(random_states):
    for x in random_states:
        A = jacobian_A(x, P.u0, P.L)
        A_fd = _fd(lambda a, b: dynamics(a, P.u0, P.L) - dynamics(b, P.u0, P.L), x)
        assert np.abs(A - A_fd).max() < 1e-6
        B = jacobian_B(x, P.u0, P.L)
        B_fd = _fd(lambda a, b: dynamics(x, a, P.L) - dynamics(x, b, P.L), P.u0.copy())
        assert np.abs(B - B_fd).max() < 1e-5
        C = jacobian_C(x)
        C_fd = _fd(_meas_diff, x)
        assert np.abs(C - C_fd).max() < 1e-6
    assert A.shape == (6, 6) and B.shape == (6, 4) and C.shape == (5, 6)


def _meas_diff(a, b):
    from kfcal_helpers.coop import measurement_residual

    return measurement_residual(measure(a), measure(b))


def test_discretization_is_matrix_exponential():
    from scipy.linalg import expm

    x = nominal_trajectory(P)[37]
    A, B, C = jacobian_A(x, P.u0), jacobian_B(x, P.u0), jacobian_C(x)
    F, G, H = discretize(A, B, C, P.dt)
    assert np.allclose(F, expm(A * P.dt), atol=1e-14)
    assert np.allclose(G, P.dt * B) and np.allclose(H, C)


def test_observability_over_a_window():
    xn = nominal_trajectory(P)[:10]
    F = np.eye(6) + P.dt * jacobian_A(xn, P.u0)
    H = jacobian_C(xn)
    assert np.linalg.matrix_rank(observability_matrix(F[:1], H[:1])) == 5
    assert np.linalg.matrix_rank(observability_matrix(F[:9], H)) == 6
    with pytest.raises(ValueError, match="F must"):
        observability_matrix(F[:2], H[:5, :, :])


def test_params_bad_input():
    with pytest.raises(ValueError, match="L must"):
        CoopParams(L=0)
    with pytest.raises(ValueError, match="dt must"):
        CoopParams(dt=-0.1)
    with pytest.raises(ValueError, match="Qtrue must be symmetric"):
        CoopParams(Qtrue=np.diag([1.0] * 6) + np.triu(np.ones((6, 6)), 1) * 0.1)
    with pytest.raises(ValueError, match="Rtrue must be positive definite"):
        CoopParams(Rtrue=np.diag([1.0, 1.0, -1.0, 1.0, 1.0]))
    with pytest.raises(ValueError, match="x0 must"):
        CoopParams(x0=np.zeros(5))
    with pytest.raises(ValueError, match="duration must"):
        CoopParams(duration=0.05)
    with pytest.raises(ValueError, match="L must"):
        step(P.x0, P.u0, 0.1, L=0.0)
    with pytest.raises(ValueError, match="x must"):
        step(np.zeros(5), P.u0)


def test_same_position_raises():
    x = np.array([1.0, 2.0, 0.3, 1.0, 2.0, -0.4])
    with pytest.raises(ValueError, match="x: the two vehicles are at the same position"):
        jacobian_C(x)
    with pytest.raises(ValueError, match="x: "):
        measure(x)


def test_params_are_read_only():
    with pytest.raises(ValueError):
        P.Qtrue[0, 0] = 1.0
    assert replace(P, L=1.0).L == 1.0 and P.L == 0.5


def test_wrap_one_vector_matches_the_array_path():
    """wrap_state has a fast path for single vectors: same convention (-pi, pi] as for arrays."""
    rng = np.random.default_rng(1)
    xs = rng.uniform(-20, 20, (200, 6))
    xs[0, [2, 5]] = [np.pi, -np.pi]
    rows = np.array([wrap_state(x) for x in xs])
    assert np.allclose(rows, wrap_state(xs), atol=1e-12, rtol=0)
    assert rows[0, 2] == np.pi and rows[0, 5] == np.pi


def test_noise_model_omega():
    """Omega = dt I by default (state noise dt^2 Qtrue per step); Omega = I is the named variant."""
    assert P.noise_model == "dt" and np.allclose(P.Omega, 0.1 * np.eye(6))
    assert np.allclose(P.process_noise(), 0.01 * P.Qtrue)
    ident = replace(P, noise_model="identity")
    assert np.allclose(ident.Omega, np.eye(6)) and np.allclose(ident.process_noise(), P.Qtrue)
    with pytest.raises(ValueError, match="noise_model must be one of 'dt', 'identity'"):
        CoopParams(noise_model="I")
    with pytest.raises(ValueError, match="Q must be positive definite"):
        P.process_noise(-np.eye(6))


@pytest.mark.parametrize("model, factor", [("dt", 0.01), ("identity", 1.0)])
def test_truth_simulation_uses_omega(model, factor):
    """The truth's one-step increments beyond the closed-form map have covariance Omega Qtrue Omega^T:
    the sample variances of 400 runs x 20 steps lie within 5 standard errors of factor * Qtrue."""
    from kfcal_helpers.coop import simulate_truth

    pp = replace(P, noise_model=model, duration=2.0)
    x = simulate_truth(pp, np.random.default_rng(3), n_runs=400)
    w = state_residual(x[:, 1:], step(x[:, :-1], pp.u0, pp.dt, pp.L)).reshape(-1, 6)
    var = w.var(axis=0)
    expected = factor * np.diag(P.Qtrue)
    assert np.all(np.abs(var / expected - 1) < 5 * np.sqrt(2 / w.shape[0]))


def test_exact_step_jacobian():
    """jacobian_step against finite differences of the exact map; I + dt A differs from it at second order."""
    from kfcal_helpers.coop.model import jacobian_step

    rng = np.random.default_rng(2)
    x = P.x0 + rng.normal(size=(5, 6))
    for xi in x:
        fd = _fd(lambda a, b: state_residual(step(a, P.u0, P.dt, P.L), step(b, P.u0, P.dt, P.L)), xi)
        assert np.allclose(jacobian_step(xi, P.u0, P.dt, P.L), fd, atol=1e-7)
        euler = np.eye(6) + P.dt * jacobian_A(xi, P.u0, P.L)
        gap = np.abs(euler - jacobian_step(xi, P.u0, P.dt, P.L)).max()
        assert 1e-4 < gap < 0.1  # 12 m/s * (pi/25 * 0.1)^2 / ... : second order in dt


def test_course_log_setting(tmp_path, monkeypatch):
    """KFCAL_COURSE_LOG: a valid folder is loaded; unset or missing falls back to the generated log, saying so."""
    from kfcal_helpers.coop import course_log, simulate, write_log_csv

    monkeypatch.delenv("KFCAL_COURSE_LOG", raising=False)
    log, found, msg = course_log(replace(P, duration=1.0), seed=3)
    assert not found and "is not set" in msg and len(msg.splitlines()) == 1
    assert np.array_equal(log.y, simulate(replace(P, duration=1.0), seed=3).log().y, equal_nan=True)
    monkeypatch.setenv("KFCAL_COURSE_LOG", str(tmp_path / "nothing"))
    assert course_log(replace(P, duration=1.0))[1] is False
    write_log_csv(simulate(replace(P, duration=1.0), seed=4).log(), tmp_path / "log")
    monkeypatch.setenv("KFCAL_COURSE_LOG", str(tmp_path / "log"))
    log, found, msg = course_log()
    assert found and str(tmp_path / "log") in msg and log.n_samples == 11
