"""Exact DMD against a known linear system, PyDMD, and finite differences; metrics."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxbelt.rom import fit_dmd, rmse, rrmse
from jaxbelt.rom import BasisTrajectory, dmd_coordinates
from jaxbelt.rom.dmd import stack_trajectories


def _linear_system(n=8, seed=0):
    rng = np.random.default_rng(seed)
    lam = np.array([0.99, 0.95, 0.9 * np.exp(0.3j), 0.9 * np.exp(-0.3j), 0.7, 0.5, 0.3 * np.exp(1j), 0.3 * np.exp(-1j)])
    # a real matrix with these eigenvalues: real Schur-like blocks in a random basis
    B = np.zeros((n, n))
    i = 0
    blocks = [np.array([[0.99]]), np.array([[0.95]]),
              np.array([[0.9 * np.cos(0.3), -0.9 * np.sin(0.3)], [0.9 * np.sin(0.3), 0.9 * np.cos(0.3)]]),
              np.array([[0.7]]), np.array([[0.5]]),
              np.array([[0.3 * np.cos(1.0), -0.3 * np.sin(1.0)], [0.3 * np.sin(1.0), 0.3 * np.cos(1.0)]])]
    for blk in blocks:
        k = blk.shape[0]
        B[i:i + k, i:i + k] = blk
        i += k
    T = rng.normal(size=(n, n))
    A = T @ B @ np.linalg.inv(T)
    x = rng.normal(size=n)
    X = [x]
    for _ in range(40):
        X.append(A @ X[-1])
    return A, np.stack(X, axis=1), np.sort_complex(lam)


def test_recovers_exact_eigenvalues_of_a_linear_system():
    A, X, lam = _linear_system()
    model = fit_dmd(jnp.asarray(X))
    np.testing.assert_allclose(np.sort_complex(np.asarray(model.eigs)), lam, atol=1e-8)
    # and predicts the trajectory from any start snapshot
    pred = model.predict(jnp.asarray(X[:, 10]), 20)
    np.testing.assert_allclose(np.asarray(pred), X[:, 11:31].T, rtol=1e-6, atol=1e-8 * np.abs(X).max())


def test_matches_pydmd():
    pydmd = pytest.importorskip("pydmd")
    rng = np.random.default_rng(3)
    t = np.linspace(0, 4 * np.pi, 60)
    xs = np.linspace(-1, 1, 50)[:, None]
    X = np.cosh(xs) * np.cos(2.1 * t) + np.tanh(xs) * np.sin(0.7 * t) * np.exp(-0.05 * t) + 1e-3 * rng.normal(size=(50, 60))
    ref = pydmd.DMD(svd_rank=4, exact=True).fit(X)
    ours = fit_dmd(jnp.asarray(X), rank=4)
    order_ref, order_our = np.argsort(np.angle(ref.eigs)), np.argsort(np.angle(np.asarray(ours.eigs)))
    np.testing.assert_allclose(np.asarray(ours.eigs)[order_our], ref.eigs[order_ref], rtol=1e-9)
    for i, j in zip(order_our, order_ref):
        a, b = np.asarray(ours.modes)[:, i], ref.modes[:, j]
        cos = abs(np.vdot(a, b)) / (np.linalg.norm(a) * np.linalg.norm(b))
        assert cos == pytest.approx(1.0, abs=1e-9)  # same mode up to a complex scale


def test_multi_trajectory_stacking_fits_the_shared_operator():
    A, X1, lam = _linear_system(seed=0)
    rng = np.random.default_rng(7)
    x = rng.normal(size=8)
    X2 = [x]
    for _ in range(20):
        X2.append(A @ X2[-1])
    X, Y = stack_trajectories([jnp.asarray(X1[:, :10]), jnp.asarray(np.stack(X2, 1)[:, :10])])
    model = fit_dmd(X, Y)
    np.testing.assert_allclose(np.sort_complex(np.asarray(model.eigs)), lam, atol=1e-8)


def test_gradient_through_fit_and_predict_matches_finite_differences():
    A, X, _ = _linear_system()
    X = jnp.asarray(X[:, :25])
    E = jnp.asarray(np.random.default_rng(1).normal(size=X.shape))

    def loss(eps):
        m = fit_dmd(X + eps * E, rank=8)
        return jnp.sum(m.predict(X[:, 5], 10) ** 2)

    g = jax.jit(jax.grad(loss))(0.0)  # jit-compiled: one program each, not op by op
    loss = jax.jit(loss)
    h = 1e-6
    fd = (loss(h) - loss(-h)) / (2 * h)
    assert abs(float(g - fd)) < 1e-5 * abs(float(fd))


def test_observed_prediction_equals_projected_full_prediction():
    A, X, _ = _linear_system()
    m = fit_dmd(jnp.asarray(X))
    C = jnp.asarray(np.random.default_rng(2).normal(size=(3, 8)))
    full = m.predict(jnp.asarray(X[:, 0]), 12)
    np.testing.assert_allclose(np.asarray(m.predict(jnp.asarray(X[:, 0]), 12, observe=C)), np.asarray(full @ C.T), rtol=1e-10)


def test_stable_drops_growing_modes():
    m = fit_dmd(jnp.asarray(_linear_system()[1]))
    from jaxbelt.rom.dmd import DMDModel

    grown = DMDModel(jnp.concatenate([m.eigs, jnp.array([1.2 + 0j])]), jnp.concatenate([m.modes, m.modes[:, :1]], 1))
    kept = grown.stable()
    assert kept.eigs.shape[0] == m.eigs.shape[0]
    assert np.all(np.abs(np.asarray(kept.eigs)) <= 1 + 1e-5)  # what is kept is stable, not just as many
    np.testing.assert_allclose(np.sort_complex(np.asarray(kept.eigs)), np.sort_complex(np.asarray(m.eigs)))
    # the tolerance band: a mode at 1 + 1e-6 (the static offset's, from a fit) stays; 1 + 1e-4 goes
    edge = DMDModel(jnp.array([1.0 + 1e-6 + 0j, 1.0 + 1e-4 + 0j]), m.modes[:, :2])
    np.testing.assert_allclose(np.abs(np.asarray(edge.stable().eigs)), [1.0 + 1e-6])


def test_rmse_and_rrmse_definitions_on_hand_made_arrays():
    x = jnp.array([[1.0, 2.0], [3.0, 4.0]])
    y = jnp.array([[1.0, 2.5], [2.0, 4.0]])
    assert float(rmse(x, y)) == pytest.approx(np.sqrt((0.25 + 1.0) / 4))
    assert float(rrmse(x, y)) == pytest.approx(np.sqrt(1.25 / 30.0))
    np.testing.assert_allclose(np.asarray(rmse(x, y, axis=1)), [np.sqrt(0.25 / 2), np.sqrt(1.0 / 2)])


def test_dmd_coordinates_carry_the_prediction_in_an_orthonormal_basis():
    _, X, _ = _linear_system()
    Z = jnp.asarray(X[:, :30])
    model = fit_dmd(Z)
    traj = dmd_coordinates(Z, model, Z[:, -1], 10)
    assert isinstance(traj, BasisTrajectory)
    Q = np.asarray(traj.basis)
    np.testing.assert_allclose(Q.T @ Q, np.eye(Q.shape[1]), atol=1e-12)
    assert traj.coords.shape == (11, Q.shape[1])
    # row 0 the start, rows 1 … k the prediction, both as full states through the basis
    np.testing.assert_allclose(Q @ np.asarray(traj.coords[0]), X[:, 29], atol=1e-10)
    np.testing.assert_allclose(np.asarray(traj.coords[1:]) @ Q.T, np.asarray(model.predict(Z[:, -1], 10)),
                               rtol=1e-8, atol=1e-8)
    np.testing.assert_array_equal(np.asarray(traj.z_true0), X[:, 29])


def test_randomized_svd_matches_the_full_svd_on_a_low_rank_matrix():
    from jaxbelt.rom.dmd import randomized_svd

    rng = np.random.default_rng(5)
    X = rng.normal(size=(300, 12)) @ np.diag(np.logspace(0, -6, 12)) @ rng.normal(size=(12, 80))
    U, s, Vh = randomized_svd(jnp.asarray(X), 24)
    s_full = np.linalg.svd(X, compute_uv=False)
    np.testing.assert_allclose(np.asarray(s)[:12], s_full[:12], rtol=1e-9)
    np.testing.assert_allclose(np.asarray(U[:, :12] * s[:12]) @ np.asarray(Vh[:12]), X, atol=1e-12 * s_full[0])
    np.testing.assert_allclose(np.asarray(U.T @ U), np.eye(24), atol=1e-12)


def test_fit_dmd_randomized_equals_full_and_auto_falls_back_when_the_rank_fills_the_sketch():
    A, X, lam = _linear_system()
    # a long trajectory of a rank-8 system embedded in 200 dimensions: the sketch applies
    rng = np.random.default_rng(1)
    E = np.linalg.qr(rng.normal(size=(200, 8)))[0]
    Z = jnp.asarray(E @ X)
    full, rnd, auto = (fit_dmd(Z, svd=k) for k in ("full", "randomized", "auto"))
    for fit in (rnd, auto):
        np.testing.assert_allclose(np.sort_complex(np.asarray(fit.eigs)), np.sort_complex(np.asarray(full.eigs)),
                                   atol=1e-9)
        np.testing.assert_allclose(np.asarray(fit.predict(Z[:, 5], 10)), np.asarray(full.predict(Z[:, 5], 10)),
                                   atol=1e-9 * float(jnp.max(jnp.abs(Z))))
    # full rank (white noise, 120 pairs): the rank found fills the 48-column sketch, so auto takes the full SVD
    W = jnp.asarray(rng.normal(size=(150, 121)))
    assert fit_dmd(W).eigs.shape[0] == fit_dmd(W, svd="full").eigs.shape[0] == 120
    with pytest.raises(ValueError, match="svd"):
        fit_dmd(Z, svd="qr")
