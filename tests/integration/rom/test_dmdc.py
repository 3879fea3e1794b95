"""DMD with control and parametric DMD: known systems, PyDMD, held-out belt configurations."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.rom import (belt_inputs, collect_first_order, fit_dmdc, fit_parametric_dmd, interpolation_weights,
                         parameters, rmse, stack_controlled, tracer_operator)


def _linear_system(seed=0, n=6, l=2, m=60):
    rng = np.random.default_rng(seed)
    Q = np.linalg.qr(rng.normal(size=(n, n)))[0]
    A = Q @ np.diag(np.linspace(0.5, 0.95, n)) @ Q.T
    B = rng.normal(size=(n, l))
    U = rng.normal(size=(l, m))
    X = np.zeros((n, m + 1))
    X[:, 0] = rng.normal(size=n)
    for k in range(m):
        X[:, k + 1] = A @ X[:, k] + B @ U[:, k]
    return A, B, X, U


@pytest.mark.parametrize("method", ["pod", "proctor"])
def test_recovers_a_and_b_of_a_known_linear_system(method):
    A, B, X, U = _linear_system()
    d = fit_dmdc(X[:, :-1], X[:, 1:], U, method=method)
    V = np.asarray(d.basis)
    assert np.allclose(V @ np.asarray(d.A) @ V.T, A, atol=1e-9)
    assert np.allclose(np.asarray(d.B_full), B, atol=1e-9)
    assert np.allclose(np.sort(np.abs(np.asarray(d.eigs))), np.sort(np.abs(np.linalg.eigvals(A))), atol=1e-9)
    pred = d.predict(jnp.asarray(X[:, 0]), jnp.asarray(U.T), U.shape[1])
    assert np.allclose(np.asarray(pred), X[:, 1:].T, atol=1e-8)


def test_proctor_form_matches_pydmd():
    from pydmd import DMDc

    rng = np.random.default_rng(3)
    A, B, X, U = _linear_system(seed=3, n=12, l=2, m=40)
    X = X + 1e-3 * rng.normal(size=X.shape)  # noisy: truncation matters
    ref = DMDc(svd_rank=8, svd_rank_omega=10)
    ref.fit(X, U)
    d = fit_dmdc(X[:, :-1], X[:, 1:], U, rank=10, rank_out=8, method="proctor", scale_inputs=False)
    assert np.allclose(np.sort_complex(np.asarray(d.eigs)), np.sort_complex(ref.eigs), atol=1e-10)
    assert np.allclose(np.asarray(d.B_full), ref.B, atol=1e-10)


def test_interpolation_weights_reproduce_affine_functions():
    P = jnp.array([[0.0, 0.0], [1.0, 0.0], [0.0, 2.0], [1.0, 1.0]])
    mu = jnp.array([0.3, 0.7])
    w = interpolation_weights(P, mu)
    assert np.isclose(float(jnp.sum(w)), 1.0)
    assert np.allclose(np.asarray(w @ P), np.asarray(mu))
    f = P @ jnp.array([2.0, -1.0]) + 5.0  # any affine function of the parameters
    assert np.isclose(float(w @ f), float(mu @ jnp.array([2.0, -1.0]) + 5.0))


def test_gradient_through_dmdc_fit_and_prediction():
    A, B, X, U = _linear_system(seed=5, n=5, l=1, m=30)
    X, U = jnp.asarray(X), jnp.asarray(U)

    def f(X):
        d = fit_dmdc(X[:, :-1], X[:, 1:], U, rank=5)
        return jnp.sum(d.predict(X[:, 0], jnp.ones(1), 10) ** 2)

    dX = jax.random.normal(jax.random.PRNGKey(0), X.shape)
    g = jnp.vdot(jax.jit(jax.grad(f))(X), dX)  # jit-compiled: one program each, not op by op
    f = jax.jit(f)
    fd = (f(X + 1e-6 * dX) - f(X - 1e-6 * dX)) / 2e-6
    assert abs(float(g - fd)) < 1e-5 * abs(float(fd))


DT = jb.load_scene("two-roller-1d").time.dt  # the time step of every two-roller-1d scene


@pytest.fixture(scope="module")
def belt():
    n_train, n_test = 150, 400
    runs = {}
    for name in ("two-roller-1d", "two-roller-1d-train1", "two-roller-1d-train2"):
        m = jb.load_model(name)
        runs[name] = (m, collect_first_order(m, jb.RunOptions(jb.make_solver(), n_train, DT))[2])
    m0 = runs["two-roller-1d"][0]
    C = tracer_operator(m0)
    return runs, jnp.concatenate([C, jnp.zeros_like(C)], axis=1), n_test


def _truth(test, n):
    return jb.simulate(test, n_steps=n, dt=DT)[1].tracer_u


def test_dmdc_predicts_a_held_out_misalignment(belt):
    # trained at the nominal drive speed on 0 and -10 mm, tested on -6 mm for 400 steps
    runs, Cz, n = belt
    use = [runs["two-roller-1d"], runs["two-roller-1d-train1"]]
    X, Y, U = stack_controlled([z for _, z in use], [belt_inputs(parameters(m), z.shape[1] - 1) for m, z in use])
    d = fit_dmdc(X, Y, U, rank=30)
    test = jb.with_misalignment(use[0][0], translation=jnp.array([-6e-3, 0.0]))
    z0 = collect_first_order(test, jb.RunOptions(jb.make_solver(), 1, DT))[2][:, 0]
    pred = d.predict(z0, belt_inputs(parameters(test), 1)[:, 0], n, observe=Cz)
    assert float(rmse(_truth(test, n), pred)) * 1e3 < 0.02
    # the source's multi-configuration DMD (no inputs) cannot tell the configurations apart
    from jaxbelt.rom import fit_dmd

    plain = fit_dmd(X, Y, rank=30)
    err_plain = float(rmse(_truth(test, n), plain.predict(z0, n, observe=Cz))) * 1e3
    assert err_plain > 0.02


def test_parametric_dmd_predicts_a_held_out_misalignment_and_speed(belt):
    runs, Cz, n = belt
    trajs = [z for _, z in runs.values()]
    P = jnp.stack([parameters(m) for m, _ in runs.values()])
    p = fit_parametric_dmd(trajs, P, rank=30)
    m0 = runs["two-roller-1d"][0]
    test = jb.with_misalignment(m0, translation=jnp.array([-6e-3, 0.0])).replace(omega=0.9 * m0.omega)
    pred = p.predict(parameters(test), n + 1, observe=Cz)[1:]
    assert float(rmse(_truth(test, n), pred)) * 1e3 < 0.02


def test_parametric_dmd_with_a_given_basis_equals_its_own_svd():
    """``basis=`` (one SVD reused over a rank study) gives the model of the SVD the fit would do."""
    rng = np.random.default_rng(3)
    trajs, P = [], []
    for j in range(3):
        A, B, X, U = _linear_system(seed=j, m=30)
        trajs.append(jnp.asarray(X))
        P.append([float(j)])
    own = fit_parametric_dmd(trajs, jnp.asarray(P), rank=5)
    U_all = np.linalg.svd(np.concatenate([np.asarray(t) for t in trajs], axis=1), full_matrices=False)[0]
    given = fit_parametric_dmd(trajs, jnp.asarray(P), rank=5, basis=jnp.asarray(U_all[:, :6]))
    mu = jnp.asarray([rng.uniform(0, 2)])
    np.testing.assert_allclose(np.asarray(given.predict(mu, 10)), np.asarray(own.predict(mu, 10)), atol=1e-9)
