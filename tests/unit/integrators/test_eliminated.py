"""Static condensation (:mod:`jaxbelt.integrators.eliminated`) on a coarse pre-tensioned
idle-translated 1D belt from a perturbed state with non-uniform masses, against numpy: the
condensed map ``x_e = g + P x_f`` satisfies the algebraic rows for any ``x_f``; ``M̂``, ``K̂`` are the
Schur-type combinations of the dense blocks; one step equals the dense Backward-Euler step of the
full DAE (``np.linalg.solve``); the recovered state puts ``x_f`` and ``x_e`` back in place."""

import jax
import numpy as np
import pytest

from jaxbelt.assembly import dae_matrices, dae_rhs
from jaxbelt.integrators.eliminated import EliminatedBackwardEuler, eliminated_system, recover_state
from jaxbelt.linalg import join
from helpers import perturbed_state, solve_step

DT = 0.004


@pytest.fixture(scope="module")
def state(model):
    return perturbed_state(model, seed=1)


@pytest.fixture(scope="module")
def dense(model, state):
    K, M = jax.jit(dae_matrices)(model, state.m_e)
    F = join(*dae_rhs(model, state.u, state.chi, DT))
    return np.asarray(K.to_dense()), np.asarray(M.to_dense()), np.asarray(F)


@pytest.fixture(scope="module")
def condensed(model, state):
    return [np.asarray(a) for a in jax.jit(eliminated_system)(model, state, DT)]


def test_partition_splits_every_unknown_once_into_dynamic_and_algebraic(model):
    f, e = model.partition
    assert sorted(f + e) == list(range(model.n_unknowns)) and len(f) and len(e)
    con = np.asarray(model.is_constraint).ravel()
    assert set(np.flatnonzero(con)) <= set(e)  # no-slip rows are algebraic


def test_condensed_map_satisfies_the_algebraic_rows_for_any_dynamic_values(model, dense, condensed):
    K, _, F = dense
    _, _, _, P, g, _ = condensed
    f, e = (np.asarray(i) for i in model.partition)
    for seed in range(3):
        x_f = np.random.default_rng(seed).standard_normal(len(f)) * 1e-4
        x = np.zeros(model.n_unknowns)
        x[f], x[e] = x_f, g + P @ x_f
        np.testing.assert_allclose(K[e] @ x, F[e], rtol=1e-9, atol=1e-9 * np.abs(F[e]).max() + 1e-12)


def test_condensed_matrices_are_the_block_combinations(model, dense, condensed):
    K, M, F = dense
    M_hat, K_hat, F_hat, P, g, p = condensed
    f, e = (np.asarray(i) for i in model.partition)
    np.testing.assert_allclose(P, -np.linalg.solve(K[np.ix_(e, e)], K[np.ix_(e, f)]), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(K_hat, K[np.ix_(f, f)] + K[np.ix_(f, e)] @ P, rtol=1e-9, atol=1e-6 * np.abs(K).max())
    np.testing.assert_allclose(M_hat, M[np.ix_(f, f)] + M[np.ix_(f, e)] @ P, rtol=1e-9, atol=1e-15)
    a_e0 = (g + P @ p[f] - p[e]) / DT ** 2
    np.testing.assert_allclose(F_hat, F[f] - K[np.ix_(f, e)] @ g - M[np.ix_(f, e)] @ a_e0, rtol=1e-9,
                               atol=1e-9 * np.abs(F_hat).max())


def test_step_equals_the_dense_backward_euler_step_of_the_full_dae(model, state, dense):
    K, M, F = dense
    x0, v0 = np.asarray(join(state.u, state.chi)), np.asarray(join(state.u_dot, state.chi_dot))
    a = np.linalg.solve(M + DT ** 2 * K, F - K @ (x0 + DT * v0))
    v_ref = v0 + DT * a
    x_ref = x0 + DT * v_ref
    s1 = solve_step(model, EliminatedBackwardEuler(), state, DT)
    np.testing.assert_allclose(np.asarray(join(s1.u, s1.chi)), x_ref, rtol=1e-9, atol=1e-10 * np.abs(x_ref).max())
    np.testing.assert_allclose(np.asarray(join(s1.u_dot, s1.chi_dot)), v_ref, rtol=1e-8,
                               atol=1e-9 * np.abs(v_ref).max())


def test_recover_state_places_both_parts_and_differences_the_algebraic_velocities(model, state):
    f, e = model.partition
    rng = np.random.default_rng(7)
    nf, ne = len(f), len(e)
    P, g = rng.standard_normal((ne, nf)), rng.standard_normal(ne)
    x_f, v_f = rng.standard_normal(nf), rng.standard_normal(nf)
    s1 = recover_state(state, DT, x_f, v_f, P, g, f, e)
    x1, v1 = np.asarray(join(s1.u, s1.chi)), np.asarray(join(s1.u_dot, s1.chi_dot))
    x0 = np.asarray(join(state.u, state.chi))
    np.testing.assert_array_equal(x1[list(f)], x_f)
    np.testing.assert_array_equal(v1[list(f)], v_f)
    np.testing.assert_allclose(x1[list(e)], g + P @ x_f, rtol=1e-13)
    np.testing.assert_allclose(v1[list(e)], (g + P @ x_f - x0[list(e)]) / DT, rtol=1e-12)
    np.testing.assert_array_equal(np.asarray(s1.m_e), np.asarray(state.m_e))
