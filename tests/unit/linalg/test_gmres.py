"""Restarted GMRES (:mod:`jaxbelt.linalg.gmres`) against dense solves: its residual is the true one,
restarts and right preconditioning reach the same solution, and it batches under ``vmap``."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxbelt.linalg.gmres import BLOCK, gmres, gmres_affine


def _system(n=120, seed=0, spread=0.9):
    rng = np.random.default_rng(seed)
    A = np.eye(n) + spread * rng.standard_normal((n, n)) / np.sqrt(n)
    return A, rng.standard_normal(n)


@pytest.mark.parametrize("rtol", [1e-3, 1e-8, 1e-12])
def test_solution_meets_the_relative_residual_and_equals_a_dense_solve(rtol):
    A, b = _system()
    x, res, its = jax.jit(lambda b: gmres(lambda v: jnp.asarray(A) @ v, b, rtol=rtol, restart=100, max_cycles=4))(
        jnp.asarray(b))
    true = np.linalg.norm(A @ np.asarray(x) - b) / np.linalg.norm(b)
    assert true <= rtol and abs(float(res) - true) <= 1e-3 * rtol + 1e-15
    np.testing.assert_allclose(np.asarray(x), np.linalg.solve(A, b), rtol=0, atol=50 * rtol * np.abs(np.linalg.solve(A, b)).max())
    assert 0 < int(its) <= 100


def test_restarts_reach_the_tolerance_and_count_every_iteration():
    """A restart shorter than the iterations needed, and not a multiple of the basis block."""
    A, b = _system(spread=0.5)
    restart = BLOCK + 3
    x, res, its = gmres(lambda v: jnp.asarray(A) @ v, jnp.asarray(b), rtol=1e-10, restart=restart, max_cycles=30)
    assert float(res) <= 1e-10 and int(its) > restart
    np.testing.assert_allclose(np.asarray(x), np.linalg.solve(A, b), atol=1e-8)


def test_an_exact_right_preconditioner_solves_in_one_iteration_and_a_poor_one_still_converges():
    A, b = _system()
    Ainv = np.linalg.inv(A)
    x, res, its = gmres(lambda v: jnp.asarray(A) @ v, jnp.asarray(b), rtol=1e-10, restart=20,
                        precondition=lambda v: jnp.asarray(Ainv) @ v)
    assert int(its) == 1 and float(res) <= 1e-10
    D = np.diag(1.0 + np.arange(len(b)) / len(b))  # a scaling, unrelated to A
    x, res, _ = gmres(lambda v: jnp.asarray(A) @ v, jnp.asarray(b), rtol=1e-10, restart=100,
                      precondition=lambda v: jnp.asarray(D) @ v)
    np.testing.assert_allclose(np.asarray(x), np.linalg.solve(A, b), atol=1e-8)


def test_zero_right_hand_side_and_a_singular_consistent_system():
    A, _ = _system(n=40)
    x, res, its = gmres(lambda v: jnp.asarray(A) @ v, jnp.zeros(40), rtol=1e-8)
    assert np.all(np.asarray(x) == 0) and int(its) == 0 and float(res) == 0
    P = np.eye(40)
    P[-1, -1] = 0.0  # singular: the last component is invisible; b in the range
    b = np.r_[np.ones(39), 0.0]
    x, res, _ = gmres(lambda v: jnp.asarray(P) @ v, jnp.asarray(b), rtol=1e-10)
    assert float(res) <= 1e-10 and np.all(np.isfinite(np.asarray(x)))


def test_vmap_over_right_hand_sides_equals_one_at_a_time():
    A, _ = _system(n=60)
    B = np.random.default_rng(3).standard_normal((4, 60))
    solve = lambda b: gmres(lambda v: jnp.asarray(A) @ v, b, rtol=1e-9, restart=60)[0]  # noqa: E731
    X = jax.vmap(solve)(jnp.asarray(B))
    for k in range(4):
        np.testing.assert_allclose(np.asarray(X[k]), np.asarray(solve(jnp.asarray(B[k]))), atol=1e-10)
        np.testing.assert_allclose(np.asarray(X[k]), np.linalg.solve(A, B[k]), atol=1e-7)


def test_the_operator_is_traced_once_per_solve():
    """GMRES applies the operator at one place in its program (the restarts' true residuals and
    the Arnoldi vectors alike), and Newton linearises its map once per step: a compiled solve
    holds one copy of a linearised time-step map, not one per call site."""
    from jaxbelt.linalg.newton import newton_krylov

    A, b = _system()
    traced = []

    def matvec(v):
        traced.append("A")
        return jnp.asarray(A) @ v

    jax.make_jaxpr(lambda r: gmres(matvec, r, rtol=1e-8, restart=20, max_cycles=5))(jnp.asarray(b))
    assert traced == ["A"]

    def f(y):
        traced.append("f")
        return jnp.asarray(A) @ y + 0.1 * y ** 3 - jnp.asarray(b)

    y, rms, _, steps, _ = newton_krylov(f, jnp.zeros_like(jnp.asarray(b)), 1e-10, 20, 60, 4)
    assert traced.count("f") == 1 and float(rms) <= 1e-10 and int(steps) >= 2


def test_affine_gmres_equals_the_dense_solve_of_the_operator_it_is_given():
    """:func:`jaxbelt.linalg.gmres.gmres_affine`: ``A x = b`` known only through ``x, s ↦ A x − s b``;
    the relative residual is against ``‖b‖`` (the first true residual's norm), a zero ``b`` returns
    at once."""
    A, b = _system()
    Aj, bj = jnp.asarray(A), jnp.asarray(b)
    x, res, its = jax.jit(lambda: gmres_affine(lambda v, s: Aj @ v - s * bj, len(b), jnp.float64, rtol=1e-10,
                                               restart=100))()
    assert float(res) <= 1e-10 and abs(float(res) - np.linalg.norm(A @ np.asarray(x) - b) / np.linalg.norm(b)) < 1e-12
    np.testing.assert_allclose(np.asarray(x), np.linalg.solve(A, b), atol=1e-8)
    x0, res0, its0 = gmres_affine(lambda v, s: Aj @ v, len(b), jnp.float64, rtol=1e-10)
    assert np.all(np.asarray(x0) == 0) and int(its0) == 0 and float(res0) == 0


def test_newton_with_tangents_gives_the_root_and_the_implicit_derivatives():
    """:func:`jaxbelt.linalg.newton.newton_krylov_tangents` on ``f(y, θ) = A y + 0.1 y³ − B θ − c``:
    the root :func:`newton_krylov` finds, tangents equal to the dense implicit-function-theorem
    ``−(∂f/∂y)⁻¹ ∂f/∂θ`` at it, ``count`` of them (the rest NaN), ``f`` traced once."""
    from jaxbelt.linalg.newton import newton_krylov, newton_krylov_tangents

    A, c = _system(n=50, spread=0.5)
    B = np.random.default_rng(5).standard_normal((50, 3))
    traced = []

    def f(y, th):
        traced.append("f")
        return jnp.asarray(A) @ y + 0.1 * y ** 3 - jnp.asarray(B) @ th - jnp.asarray(c)

    theta = jnp.asarray([0.3, -0.2, 0.1])
    y, rms, _, steps, _, T, t_its = newton_krylov_tangents(f, jnp.zeros(50), theta, 1e-11, 20, 1e-11, 60, 4)
    assert traced == ["f"] and float(rms) <= 1e-11 and int(t_its) > 0
    y_alone = newton_krylov(lambda y: f(y, theta), jnp.zeros(50), 1e-11, 20, 60, 4)[0]
    np.testing.assert_allclose(np.asarray(y), np.asarray(y_alone), atol=1e-12)
    Jy = A + np.diag(0.3 * np.asarray(y) ** 2)
    np.testing.assert_allclose(np.asarray(T).T, np.linalg.solve(Jy, B), atol=1e-9)
    _, _, _, _, _, T2, _ = newton_krylov_tangents(f, jnp.zeros(50), theta, 1e-11, 20, 1e-11, 60, 4, count=2)
    np.testing.assert_allclose(np.asarray(T2[:2]), np.asarray(T[:2]), atol=1e-12)
    assert np.all(np.isnan(np.asarray(T2[2])))
