"""Block Thomas elimination (:mod:`jaxbelt.linalg.thomas`) against numpy dense solves of the assembled
block-tridiagonal matrix: the plain sweeps, the one-sweep factor-and-solve, and the sweeps rearranged
along chains (dense or banded coupling) at the extreme break patterns; the chain and band
bookkeeping against hand-worked small cases."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from helpers import dense_block_tridiagonal
from jaxbelt.linalg.thomas import (band_diagonals, band_times, chain_thomas, chained_thomas_apply, elimination_chains,
                                   take_blocks, thomas_apply, thomas_factor)


def _blocks(m, b, seed=0, breaks=None, w=None):
    """Diagonally dominant block-tridiagonal blocks; rows of ``breaks`` have zero couplings, and a
    band ``w`` zeroes the couplings' entries more than ``w`` diagonals off the main one."""
    rng = np.random.default_rng(seed)
    diag = rng.standard_normal((m, b, b)) + 3.0 * b * np.eye(b)
    lower, upper = rng.standard_normal((2, m, b, b))
    if w is not None:
        i, j = np.indices((b, b))
        lower, upper = lower * (abs(i - j) <= w), upper * (abs(i - j) <= w)
    if breaks is not None:
        lower[breaks], upper[breaks] = 0.0, 0.0
    return diag, lower, upper


def _dense_solve(diag, lower, upper, r):
    m, b, k = r.shape
    return np.linalg.solve(dense_block_tridiagonal(diag, lower, upper), r.reshape(m * b, k)).reshape(m, b, k)


@pytest.mark.parametrize("m,b,k", [(1, 3, 1), (2, 2, 3), (9, 4, 2)])
def test_sweeps_equal_the_dense_solve(m, b, k):
    diag, lower, upper = _blocks(m, b, seed=m)
    r = np.random.default_rng(1).standard_normal((m, b, k))
    x = jax.jit(lambda *a: thomas_apply(thomas_factor(*a[:3]), a[3]))(diag, lower, upper, r)
    np.testing.assert_allclose(np.asarray(x), _dense_solve(diag, lower, upper, r), rtol=1e-12, atol=1e-13)


def test_blocks_outside_the_matrix_are_ignored():
    """``lower[0]`` and ``upper[-1]`` couple to blocks that do not exist."""
    diag, lower, upper = _blocks(5, 3, seed=2)
    r = np.random.default_rng(2).standard_normal((5, 3, 1))
    noisy_lower, noisy_upper = lower.copy(), upper.copy()
    noisy_lower[0], noisy_upper[-1] = 1e3, -1e3
    x = thomas_apply(thomas_factor(jnp.asarray(diag), jnp.asarray(noisy_lower), jnp.asarray(noisy_upper)), r)
    np.testing.assert_allclose(np.asarray(x), _dense_solve(diag, lower, upper, r), rtol=1e-12, atol=1e-13)


def test_factor_with_a_right_hand_side_solves_it_in_the_same_sweep():
    diag, lower, upper = _blocks(7, 3, seed=4)
    r = np.random.default_rng(4).standard_normal((7, 3, 4))
    F, x = jax.jit(thomas_factor)(diag, lower, upper, r)
    F0 = jax.jit(thomas_factor)(diag, lower, upper)
    np.testing.assert_allclose(np.asarray(x), _dense_solve(diag, lower, upper, r), rtol=1e-12, atol=1e-13)
    for a, b in zip(jax.tree.leaves(F), jax.tree.leaves(F0)):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(np.asarray(F.inv[0]), np.linalg.inv(diag[0]), rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("pattern", ["none", "all", "ends", "alternate"])
@pytest.mark.parametrize("band", [None, 1])
def test_chained_sweeps_equal_the_dense_solve_at_extreme_break_patterns(pattern, band):
    """No break (one chain through every block), every block a break (a block-diagonal matrix),
    breaks at both ends only, and every other block."""
    m, b = 8, 4
    breaks = {"none": np.zeros(m, bool), "all": np.ones(m, bool), "ends": np.isin(np.arange(m), [0, m - 1]),
              "alternate": np.arange(m) % 2 == 0}[pattern]
    diag, lower, upper = _blocks(m, b, seed=6, breaks=breaks, w=band)
    r = np.random.default_rng(6).standard_normal((m, b, 2))
    x = jax.jit(lambda *a: chained_thomas_apply(chain_thomas(thomas_factor(*a[:3]), breaks, band=band), a[3]))(
        diag, lower, upper, r)
    np.testing.assert_allclose(np.asarray(x), _dense_solve(diag, lower, upper, r), rtol=1e-12, atol=1e-13)


def test_elimination_chains_of_a_hand_worked_pattern():
    breaks = [True, False, False, True, True, False]
    assert elimination_chains(6, breaks, reverse=False) == [[0, 1, 2], [3], [4, 5]]
    assert elimination_chains(6, breaks, reverse=True) == [[5], [4], [3, 2, 1], [0]]  # a break starts a chain
    assert elimination_chains(3, [False] * 3, reverse=False) == [[0, 1, 2]]
    assert elimination_chains(3, [True] * 3, reverse=True) == [[2], [1], [0]]


def test_band_diagonals_of_a_hand_worked_block():
    L = jnp.asarray(np.arange(1.0, 10.0).reshape(3, 3))  # [[1 2 3] [4 5 6] [7 8 9]]
    d = np.asarray(band_diagonals(L, 1))
    np.testing.assert_array_equal(d, [[0.0, 4.0, 8.0], [1.0, 5.0, 9.0], [2.0, 6.0, 0.0]])  # [d + w, j] = L[j, j + d]
    np.testing.assert_array_equal(np.asarray(band_diagonals(L, 0)), [[1.0, 5.0, 9.0]])


@pytest.mark.parametrize("w", [0, 1, 2])
def test_band_times_equals_the_dense_product_of_a_banded_block(w):
    rng = np.random.default_rng(w)
    b = 6
    i, j = np.indices((b, b))
    L = rng.standard_normal((3, b, b)) * (abs(i - j) <= w)
    y = rng.standard_normal((3, b, 2))
    np.testing.assert_allclose(np.asarray(band_times(band_diagonals(jnp.asarray(L), w), jnp.asarray(y), w)), L @ y,
                               rtol=1e-14, atol=1e-14)


def test_take_blocks_equals_fancy_indexing_for_any_index_shape():
    a = jnp.asarray(np.random.default_rng(0).standard_normal((7, 2, 3)))
    for index in ([4], [[0, 6], [3, 3]], np.arange(6).reshape(3, 2, 1)):
        np.testing.assert_array_equal(np.asarray(take_blocks(a, index)), np.asarray(a)[np.asarray(index)])


def test_numpy_blocks_factor_outside_jit():
    diag, lower, upper = _blocks(4, 2, seed=5)
    r = np.random.default_rng(5).standard_normal((4, 2, 1))
    x = thomas_apply(thomas_factor(diag, lower, upper), r)
    np.testing.assert_allclose(np.asarray(x), _dense_solve(diag, lower, upper, r), rtol=1e-12, atol=1e-13)
