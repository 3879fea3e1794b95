"""The border-first solve of a bordered block-cyclic matrix: the border's unknowns from the Green's
functions of its rows, then one sweep through the interior.

With the loop cut at block 0 (:mod:`jaxbelt.linalg.bordered`) the matrix is ``[T G; H Z]``: the
block-tridiagonal interior ``T`` (belt blocks ``1..n-1``), the border (block 0 and the roller
unknowns) with its columns ``G`` and rows ``H``, and the Schur complement
``S = Z - H T⁻¹ G``. :func:`~jaxbelt.linalg.bordered.factor_solve` solves it *interior first*,

$$ y = T^{-1} r,\\quad x_\\partial = S^{-1}(r_\\partial - H y),\\quad x = y - (T^{-1} G)\\, x_\\partial, $$

with ``T⁻¹ G`` kept. :func:`border_first_solve` solves it *border first*,

$$ x_\\partial = S^{-1}(r_\\partial - \\Phi r),\\quad x = T^{-1}(r - G x_\\partial),\\qquad \\Phi = H T^{-1}, $$

with the Green's functions ``Φ`` of the border rows kept instead (:func:`border_green`). Both are
exact and stream one sweep's factors per solve. On the belt ``Φ`` is small: block 0's rows see
only the free spans next to block 0 (``T`` decouples at the roller columns), and the roller rows
of the prescribed roller DOFs are zero, which leaves the few force- or torque-loaded ones; ``G``
is block 0's two neighbours and the roller columns ``C`` on the belt's roller columns.

**Why:** the exact step's matrix changes from one step to the next in the tilt columns of ``C``
only (the lever arm ``z + v``, model specification §4.2). Interior first, each step needs
``T⁻¹`` of the new columns — a sweep with one right-hand side per tilt — to keep ``T⁻¹ G``.
Border first, only the tilt columns of ``S`` change, by ``Φ`` times the new columns on the roller
columns: a small product (:func:`replace_border_columns`). The exact step then streams the same
bytes as a solve with frozen factors. Everything here is ``jnp``: it jit-compiles, vmaps and is
linear in the right-hand side, so the adjoint solve is its transpose
(:func:`border_first_solve_transposed`).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.linalg import lu_factor, lu_solve

from .bordered import (BorderedBlockCyclic, BorderedFactorisation, apply_interior, border_times, scale_rows,
                       to_interior)


class BorderFirstFactors(eqx.Module):
    """Factors of a row-equilibrated bordered block-cyclic matrix for :func:`border_first_solve`.

    **Fields:** ``row_b`` (n, b), ``row_r`` (q,) the row scales; ``interior`` the factors of ``T``
    (as :class:`~jaxbelt.linalg.bordered.BorderedFactorisation`'s); ``Phi_top`` (b, k₀, b) the
    Green's functions of block 0's rows on the interior blocks ``top_blocks`` (static; zero on the
    others); ``Phi_roll`` (r, n-1, b) those of the roller rows ``roll_rows`` (static; the other
    roller rows vanish); ``G0`` (2, b, b) the couplings of interior blocks 0 and n-2 to block 0;
    ``C_on`` (k, b, q) the roller columns on the interior blocks ``C_blocks`` (static; zero on the
    others); ``S_lu``, ``S_piv`` the LU of the (b + q)² Schur complement."""

    row_b: jax.Array
    row_r: jax.Array
    interior: eqx.Module
    Phi_top: jax.Array
    Phi_roll: jax.Array
    G0: jax.Array
    C_on: jax.Array
    S_lu: jax.Array
    S_piv: jax.Array
    top_blocks: tuple = eqx.field(static=True)
    roll_rows: tuple = eqx.field(static=True)
    C_blocks: tuple = eqx.field(static=True)


def border_green(F: BorderedFactorisation) -> jax.Array:
    """``Φ = H T⁻¹`` (b + q, n-1, b) of the factors ``F``: row ``i`` is how border row ``i`` of the
    Schur complement sees a unit entry of the interior. One transposed sweep with ``b + q``
    right-hand sides (the rows of ``H``)."""
    m, b = F.y_GR.shape[0], F.y_GR.shape[1]
    s = F.S_lu.shape[0]

    def seen_by_border_rows(c):  # (m, b) -> (s,): H T⁻¹ c
        return border_times(F.H, apply_interior(F.interior, c[:, :, None]), F.H_blocks)[:, 0]

    rows_T = jax.linear_transpose(seen_by_border_rows, jax.ShapeDtypeStruct((m, b), F.S_lu.dtype))
    return jax.vmap(lambda e: rows_T(e)[0])(jnp.eye(s, dtype=F.S_lu.dtype))


def border_first(F: BorderedFactorisation, A: BorderedBlockCyclic, roll_rows, column_blocks=None,
                 Phi: jax.Array | None = None) -> BorderFirstFactors:
    """The factors ``F`` of ``A`` (:func:`~jaxbelt.linalg.bordered.factorise`, chained or not)
    rearranged for :func:`border_first_solve`.

    **Arguments:** ``roll_rows`` (static) the roller rows of ``A.D`` that can be non-zero (the
    caller's guarantee that the others vanish: on the belt the dynamic roller DOFs);
    ``column_blocks`` (static) the interior blocks (belt column ``i`` is block ``i - 1``) where
    ``A.C`` can be non-zero (the belt's roller columns; ``None``: all); ``Phi``
    :func:`border_green` of ``F`` where the caller has it already."""
    n, b = A.n_blocks, A.block
    Phi = border_green(F) if Phi is None else Phi
    As = scale_rows(A, F.row_b, F.row_r)
    C_blocks = tuple(range(n - 1)) if column_blocks is None else tuple(int(k) for k in column_blocks)
    roll_rows = tuple(int(r) for r in roll_rows)
    return BorderFirstFactors(
        row_b=F.row_b, row_r=F.row_r, interior=F.interior,
        Phi_top=Phi[:b][:, np.asarray(F.y_G0_rows, int)], Phi_roll=Phi[b + np.asarray(roll_rows, int)],
        G0=jnp.stack([As.lower[1], As.upper[n - 1]]), C_on=As.C[1:][np.asarray(C_blocks, int)],
        S_lu=F.S_lu, S_piv=F.S_piv, top_blocks=tuple(F.y_G0_rows), roll_rows=roll_rows, C_blocks=C_blocks)


def replace_border_columns(F: BorderFirstFactors, S_ref: jax.Array, green: jax.Array, E: jax.Array, columns,
                           C_on, on_columns) -> BorderFirstFactors:
    """The exact border-first factors of a matrix that differs from ``F``'s only in the roller
    columns ``columns`` (static indices into the roller unknowns).

    **Arguments:** ``S_ref`` the unfactored Schur complement of ``F``'s matrix (its row scaling:
    :func:`~jaxbelt.linalg.bordered.scaled_schur`); ``green`` ``Φ`` on ``F.C_blocks``
    (b + q, len(C_blocks), b); ``E`` the roller block (unchanged); ``C_on`` (n_on, b, k) the new
    columns, unscaled, on the belt columns ``on_columns`` (static), zero elsewhere: they must hold
    column 0 and every column of ``F.C_blocks`` where the new columns are non-zero.

    Only the listed columns of ``S`` change, by ``Z_cols - Φ C_cols``: no sweep. The interior
    factors, the Green's functions and the row scales are ``F``'s (any positive row scaling factors
    the same system)."""
    b = F.G0.shape[1]
    on = [int(c) for c in on_columns]
    pos = {c: i for i, c in enumerate(on)}
    cols = jnp.asarray(columns, int)
    scaled = C_on * F.row_b[np.asarray(on, int)][:, :, None]
    padded = jnp.concatenate([scaled, jnp.zeros((1,) + scaled.shape[1:], scaled.dtype)])
    C0 = padded[pos.get(0, len(on))]  # (b, k): block 0's part, in the Schur complement's own block
    C_kept = padded[np.asarray([pos.get(k + 1, len(on)) for k in F.C_blocks], int)]  # (len(C_blocks), b, k)
    Z_cols = jnp.concatenate([C0, E[:, cols] * F.row_r[:, None]], axis=0)
    S = S_ref.at[:, b + cols].set(Z_cols - jnp.einsum("skb,kbc->sc", green, C_kept))
    S_lu, S_piv = lu_factor(S)
    C_all = F.C_on.at[:, :, cols].set(C_kept)
    return eqx.tree_at(lambda f: (f.C_on, f.S_lu, f.S_piv), F, (C_all, S_lu, S_piv))


def border_first_solve(F: BorderFirstFactors, rhs_belt, rhs_roll):
    """``A⁻¹ r`` border first (module docstring): ``(x_belt (n, b), x_roll (q,))``."""
    rb, rr = rhs_belt * F.row_b, rhs_roll * F.row_r
    b, q = rb.shape[1], rr.shape[0]
    r = rb[1:]
    m = r.shape[0]
    top = jnp.einsum("ikb,kb->i", F.Phi_top, r[np.asarray(F.top_blocks, int)])
    seen = jnp.einsum("ikb,kb->i", F.Phi_roll, r)
    pos = np.full(q, len(F.roll_rows))
    pos[np.asarray(F.roll_rows, int)] = np.arange(len(F.roll_rows))
    rolls = jnp.concatenate([seen, jnp.zeros(1, seen.dtype)])[pos]  # zero on the rows that vanish (no scatter)
    x_border = lu_solve((F.S_lu, F.S_piv), jnp.concatenate([rb[0], rr]) - jnp.concatenate([top, rolls]))
    x_0, x_roll = x_border[:b], x_border[b:]
    g = (to_interior(F.G0 @ x_0, (0, m - 1), m)
         + to_interior(jnp.einsum("kbq,q->kb", F.C_on, x_roll), F.C_blocks, m))
    x_int = apply_interior(F.interior, (r - g)[:, :, None])[:, :, 0]
    return jnp.concatenate([x_0[None], x_int], axis=0), x_roll


def border_first_solve_transposed(F: BorderFirstFactors, rhs_belt, rhs_roll):
    """``A⁻ᵀ r`` with the factors of ``A``: the transpose of :func:`border_first_solve` (it is
    linear in the right-hand side), no refactorisation."""
    spec = (jax.ShapeDtypeStruct(rhs_belt.shape, rhs_belt.dtype), jax.ShapeDtypeStruct(rhs_roll.shape, rhs_roll.dtype))
    return jax.linear_transpose(lambda rb, rr: border_first_solve(F, rb, rr), *spec)((rhs_belt, rhs_roll))
