"""The orbit-determination model: Jacobians against finite differences, the integrated nominal against
its closed form, the visibility rule, the DT model, the simulation's shapes and the course's columns."""

from dataclasses import replace

import numpy as np
import pytest
from scipy.linalg import expm

from kfcal_helpers.angles import wrap_angle
from kfcal_helpers.orbit import (
    OrbitParams,
    discretize,
    dynamics,
    from_columns,
    integrate,
    jacobian_A,
    jacobian_C,
    measure,
    nominal_state,
    nominal_trajectory,
    propagate,
    simulate,
    simulate_truth,
    station_angles,
    station_states,
    to_columns,
    visible,
)

P = OrbitParams()


def _states(rng, n):
    """States near the orbit: radius 6500..7000 km, any angle, velocities about 7.7 km/s."""
    a = rng.uniform(-np.pi, np.pi, n)
    r = rng.uniform(6500, 7000, n)
    v = rng.uniform(7.0, 8.0, n)
    b = a + np.pi / 2 + rng.uniform(-0.2, 0.2, n)
    return np.stack([r * np.cos(a), v * np.cos(b), r * np.sin(a), v * np.sin(b)], axis=-1)


def _fd(fun, x, h):
    """Central differences of fun (.., m) with respect to x (4,), one column per state, steps h (4,)."""
    cols = []
    for j in range(4):
        e = np.zeros(4)
        e[j] = h[j]
        cols.append((fun(x + e) - fun(x - e)) / (2 * h[j]))
    return np.stack(cols, axis=-1)


def test_jacobian_A_matches_finite_differences():
    rng = np.random.default_rng(1)
    h = np.array([1e-3, 1e-6, 1e-3, 1e-6])
    for x in _states(rng, 20):
        A = jacobian_A(x, P)
        np.testing.assert_allclose(A, _fd(lambda z: dynamics(z, P), x, h), rtol=1e-6, atol=1e-13)
        assert A.shape == (4, 4) and A[1, 0] != 0 and A[1, 2] == A[3, 0]


def test_jacobian_C_matches_finite_differences_for_every_station():
    rng = np.random.default_rng(2)
    h = np.array([1e-3, 1e-6, 1e-3, 1e-6])
    for x, t in zip(_states(rng, 10), rng.uniform(0, 14000, 10)):
        C = jacobian_C(x, t, P)
        assert C.shape == (12, 3, 4)

        def h_unwrapped(z):
            m = measure(z, t, P)
            m[..., 2] = np.unwrap(np.stack([measure(x, t, P)[..., 2], m[..., 2]]), axis=0)[1]  # phi across +-pi
            return m

        np.testing.assert_allclose(C, _fd(h_unwrapped, x, h), rtol=1e-5, atol=1e-10)


def test_integrated_nominal_matches_the_closed_form():
    """solve_ivp (tight tolerances) and the filters' RK4 map carry the nominal along the circle."""
    K = 200  # 2000 s, over a third of an orbit
    nom = nominal_trajectory(P, K)
    x, z = nom[0], nom[0]
    for k in range(1, K):
        x = integrate(x, P)
        z = propagate(z, P)
    np.testing.assert_allclose(x, nom[-1], rtol=0, atol=1e-6)  # km, km/s
    np.testing.assert_allclose(z, nom[-1], rtol=0, atol=1e-6)
    # one step of the RK4 map from the nominal, against the closed form
    one = propagate(nom[:-1], P)
    assert np.abs(one - nom[1:]).max() < 1e-7
    assert abs(P.period - 5431.0) < 1.0


def test_stations_and_their_velocities():
    t = np.linspace(0, 14000, 15)
    s = station_states(t, P)
    assert s.shape == (15, 12, 4)
    np.testing.assert_allclose(np.hypot(s[..., 0], s[..., 2]), P.RE)
    h = 1e-2
    vel = (station_states(t + h, P) - station_states(t - h, P)) / (2 * h)
    np.testing.assert_allclose(s[..., 1], vel[..., 0], rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(s[..., 3], vel[..., 2], rtol=1e-6, atol=1e-9)
    th = station_angles(0.0, P)
    np.testing.assert_allclose(th, np.arange(12) * np.pi / 6)


def test_visibility_is_the_horizon_rule_and_phi_within_a_quarter_turn():
    rng = np.random.default_rng(3)
    x = _states(rng, 400)
    t = rng.uniform(0, 14000, 400)
    v = visible(x, t, P)
    st = station_states(t, P)
    los = x[:, None, [0, 2]] - st[..., [0, 2]]
    rule = (los * st[..., [0, 2]]).sum(axis=-1) > 0
    np.testing.assert_array_equal(v, rule)
    phi = measure(x, t, P)[..., 2]
    quarter = np.abs(wrap_angle(phi - station_angles(t, P))) < np.pi / 2
    np.testing.assert_array_equal(v, quarter)
    assert 0.02 < v.mean() < 0.2  # a station sees a low orbit a small part of the time
    # along the nominal: one or two stations at every step
    nom = nominal_trajectory(P)
    counts = visible(nom, P.t, P).sum(axis=1)
    assert counts.min() == 1 and counts.max() == 2


def test_measurements_are_range_rate_and_wrapped_angle():
    x = np.array([7000.0, 0.5, 100.0, 7.5])
    m = measure(x, 1000.0, P)
    st = station_states(1000.0, P)
    d = x - st
    rho = np.hypot(d[:, 0], d[:, 2])
    np.testing.assert_allclose(m[:, 0], rho)
    np.testing.assert_allclose(m[:, 1], (d[:, 0] * d[:, 1] + d[:, 2] * d[:, 3]) / rho)
    assert np.all(np.abs(m[:, 2]) <= np.pi)
    np.testing.assert_allclose(np.cos(m[:, 2]), d[:, 0] / rho)


def test_discretize_euler_and_expm():
    A = jacobian_A(nominal_trajectory(P, 5), P)
    F = discretize(A, P.dt)
    np.testing.assert_allclose(F, np.eye(4) + P.dt * A)
    E = discretize(A, P.dt, "expm")
    np.testing.assert_allclose(E[2], expm(P.dt * A[2]), rtol=1e-12)
    assert np.abs(E - F).max() < 1e-3 * P.dt  # O(dt^2 |A|^2)
    np.testing.assert_allclose(P.Omega, P.dt * P.Gamma)
    np.testing.assert_allclose(P.process_noise(), P.dt**2 * 1e-10 * np.diag([0, 1, 0, 1]), atol=1e-20)


def test_simulation_shapes_visibility_and_the_course_columns():
    p = replace(P, n_steps=300)
    sim = simulate(p, seed=4)
    K = p.n_samples
    assert sim.truth.shape == (K, 4) and sim.y.shape == (K, 12, 3)
    finite = np.isfinite(sim.y).all(axis=-1)
    assert not finite[0].any()  # no measurement at t_0
    np.testing.assert_array_equal(finite[1:], visible(sim.truth[1:], p.t[1:], p))
    assert np.all(np.abs(sim.y[..., 2][finite]) <= np.pi)
    log = sim.log()
    assert len(log.ydata) == K and log.ydata[0].shape == (4, 0)
    assert all(c.shape[0] == 4 for c in log.ydata)
    np.testing.assert_array_equal(log.dof, 3 * finite.sum(axis=1))
    np.testing.assert_array_equal(from_columns(to_columns(sim.y)), sim.y)
    ids = np.concatenate([c[3] for c in log.ydata])
    assert set(ids.tolist()) <= set(range(1, 13)) and ids.size == finite.sum()
    many = simulate(p, 3, seed=4)
    assert many.truth.shape == (3, K, 4) and many.y.shape == (3, K, 12, 3)
    one = simulate(p, 1, seed=4)
    np.testing.assert_array_equal(one.truth[0], sim.truth)


def test_measurement_noise_has_the_covariance_Rtrue():
    p = replace(P, n_steps=600)
    sim = simulate(p, 20, seed=5)
    t = p.t
    err = sim.y - measure(sim.truth, t, p)
    err[..., 2] = wrap_angle(err[..., 2])
    e = err[np.isfinite(err).all(axis=-1)]
    assert e.shape[0] > 5000
    np.testing.assert_allclose(e.var(axis=0), np.diag(P.Rtrue), rtol=0.1)


def test_noise_free_truth_from_the_nominal_is_the_nominal():
    p = replace(P, n_steps=50)
    x = simulate_truth(p, 0, x0=nominal_state(0.0, p), process_noise=False)
    np.testing.assert_allclose(x, nominal_trajectory(p), atol=1e-7)


@pytest.mark.parametrize("kwargs,name", [
    ({"dt": 0.0}, "dt"), ({"n_steps": 0}, "n_steps"), ({"n_steps": 10**9}, "n_steps"), ({"Qtrue": np.eye(3)}, "Qtrue"),
    ({"Rtrue": -np.eye(3)}, "Rtrue"), ({"dx0": [1, 2]}, "dx0"), ({"r0": 6000.0}, "r0"),
    ({"n_stations": 0}, "n_stations"), ({"omegaE": -1.0}, "omegaE"), ({"P0": np.ones((4, 4))}, "P0"),
])
def test_bad_params_name_the_argument(kwargs, name):
    with pytest.raises(ValueError, match=name):
        OrbitParams(**kwargs)


def test_bad_inputs_name_the_argument():
    with pytest.raises(ValueError, match="x must have shape"):
        jacobian_A(np.zeros(3))
    with pytest.raises(ValueError, match="x must hold only finite"):
        measure([np.nan, 0, 0, 0], 0.0)
    with pytest.raises(ValueError, match="transition"):
        discretize(np.zeros((4, 4)), 10.0, "rk")
    with pytest.raises(ValueError, match="params"):
        visible(np.ones(4), 0.0, params={})
    with pytest.raises(ValueError, match="station ids"):
        from_columns([np.array([[1.0], [0.1], [0.2], [13.0]])])


def test_rk4_truth_agrees_with_solve_ivp_on_the_same_draws():
    a = simulate(P, 2, seed=8)
    b = simulate(P, 2, seed=8, integrator="rk4")
    assert np.abs(a.truth - a.truth[:, :1]).max() > 1000  # the orbit moved
    np.testing.assert_allclose(b.truth, a.truth, rtol=0, atol=1e-7)  # km, km/s over the 1400 steps
    np.testing.assert_array_equal(np.isfinite(b.y), np.isfinite(a.y))
    with pytest.raises(ValueError, match="integrator"):
        simulate(P, seed=8, integrator="euler")


@pytest.mark.parametrize("integrator", ["rk4", "solve_ivp"])
def test_truth_noise_enters_as_the_filters_dt_model_omega_w(integrator):
    """The truth is the filters' DT model ``x_{k+1} = f_d(x_k) + Omega w_k``, ``Omega = dt Gamma``: each step is
    the noise-free flow plus a velocity kick ``dt w_k`` and no position change.  (Holding w_k over the step, as
    the truth once did, also moves the position by ``dt^2 w_k / 2``, a noise the filters' ``Omega Q Omega^T``
    lacks: the EKF's and UKF's 1000-run NEES then sat at 3.89, not 4.)"""
    p = replace(P, n_steps=30)
    x = simulate_truth(p, 4, n_runs=3, integrator=integrator)
    rng = np.random.default_rng(4)  # the same draws: initial states, then w_k
    rng.standard_normal((3, 4))
    w = rng.standard_normal((3, p.n_steps, 2)) @ np.linalg.cholesky(p.Qtrue).T
    flow = propagate(x[:, :-1], p, substeps=5) if integrator == "rk4" else integrate(x[:, :-1], p)
    kick = x[:, 1:] - flow
    np.testing.assert_allclose(kick, w @ p.Omega.T, rtol=0, atol=1e-9)  # km, km/s
    assert np.abs(kick[..., [0, 2]]).max() < 1e-9 < np.abs(kick[..., [1, 3]]).min()
