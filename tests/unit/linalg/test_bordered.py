"""The structured bordered block-cyclic solver against dense references.

The solves run jit-compiled, as inside a simulation (one program per shape instead of a few
hundred op-by-op compilations)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from helpers import load, random_bordered
from jaxbelt.assembly import dae_matrices
from jaxbelt.linalg import bordered_solve, dense_solve, join


solve = jax.jit(bordered_solve, static_argnums=3)


@pytest.mark.parametrize("method", ["thomas", "cyclic-reduction"])
@pytest.mark.parametrize("n,b,q", [(3, 1, 2), (12, 1, 4), (9, 4, 6), (20, 6, 18)])
def test_structured_equals_dense(n, b, q, method):
    A, rb, rr = random_bordered(n, b, q)
    xb, xr = solve(A, rb, rr, method)
    x_ref = jnp.linalg.solve(A.to_dense(), join(rb, rr))
    np.testing.assert_allclose(np.asarray(join(xb, xr)), np.asarray(x_ref), rtol=1e-10, atol=1e-12)


def test_matvec_and_transpose():
    A, rb, rr = random_bordered(7, 3, 5, seed=1)
    y = join(*A.matvec(rb, rr))
    np.testing.assert_allclose(np.asarray(y), np.asarray(A.to_dense() @ join(rb, rr)), rtol=1e-12)
    np.testing.assert_array_equal(np.asarray(A.transpose().to_dense()), np.asarray(A.to_dense().T))


def test_cyclic_reduction_equals_thomas_on_interiors():
    from jaxbelt.linalg.thomas import thomas_apply, thomas_factor
    from jaxbelt.linalg.cyclic_reduction import bcr_apply, bcr_factor

    rng = np.random.default_rng(5)
    for m in (1, 2, 5, 8, 103):
        D = jnp.asarray(rng.normal(size=(m, 4, 4)) + 8 * np.eye(4))
        L, U = jnp.asarray(rng.normal(size=(m, 4, 4))), jnp.asarray(rng.normal(size=(m, 4, 4)))
        r = jnp.asarray(rng.normal(size=(m, 4, 3)))
        np.testing.assert_allclose(np.asarray(jax.jit(lambda *a: bcr_apply(bcr_factor(*a[:3]), a[3]))(D, L, U, r)),
                                   np.asarray(jax.jit(lambda *a: thomas_apply(thomas_factor(*a[:3]), a[3]))(D, L, U, r)),
                                   rtol=1e-10, atol=1e-12)


def test_belt_matrix_structured_equals_dense():
    model, opts = load("two-roller-1d-train1")
    K, M = dae_matrices(model, model.m_e0)
    A = M + K.scale(opts.dt**2)
    rng = np.random.default_rng(2)
    rb, rr = jnp.asarray(rng.normal(size=(model.n_xi, 1))), jnp.asarray(rng.normal(size=4))
    dense = jax.jit(dense_solve)
    x1 = join(*solve(A, rb, rr, "thomas"))
    x2 = join(*dense(A, rb, rr))
    assert float(jnp.linalg.norm(x1 - x2) / jnp.linalg.norm(x2)) < 1e-10
    # also the static K (initial condition)
    x1 = join(*solve(K, rb, rr, "thomas"))
    x2 = join(*dense(K, rb, rr))
    assert float(jnp.linalg.norm(x1 - x2) / jnp.linalg.norm(x2)) < 1e-10


def test_gradient_through_structured_solve_matches_dense():
    A, rb, rr = random_bordered(8, 2, 3, seed=3)

    def loss(scale, solve):
        A2 = A + A.scale(scale)
        xb, xr = solve(A2, rb * (1 + scale), rr)
        return jnp.sum(xb**2) + jnp.sum(xr**3)

    g1 = jax.jit(jax.grad(loss), static_argnums=1)(0.1, bordered_solve)
    g2 = jax.jit(jax.grad(loss), static_argnums=1)(0.1, dense_solve)
    assert float(g1) == pytest.approx(float(g2), rel=1e-9)


def test_row_equilibration_conditions_the_belt_matrix():
    from jaxbelt.linalg.bordered import row_equilibrate
    from helpers import scene_with

    m, opts = load(scene_with(lambda d: d["mesh"].update(n_eta=3), "three-roller"))  # the shared coarse scene

    @jax.jit  # one program, not op by op
    def matrices(m, dt):
        K, M = dae_matrices(m, m.m_e0)
        A = M + K.scale(dt**2)
        As, _, _ = row_equilibrate(A, jnp.zeros((m.n_xi, m.block)), jnp.zeros(m.n_roller_dofs))
        return A.to_dense(), As.to_dense()

    A, As = matrices(m, opts.dt)
    c0, c1 = np.linalg.cond(np.asarray(A)), np.linalg.cond(np.asarray(As))  # 4.5e8, 1.1e4
    assert c0 > 1e8 and c1 < 2e4
