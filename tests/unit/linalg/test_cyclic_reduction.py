"""Block cyclic reduction (:mod:`jaxbelt.linalg.cyclic_reduction`) against independent references: the
analytic solution of the discrete Poisson problem (scalar blocks), numpy dense solves of random
diagonally dominant block-tridiagonal systems of every parity of size, the level count ``⌈log₂ m⌉``,
and the derivative of a solve against the dense ``−A⁻¹ (∂A) x``."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from helpers import dense_block_tridiagonal
from jaxbelt.linalg.cyclic_reduction import bcr_apply, bcr_factor


def _blocks(m, b, seed=0):
    rng = np.random.default_rng(seed)
    return rng.standard_normal((m, b, b)) + 3.0 * b * np.eye(b), rng.standard_normal((m, b, b)), \
        rng.standard_normal((m, b, b))


solve = jax.jit(lambda d, lo, up, r: bcr_apply(bcr_factor(d, lo, up), r))


@pytest.mark.parametrize("m", [1, 2, 7, 16, 33])
def test_discrete_poisson_problem_has_the_parabola_as_its_solution(m):
    """``−x_{i−1} + 2 x_i − x_{i+1} = 1`` with ``x_0 = x_{m+1} = 0``: ``x_i = i (m + 1 − i) / 2``."""
    diag, off = np.full((m, 1, 1), 2.0), np.full((m, 1, 1), -1.0)
    x = solve(diag, off, off, np.ones((m, 1, 1)))
    i = np.arange(1, m + 1)
    np.testing.assert_allclose(np.asarray(x)[:, 0, 0], i * (m + 1 - i) / 2, rtol=1e-12)


@pytest.mark.parametrize("m", [3, 4, 5, 12, 17])
def test_solve_equals_the_dense_solve_and_ignores_the_outer_couplings(m):
    b, k = 3, 2
    diag, lower, upper = _blocks(m, b, seed=m)
    r = np.random.default_rng(m).standard_normal((m, b, k))
    ref = np.linalg.solve(dense_block_tridiagonal(diag, lower, upper), r.reshape(m * b, k)).reshape(m, b, k)
    lower[0], upper[-1] = 50.0, -50.0  # outside the matrix
    np.testing.assert_allclose(np.asarray(solve(diag, lower, upper, r)), ref, rtol=1e-11, atol=1e-12)


@pytest.mark.parametrize("m", [1, 2, 3, 8, 9, 100])
def test_levels_halve_the_block_count_down_to_one(m):
    diag, lower, upper = _blocks(m, 2)
    F = jax.jit(bcr_factor)(diag, lower, upper)
    assert len(F.levels) == (math.ceil(math.log2(m)) if m > 1 else 0)
    sizes = [m]
    while sizes[-1] > 2:
        sizes.append(-(-sizes[-1] // 2))
    assert F.sizes == (tuple(sizes) if m > 1 else ())
    assert F.last_inv.shape == (2, 2)


def test_factors_serve_many_right_hand_sides_and_batch_under_vmap():
    m, b = 6, 2
    diag, lower, upper = _blocks(m, b, seed=3)
    F = jax.jit(bcr_factor)(diag, lower, upper)
    R = np.random.default_rng(3).standard_normal((4, m, b, 1))
    X = jax.jit(jax.vmap(bcr_apply, in_axes=(None, 0)))(F, R)
    A = dense_block_tridiagonal(diag, lower, upper)
    for q in range(4):
        np.testing.assert_allclose(np.asarray(X[q]).ravel(), np.linalg.solve(A, R[q].ravel()), rtol=1e-11, atol=1e-12)


def test_derivative_of_a_solve_equals_the_dense_implicit_derivative():
    """``x(s) = A(s)⁻¹ r`` with ``A(s) = A + s E``: ``dx/ds = −A⁻¹ E x`` (reverse mode through the
    factorisation and the sweeps)."""
    m, b = 5, 2
    diag, lower, upper = _blocks(m, b, seed=8)
    E = np.random.default_rng(9).standard_normal((m, b, b))
    r = np.random.default_rng(10).standard_normal((m, b, 1))
    w = np.random.default_rng(11).standard_normal(m * b)

    def f(s):
        return jnp.asarray(w) @ bcr_apply(bcr_factor(diag + s * E, jnp.asarray(lower), jnp.asarray(upper)),
                                          r).reshape(-1)

    A, Ed = dense_block_tridiagonal(diag, lower, upper), dense_block_tridiagonal(E, 0 * E, 0 * E)
    x = np.linalg.solve(A, r.ravel())
    np.testing.assert_allclose(float(jax.jit(jax.grad(f))(0.0)), w @ -np.linalg.solve(A, Ed @ x), rtol=1e-10)


def test_numpy_blocks_factor_outside_jit():
    m, b = 5, 2
    diag, lower, upper = _blocks(m, b, seed=3)
    r = np.random.default_rng(3).standard_normal((m, b, 1))
    ref = np.linalg.solve(dense_block_tridiagonal(diag, lower, upper), r.reshape(m * b, 1)).reshape(m, b, 1)
    np.testing.assert_allclose(np.asarray(bcr_apply(bcr_factor(diag, lower, upper), r)), ref, rtol=1e-11, atol=1e-12)
