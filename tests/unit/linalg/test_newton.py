"""Newton–Krylov on pytrees (:mod:`jaxbelt.linalg.newton`) against analytic roots and derivatives
(componentwise square roots, ``∂√θ/∂θ = 1/(2√θ)``) and numpy dense solves: the stopping rules (a
residual already within the tolerance costs no step, ``max_steps`` caps, a non-finite residual
stops), the ``missed`` flag of a linear solve, and NaN tangents where no root was reached."""

import jax
import jax.numpy as jnp
import numpy as np

from jaxbelt.linalg.newton import krylov_solve, newton_krylov, newton_krylov_tangents


def _spd(n, seed=0):
    rng = np.random.default_rng(seed)
    G = rng.standard_normal((n, n))
    return np.eye(n) + 0.3 * G @ G.T / n


def test_krylov_solve_of_a_pytree_system_equals_the_dense_solve():
    """Unknowns ``{"a": (3,), "b": (2, 2)}`` through a 7 × 7 matrix on their flattened vector."""
    A = _spd(7)
    rhs = {"a": jnp.asarray([1.0, -2.0, 0.5]), "b": jnp.asarray([[0.0, 3.0], [1.0, -1.0]])}
    flat = lambda t: jnp.concatenate([t["a"], t["b"].ravel()])  # noqa: E731 (ravel_pytree's key order)
    matvec = lambda t: (lambda v: {"a": v[:3], "b": v[3:].reshape(2, 2)})(jnp.asarray(A) @ flat(t))  # noqa: E731
    x, missed = jax.jit(lambda r: krylov_solve(matvec, r, rtol=1e-12, restart=10))(rhs)
    assert not bool(missed) and x["b"].shape == (2, 2)
    np.testing.assert_allclose(np.asarray(flat(x)), np.linalg.solve(A, np.asarray(flat(rhs))), rtol=1e-10)


def test_krylov_solve_flags_a_solve_that_ended_far_above_its_tolerance():
    """One cycle of two Krylov vectors on a 40-unknown system with a spread spectrum cannot reach
    1e-12: ``missed`` is set."""
    A = np.diag(np.linspace(1.0, 100.0, 40))
    b = jnp.ones(40)
    _, missed = krylov_solve(lambda v: jnp.asarray(A) @ v, b, rtol=1e-12, restart=2, cycles=1)
    assert bool(missed)


def _sqrt_problem(a):
    return lambda y: {"u": y["u"] ** 2 - a[:2], "w": y["w"] ** 2 - a[2]}


def test_newton_finds_the_componentwise_square_roots_of_a_pytree():
    a = jnp.asarray([4.0, 2.0, 9.0])
    y0 = {"u": jnp.asarray([1.0, 1.0]), "w": jnp.asarray(1.0)}
    y, rms, mx, steps, its = jax.jit(lambda y0: newton_krylov(_sqrt_problem(a), y0, 1e-12, 30, 5, 2))(y0)
    np.testing.assert_allclose(np.asarray(y["u"]), [2.0, np.sqrt(2.0)], rtol=1e-12)
    np.testing.assert_allclose(float(y["w"]), 3.0, rtol=1e-12)
    assert float(rms) <= 1e-12 and float(mx) <= np.sqrt(3) * float(rms) + 1e-300
    assert 3 <= int(steps) <= 10 and int(its) >= int(steps)  # Newton from 1: quadratic once near


def test_a_start_within_the_tolerance_takes_no_step():
    a = jnp.asarray([4.0, 2.0, 9.0])
    y0 = {"u": jnp.asarray([2.0, np.sqrt(2.0)]), "w": jnp.asarray(3.0)}
    y, rms, _, steps, its = newton_krylov(_sqrt_problem(a), y0, 1e-10, 30, 5, 2)
    assert int(steps) == 0 and int(its) == 0 and float(rms) <= 1e-10
    assert np.asarray(y["u"]).tolist() == np.asarray(y0["u"]).tolist()


def test_max_steps_caps_the_iteration_and_the_residual_reports_where_it_stopped():
    f = lambda y: y ** 2 - 100.0  # noqa: E731
    y, rms, mx, steps, _ = newton_krylov(f, jnp.ones(3), 1e-12, 2, 5, 2)
    # two Newton steps from 1 on y² = 100: 1 → 50.5 → 26.24…
    y1 = 0.5 * (1.0 + 100.0)
    y2 = 0.5 * (y1 + 100.0 / y1)
    assert int(steps) == 2
    np.testing.assert_allclose(np.asarray(y), y2, rtol=1e-10)
    np.testing.assert_allclose(float(rms), y2 ** 2 - 100.0, rtol=1e-10)
    np.testing.assert_allclose(float(mx), float(rms), rtol=1e-12)


def test_a_non_finite_residual_stops_the_iteration():
    f = lambda y: jnp.log(y) - 1.0  # noqa: E731  (NaN at negative y)
    _, rms, _, steps, its = newton_krylov(f, -jnp.ones(2), 1e-10, 20, 5, 2)
    assert int(steps) == 0 and int(its) == 0 and np.isnan(float(rms))


def test_tangents_equal_the_analytic_derivatives_of_the_root():
    """``f(y, θ) = y² − M θ`` (componentwise): ``y = √(Mθ)``, ``∂y/∂θ = diag(1/(2y)) M``."""
    M = np.array([[1.0, 0.5], [0.0, 2.0], [1.0, 1.0]])
    theta = jnp.asarray([3.0, 2.0])
    f = lambda y, th: y ** 2 - jnp.asarray(M) @ th  # noqa: E731
    y, rms, _, _, _, T, t_its = jax.jit(lambda th: newton_krylov_tangents(f, jnp.ones(3), th, 1e-12, 30, 1e-12, 5, 2))(
        theta)
    y_ref = np.sqrt(M @ np.asarray(theta))
    np.testing.assert_allclose(np.asarray(y), y_ref, rtol=1e-12)
    assert T.shape == (2, 3) and int(t_its) > 0
    np.testing.assert_allclose(np.asarray(T).T, M / (2 * y_ref[:, None]), rtol=1e-9)


def test_tangents_are_nan_without_a_root_or_when_none_is_asked_for():
    f = lambda y, th: y ** 2 - 100.0 * th[0]  # noqa: E731
    theta = jnp.asarray([1.0])
    *_, T, t_its = newton_krylov_tangents(f, jnp.ones(2), theta, 1e-12, 1, 1e-10, 5, 2)  # one step: no root
    assert np.all(np.isnan(np.asarray(T))) and int(t_its) == 0
    y, rms, *_, T0, t0 = newton_krylov_tangents(f, jnp.ones(2), theta, 1e-12, 30, 1e-10, 5, 2, count=0)
    assert float(rms) <= 1e-12 and np.all(np.isnan(np.asarray(T0))) and int(t0) == 0
    np.testing.assert_allclose(np.asarray(y), 10.0, rtol=1e-12)
