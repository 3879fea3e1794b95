"""The border-first solve (:mod:`jaxbelt.linalg.border_first`) against dense solves, on random
matrices with the belt's structure: roller columns that decouple the interior, roller columns
``C`` only on them, roller rows ``D`` only on them and their neighbours and only for some rows."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxbelt.linalg import BorderedBlockCyclic, join
from jaxbelt.linalg.border_first import (border_first, border_first_solve, border_first_solve_transposed,
                                         border_green, replace_border_columns)
from jaxbelt.linalg.bordered import factorise, scaled_schur, with_chained_interior

N, B, Q = 12, 3, 5
CONTACT = (0, 1, 5, 6, 9)  # belt columns on rollers
ROLL_ROWS = (1, 3)  # the roller rows that couple to the belt (the dynamic roller DOFs)
BLOCKS = tuple(c - 1 for c in CONTACT if c)  # their interior blocks


def belt_like(seed=0):
    rng = np.random.default_rng(seed)
    g = lambda *s: rng.normal(size=s)  # noqa: E731
    on = np.zeros(N, bool)
    on[list(CONTACT)] = True
    near = np.zeros(N, bool)
    for c in CONTACT:
        near[[(c - 1) % N, c, (c + 1) % N]] = True
    lower, upper = g(N, B, B), g(N, B, B)
    lower[on], upper[on] = 0.0, 0.0  # a roller column's rows couple to no other belt column
    C = g(N, B, Q) * on[:, None, None]
    D = g(N, Q, B) * near[:, None, None]
    D[:, [r for r in range(Q) if r not in ROLL_ROWS]] = 0.0
    A = BorderedBlockCyclic(diag=jnp.asarray(g(N, B, B) + 8 * np.eye(B)), lower=jnp.asarray(lower),
                            upper=jnp.asarray(upper), C=jnp.asarray(C), D=jnp.asarray(D),
                            E=jnp.asarray(g(Q, Q) + 8 * np.eye(Q)))
    return A, jnp.asarray(g(N, B)), jnp.asarray(g(Q))


def factors(A, interior):
    F = factorise(A, "cyclic-reduction" if interior == "cyclic-reduction" else "thomas")
    S = scaled_schur(A, F)
    if interior == "chained":
        F = with_chained_interior(F, CONTACT)
    return F, S


@pytest.mark.parametrize("interior", ["chained", "cyclic-reduction"])
def test_border_first_solve_and_its_transpose_equal_dense_solves(interior):
    A, rb, rr = belt_like()

    @jax.jit
    def solves(A, rb, rr):
        Fb = border_first(factors(A, interior)[0], A, ROLL_ROWS, BLOCKS)
        return join(*border_first_solve(Fb, rb, rr)), join(*border_first_solve_transposed(Fb, rb, rr))

    x, xT = solves(A, rb, rr)
    dense = np.asarray(A.to_dense())
    r = np.asarray(join(rb, rr))
    np.testing.assert_allclose(np.asarray(x), np.linalg.solve(dense, r), rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(np.asarray(xT), np.linalg.solve(dense.T, r), rtol=1e-11, atol=1e-12)


def test_border_rows_green_functions_are_h_times_the_interior_inverse():
    A, _, _ = belt_like(1)
    F, _ = factors(A, "thomas")
    Phi = np.asarray(jax.jit(border_green)(F))  # (b + q, n - 1, b), in the row scaling of F
    dense = np.asarray(A.to_dense())
    scale = np.concatenate([np.asarray(F.row_b).ravel(), np.asarray(F.row_r)])
    As = dense * scale[:, None]
    border = np.r_[np.arange(B), N * B + np.arange(Q)]
    interior = np.arange(B, N * B)
    H, T = As[np.ix_(border, interior)], As[np.ix_(interior, interior)]
    np.testing.assert_allclose(Phi.reshape(B + Q, -1), H @ np.linalg.inv(T), rtol=1e-10, atol=1e-12)


def test_replaced_border_columns_are_the_exact_factors_of_the_new_matrix():
    """Factors of a matrix whose roller columns 0 and 2 changed (on the roller columns), from the
    reference's without a sweep, solve the new matrix; the reference's factors do not."""
    A, rb, rr = belt_like(2)
    cols = (0, 2)
    rng = np.random.default_rng(5)
    C_on = jnp.asarray(rng.normal(size=(len(CONTACT), B, len(cols))))
    C_new = A.C.at[np.asarray(CONTACT)[:, None], :, np.asarray(cols)[None, :]].set(jnp.moveaxis(C_on, 2, 1))
    A_new = BorderedBlockCyclic(A.diag, A.lower, A.upper, C_new, A.D, A.E)

    @jax.jit
    def solves(A, C_on, rb, rr):
        F, S = factors(A, "chained")
        Phi = border_green(F)
        Fb = border_first(F, A, ROLL_ROWS, BLOCKS, Phi)
        F2 = replace_border_columns(Fb, S, Phi[:, np.asarray(BLOCKS)], A.E, cols, C_on, CONTACT)
        return join(*border_first_solve(F2, rb, rr)), join(*border_first_solve_transposed(F2, rb, rr)), \
            join(*border_first_solve(Fb, rb, rr))

    x, xT, x_ref = solves(A, C_on, rb, rr)
    dense = np.asarray(A_new.to_dense())
    r = np.asarray(join(rb, rr))
    np.testing.assert_allclose(np.asarray(x), np.linalg.solve(dense, r), rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(np.asarray(xT), np.linalg.solve(dense.T, r), rtol=1e-11, atol=1e-12)
    assert np.max(np.abs(np.asarray(x_ref) - np.linalg.solve(dense, r))) > 1e-3  # the test can fail


def test_kept_interior_names_its_border_updates():
    from jaxbelt.integrators import KeptInterior

    assert KeptInterior().border == "green"
    with pytest.raises(ValueError, match="'green' or 'sweep'"):
        KeptInterior(border="schur")
