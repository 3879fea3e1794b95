"""Factorisation reuse: frozen factors, matrix-free products, agreement with the exact mode."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.assembly import dae_apply, dae_matrices, roller_R
from jaxbelt.linalg.bordered import bordered_solve, factor_solve, factorise
from helpers import scene_fixtures, scene_with

loaded, m, dt = scene_fixtures(lambda: scene_with(lambda d: d.setdefault("mesh", {}).update(n_eta=3),
                                                  "three-roller-t72"))


@pytest.fixture(scope="module")
def state4(m, dt):
    """The state after 9 steps (a whole number of checkpoint chunks: one compiled step; the run
    test_model2d.py and test_vmap.py compile for the same shapes)."""
    return jb.simulate(m, n_steps=9, dt=dt)[0]


def test_factor_solve_equals_structured_solve(m, dt):
    s = jb.initial_state(m)
    K, M = dae_matrices(m, s.m_e, roller_R(m, s.u))
    A = M + K.scale(dt**2)
    rng = np.random.default_rng(1)
    rb, rr = jnp.asarray(rng.normal(size=(m.n_xi, m.block))), jnp.asarray(rng.normal(size=m.n_roller_dofs))
    # jit-compiled, as inside a run (one program each, not op by op)
    x1 = jax.jit(lambda A, rb, rr: factor_solve(factorise(A), rb, rr))(A, rb, rr)
    x2 = jax.jit(bordered_solve)(A, rb, rr)
    for a, b in zip(x1, x2):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-9, atol=1e-12 * float(jnp.max(jnp.abs(b))))


@pytest.mark.reference
def test_matrix_free_products_equal_assembled(m, state4):
    s = state4
    R = roller_R(m, s.u)
    K, M = dae_matrices(m, s.m_e, R)
    rng = np.random.default_rng(2)
    xb, xr = jnp.asarray(rng.normal(size=(m.n_xi, m.block))), jnp.asarray(rng.normal(size=m.n_roller_dofs))
    (kb, kr), (mb, mr) = dae_apply(m, s.m_e, R, xb, xr)
    for got, want in zip((kb, kr, mb, mr), (*K.matvec(xb, xr), *M.matvec(xb, xr))):
        np.testing.assert_allclose(np.asarray(got), np.asarray(want), rtol=1e-12, atol=1e-12 * float(jnp.max(jnp.abs(want)) + 1))


def test_reuse_mode_tracks_exact_mode(m, dt):
    _, exact = jb.simulate(m, jb.make_solver("direct", "kept-interior"), n_steps=100, dt=dt)
    _, reuse = jb.simulate(m, jb.make_solver("direct", "reuse"), n_steps=100, dt=dt)
    rmse_u = float(jnp.sqrt(jnp.mean((exact.tracer_u - reuse.tracer_u) ** 2)))
    rmse_v = float(jnp.sqrt(jnp.mean((exact.tracer_v - reuse.tracer_v) ** 2)))
    assert rmse_u < 1e-12 and rmse_v < 1e-12  # m, i.e. < 1e-9 mm


def test_step_matrix_equals_M_plus_dt2_K(m, dt, state4):
    from jaxbelt.assembly import step_matrix

    s = state4
    R = roller_R(m, s.u)
    K, M = dae_matrices(m, s.m_e, R)
    np.testing.assert_allclose(np.asarray(step_matrix(m, s.m_e, R, dt).to_dense()),
                               np.asarray((M + K.scale(dt**2)).to_dense()), rtol=1e-14, atol=1e-18)
