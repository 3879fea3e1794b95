"""Cyclic block-tridiagonal matrices bordered by roller unknowns (model specification §4).

With the unknowns ordered column by column along the belt, the DAE matrices have the form

$$
A = \\begin{bmatrix} B & C \\\\ D & E \\end{bmatrix},\\qquad
B = \\begin{bmatrix} A_0 & U_0 & & L_0 \\\\ L_1 & A_1 & U_1 & \\\\ & \\ddots & \\ddots & \\ddots \\\\
U_{n-1} & & L_{n-1} & A_{n-1} \\end{bmatrix}
$$

with ``n = n_xi`` blocks of size ``b`` (``b = 1`` in 1D, ``2 n_eta`` in 2D), cyclic because
the belt is a closed loop, and a border of ``q`` roller unknowns (``C``: belt rows × roller
columns, ``D``: roller rows × belt columns, ``E``: roller × roller).

:func:`bordered_solve` is exact and costs ``O(n b³ + n b² (b + q))``: the loop is cut at block
0, which joins the roller unknowns in a dense border of size ``s = b + q``; the remaining
``n - 1`` blocks form a plain block-tridiagonal matrix ``T``, factored by block cyclic reduction
(:mod:`jaxbelt.linalg.cyclic_reduction`, default: ``log₂ n`` batched levels) or block Thomas
elimination (a sequential ``lax.scan``); ``T⁻¹`` is applied to the ``s`` border columns and a
dense ``s × s`` Schur complement closes the system. :func:`factorise` keeps all of it, so
:func:`factor_solve` re-solves for a new right-hand side with matrix products only (the
factorisation-reuse integrator). :func:`refactorise_border` turns the factors of one matrix
into the exact factors of another that differs from it only in a few roller columns and rows
(what two Backward-Euler steps' matrices differ in under the shift transport: the exact
solver keeps its interior factors for the whole run), and
:class:`~jaxbelt.linalg.thomas.ChainedThomasFactors` (:mod:`jaxbelt.linalg.thomas`) runs
the Thomas sweeps along the chains the roller columns cut the interior into, all chains at
once. Everything is ordinary ``jnp`` code: it jit-compiles and vmaps. Derivatives do not go through the factorisation: :func:`bordered_solve` is a
``custom_linear_solve`` (:func:`solve_with_adjoint`) whose tangent solve and adjoint solve
(:func:`factor_solve_transposed`) reuse the step's factors, and whose matrix derivative comes from
the structured mat-vec — reverse mode costs one transposed solve per solve and keeps only the
factors. Neither interior method pivots across blocks; after row equilibration the belt blocks
of ``M + Δt² K`` are diagonally dominant (lumped mass plus stiffness, identity rows for the
no-slip constraints), which is what makes that safe.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax import lax
from jax.scipy.linalg import lu_factor, lu_solve

from .cyclic_reduction import CyclicReductionFactors, bcr_apply, bcr_factor
from .thomas import (ChainedThomasFactors, ThomasFactors, elimination_chains, chain_thomas, chained_thomas_apply,
                     chained_thomas_apply_sparse, thomas_apply, thomas_factor)


class BorderedBlockCyclic(eqx.Module):
    """Blocks of a bordered cyclic block-tridiagonal matrix (shapes in the module docstring).

    **Fields:** ``diag`` (n, b, b) = A[i, i]; ``lower`` (n, b, b) = A[i, i-1];
    ``upper`` (n, b, b) = A[i, i+1] (indices mod n); ``C`` (n, b, q); ``D`` (n, q, b); ``E`` (q, q).
    """

    diag: jax.Array
    lower: jax.Array
    upper: jax.Array
    C: jax.Array
    D: jax.Array
    E: jax.Array

    @property
    def n_blocks(self) -> int:
        return self.diag.shape[0]

    @property
    def block(self) -> int:
        return self.diag.shape[1]

    @property
    def n_border(self) -> int:
        return self.E.shape[0]

    @property
    def size(self) -> int:
        return self.n_blocks * self.block + self.n_border

    def __add__(self, other: "BorderedBlockCyclic") -> "BorderedBlockCyclic":
        return jax.tree.map(jnp.add, self, other)

    def scale(self, c) -> "BorderedBlockCyclic":
        return jax.tree.map(lambda a: c * a, self)

    def transpose(self) -> "BorderedBlockCyclic":
        """Aᵀ in the same format: block (i, i-1) of Aᵀ is U_{i-1}ᵀ, block (i, i+1) is L_{i+1}ᵀ."""
        tr = lambda a: jnp.swapaxes(a, -1, -2)
        return BorderedBlockCyclic(
            diag=tr(self.diag), lower=tr(jnp.roll(self.upper, 1, axis=0)),
            upper=tr(jnp.roll(self.lower, -1, axis=0)), C=tr(self.D), D=tr(self.C), E=self.E.T,
        )

    def matvec(self, x_belt: jax.Array, x_roll: jax.Array):
        """``A @ x`` for ``x = [x_belt (n, b); x_roll (q,)]``; returns the same split."""
        y = (
            jnp.einsum("nij,nj->ni", self.diag, x_belt)
            + jnp.einsum("nij,nj->ni", self.lower, jnp.roll(x_belt, 1, axis=0))
            + jnp.einsum("nij,nj->ni", self.upper, jnp.roll(x_belt, -1, axis=0))
            + jnp.einsum("niq,q->ni", self.C, x_roll)
        )
        z = _flat_roller_rows(self.D) @ x_belt.reshape(-1) + self.E @ x_roll
        return y, z

    def to_dense(self) -> jax.Array:
        """The full ``N × N`` matrix (tests and small models only)."""
        n, b, q = self.n_blocks, self.block, self.n_border
        nb = n * b
        idx = jnp.arange(n)
        A = jnp.zeros((n, n, b, b), self.diag.dtype)
        A = A.at[idx, idx].add(self.diag)
        A = A.at[idx, (idx - 1) % n].add(self.lower)
        A = A.at[idx, (idx + 1) % n].add(self.upper)
        Bm = A.transpose(0, 2, 1, 3).reshape(nb, nb)
        top = jnp.concatenate([Bm, self.C.reshape(nb, q)], axis=1)
        bot = jnp.concatenate([self.D.transpose(1, 0, 2).reshape(q, nb), self.E], axis=1)
        return jnp.concatenate([top, bot], axis=0)


def split(vec: jax.Array, n: int, b: int):
    """Split a flat vector of length ``n b + q`` into ``(belt (n, b), roller (q,))``."""
    return vec[: n * b].reshape(n, b), vec[n * b:]


def join(x_belt: jax.Array, x_roll: jax.Array) -> jax.Array:
    return jnp.concatenate([x_belt.reshape(-1), x_roll])


def row_equilibrate(A: BorderedBlockCyclic, rhs_belt, rhs_roll):
    """Scale every row by ``1 / max|row|`` (same solution, far better conditioning).

    The belt DAE mixes rows of very different size: Backward-Euler constraint rows are
    ``Δt²`` times unit coefficients, stiffness rows ``~EA/ℓ``, roller rows ``r EA``. On the
    small three-roller scene row scaling brings the condition number of ``M + Δt² K`` from
    3e8 to 1e4 (``tests/unit/linalg/test_bordered.py``)."""
    absmax = lambda a, axes: jnp.max(jnp.abs(a), axis=axes)
    rb = jnp.maximum(jnp.maximum(absmax(A.diag, 2), jnp.maximum(absmax(A.lower, 2), absmax(A.upper, 2))),
                     absmax(A.C, 2) if A.C.shape[2] else 0.0)
    rr = jnp.maximum(jnp.max(jnp.abs(A.D), axis=(0, 2)), absmax(A.E, 1)) if A.E.shape[0] else jnp.zeros(0)
    sb, sr = 1.0 / jnp.where(rb > 0, rb, 1.0), 1.0 / jnp.where(rr > 0, rr, 1.0)
    As = BorderedBlockCyclic(diag=A.diag * sb[:, :, None], lower=A.lower * sb[:, :, None],
                             upper=A.upper * sb[:, :, None], C=A.C * sb[:, :, None],
                             D=A.D * sr[None, :, None], E=A.E * sr[:, None])
    return As, rhs_belt * sb, rhs_roll * sr


class BorderedFactorisation(eqx.Module):
    """Factors of a row-equilibrated bordered block-cyclic matrix, for repeated solves.

    ``interior``: factors of the block-tridiagonal interior ``T`` (cyclic reduction or Thomas);
    ``T⁻¹ G`` for the border columns in two parts: ``y_G0`` (k0, b, b), block 0's columns on the
    interior blocks ``y_G0_rows`` (static; zero on the others), and ``y_GR`` (n-1, b, q), the
    roller columns; the border rows' couplings to the interior ``H = (U_0, L_0, D[1:] flattened)``
    (row-equilibrated; :func:`border_times`), and the LU of the ``(b + q)²`` Schur complement.
    A solve with them costs ``O(n b (b + q))``; they are all that reverse mode keeps per step for
    the adjoint solve.

    ``y_G0_rows``: all interior blocks after :func:`factorise`; :func:`with_chained_interior`
    narrows them to the free spans next to block 0, where ``T⁻¹`` of block 0's columns can be
    non-zero (``T`` decouples at the roller columns). On ``three-roller-t72`` that is 22 of the
    103 blocks: the solve then streams 0.8 MB of ``T⁻¹ G`` per step instead of 1.6 MB.

    ``y_G_cols`` (n-1, b, k) with the static ``y_G_index`` (k roller columns): columns of ``y_GR``
    that are replaced (:func:`refactorise_border`). Kept apart, the per-step factors of the exact
    mode hold only the k changed columns — ``y_GR`` stays the run's reference array, shared by
    every step and every configuration of a ``vmap`` batch — instead of a fresh copy per step,
    which reverse mode stores or recomputes.

    ``H_blocks`` (static): the interior blocks the roller rows of ``H`` are kept on (empty: all).
    :func:`with_chained_interior` narrows them to the roller columns and their neighbours, the only
    belt columns a roller's force and torque balance couples to (the roller rows are ``Rᵀ`` times
    belt rows, and ``R`` is zero off the rollers): on ``three-roller-t72`` 26 of the 103 blocks, a
    quarter of the (q, (n-1) b) matrix, which a solve streams in full otherwise."""

    row_b: jax.Array
    row_r: jax.Array
    interior: CyclicReductionFactors | ThomasFactors | ChainedThomasFactors
    y_G0: jax.Array
    y_GR: jax.Array
    H: tuple
    S_lu: jax.Array
    S_piv: jax.Array
    y_G_cols: jax.Array | None = None
    y_G_index: tuple = eqx.field(static=True, default=())
    y_G0_rows: tuple = eqx.field(static=True, default=())
    H_blocks: tuple = eqx.field(static=True, default=())


def to_interior(v, rows, m):
    """Values ``v`` (k, ...) on the interior blocks ``rows`` (static) as (m, ...), zero elsewhere —
    by a gather from ``[v; 0]`` (no scatter)."""
    if tuple(rows) == tuple(range(m)):
        return v
    pos = np.full(m, len(rows))
    pos[np.asarray(rows, int)] = np.arange(len(rows))
    return jnp.concatenate([v, jnp.zeros((1,) + v.shape[1:], v.dtype)])[pos]


def _effective_y_G(F: BorderedFactorisation) -> jax.Array:
    """``T⁻¹ G`` of ``F`` as one (n-1, b, b + q) array (its replaced columns included)."""
    y_R = F.y_GR
    if F.y_G_index:
        y_R = y_R.at[:, :, np.asarray(F.y_G_index)].set(F.y_G_cols)
    return jnp.concatenate([to_interior(F.y_G0, F.y_G0_rows, y_R.shape[0]), y_R], axis=2)


def apply_interior(F, rhs, support=()):
    """``T⁻¹ rhs`` (m, b, k) with the interior factors ``F``; ``support``: per column of ``rhs`` the
    blocks it can be non-zero on (static, optional), which the chained sweeps use to skip the
    chains a column cannot reach (:func:`~jaxbelt.linalg.thomas.chained_thomas_apply_sparse`)."""
    if isinstance(F, ChainedThomasFactors):
        return chained_thomas_apply_sparse(F, rhs, support) if support else chained_thomas_apply(F, rhs)
    return bcr_apply(F, rhs) if isinstance(F, CyclicReductionFactors) else thomas_apply(F, rhs)


def with_chained_interior(F: BorderedFactorisation, contact_columns, band: int | None = None) -> BorderedFactorisation:
    """``F`` with its Thomas interior rearranged along chains (:class:`ChainedThomasFactors`),
    the breaks at the belt's roller columns ``contact_columns`` (static; column ``i`` is interior
    block ``i - 1``), and ``y_G0`` narrowed to the free spans next to block 0 (the only blocks
    where ``T⁻¹`` of block 0's columns is non-zero: a roller column's rows couple to no belt
    column, so ``T`` decouples there; the dropped entries are exact zeros), and the roller rows of
    ``H`` narrowed to the roller columns and their neighbours (``H_blocks``; the roller rows
    ``D`` must vanish elsewhere, as the belt's do). ``band``: the interior's coupling blocks
    ``L_i`` vanish beyond that many diagonals off their main one (the model's
    ``coupling_band``): the forward sweep keeps them banded
    (:class:`~jaxbelt.linalg.thomas.ChainedThomasFactors`); ``None``: dense. Unchanged for a
    cyclic-reduction interior or unknown columns."""
    if not isinstance(F.interior, ThomasFactors) or contact_columns is None:
        return F
    m = F.interior.inv.shape[0]
    on = set(int(c) for c in contact_columns)
    breaks = [(k + 1) in on for k in range(m)]
    rows = _spans_through(breaks, (0, m - 1))
    y_G0 = to_interior(F.y_G0, F.y_G0_rows, m)[np.asarray(rows, int)]
    H_blocks = roller_row_blocks(contact_columns, m + 1)
    H = (F.H[0], F.H[1], _narrow_roller_rows(F.H[2], F.H_blocks, H_blocks, F.y_G0.shape[1]))
    return dataclasses.replace(F, interior=chain_thomas(F.interior, breaks, band), y_G0=y_G0, y_G0_rows=rows, H=H,
                               H_blocks=H_blocks)


def roller_row_blocks(contact_columns, n: int) -> tuple:
    """The interior blocks (column ``i`` is block ``i - 1``; column 0 is the border's) that the
    roller rows ``D`` can couple to: the roller columns ``contact_columns`` and their neighbours
    (``Rᵀ K_f`` reaches one column past the contact), of an ``n``-column belt loop."""
    near = {(int(c) + d) % n for c in contact_columns for d in (-1, 0, 1)}
    return tuple(sorted(c - 1 for c in near if c != 0))


def _narrow_roller_rows(D_flat, blocks_from, blocks_to, b):
    """Roller rows ``D_flat`` (q, len(blocks_from) b) kept on ``blocks_from`` (empty: all), narrowed
    to ``blocks_to`` (a subset)."""
    q = D_flat.shape[0]
    D = D_flat.reshape(q, -1, b)
    pos = {k: i for i, k in enumerate(blocks_from or range(D.shape[1]))}
    return D[:, np.asarray([pos[k] for k in blocks_to], int)].reshape(q, -1)


def _spans_through(breaks, blocks):
    """The interior blocks of the free spans (the non-break blocks of a chain, :func:`elimination_chains`)
    that contain any of ``blocks``."""
    out = set()
    for chain in elimination_chains(len(breaks), breaks, reverse=False):
        span = [i for i in chain if not breaks[i]]
        if any(j in span for j in blocks):
            out.update(span)
    return tuple(sorted(out))


def _border_parts(A):
    """Couplings of the interior blocks ``1..n-1`` to the border (block 0 + rollers): ``G``
    (interior rows × border columns, (n-1, b, s)), ``Z`` (border × border). The border rows'
    couplings ``H`` are used in sparse form (:func:`border_times`)."""
    n, b = A.n_blocks, A.block
    zero = jnp.zeros((n - 1, b, b), A.diag.dtype)
    G0 = zero.at[0].add(A.lower[1]).at[n - 2].add(A.upper[n - 1])
    G = jnp.concatenate([G0, A.C[1:]], axis=2)
    Z = jnp.block([[A.diag[0], A.C[0]], [A.D[0], A.E]])
    return G, Z


def _border_rows(A):
    """``H``, the border rows' couplings to the interior blocks ``1..n-1``, in sparse form: block
    0's rows see interior blocks 1 and n-1 only (``U_0``, ``L_0``), the roller rows see ``D``
    (:func:`_flat_roller_rows`)."""
    return A.upper[0], A.lower[0], _flat_roller_rows(A.D[1:])


def _flat_roller_rows(D):
    """The roller rows' couplings ``D`` (n-1, q, b) as one (q, (n-1) b) matrix: ``D Y`` is then
    a single matrix-vector product (an einsum over the block index is several times slower on a
    CPU)."""
    return jnp.transpose(D, (1, 0, 2)).reshape(D.shape[1], -1)


def border_times(H, Y, blocks=()):
    """``H Y`` for interior values ``Y`` (n-1, b, k) without forming ``H`` (:func:`_border_rows`);
    ``blocks``: the interior blocks ``H``'s roller rows are kept on (empty: all)."""
    U0, L0, D_flat = H
    top = U0 @ Y[0] + L0 @ Y[-1]
    Yr = Y[np.asarray(blocks, int)] if blocks else Y
    rollers = D_flat @ Yr.reshape(-1, Y.shape[-1])
    return jnp.concatenate([top, rollers], axis=0)


def default_interior_method() -> str:
    """Block Thomas on CPU, cyclic reduction on accelerators.

    On a CPU, XLA runs small batched inverses slowly enough that cyclic reduction's extra work
    does not pay (the 2D solver benchmark times both); on a GPU the sequential chain is the
    bottleneck."""
    return "thomas" if jax.default_backend() == "cpu" else "cyclic-reduction"


def factorise(A: BorderedBlockCyclic, method: str | None = None) -> BorderedFactorisation:
    """Factor ``A`` (after row equilibration, ``n >= 3`` blocks) for :func:`factor_solve`.

    ``method``: ``"thomas"`` (sequential ``lax.scan``) or ``"cyclic-reduction"`` (``log₂ n``
    batched levels); default :func:`default_interior_method`."""
    method = method or default_interior_method()
    n, b = A.n_blocks, A.block
    As, row_b, row_r = row_equilibrate(A, jnp.ones((n, b)), jnp.ones(A.n_border))  # scales = scaled ones
    G, Z = _border_parts(As)
    if method == "cyclic-reduction":
        interior = bcr_factor(As.diag[1:], As.lower[1:], As.upper[1:])
        y_G = bcr_apply(interior, G)
    else:
        interior, y_G = thomas_factor(As.diag[1:], As.lower[1:], As.upper[1:], G)
    H = _border_rows(As)
    S_lu, S_piv = lu_factor(Z - border_times(H, y_G))
    return BorderedFactorisation(row_b, row_r, interior, y_G[:, :, :b], y_G[:, :, b:], H, S_lu, S_piv,
                                 y_G0_rows=tuple(range(n - 1)))


def scaled_schur(A: BorderedBlockCyclic, F: BorderedFactorisation) -> jax.Array:
    """The (unfactored) ``(b + q)²`` Schur complement ``Z - H T⁻¹ G`` of ``A`` in ``F``'s row
    scaling (:func:`refactorise_border` updates it)."""
    G, Z = _border_parts(scale_rows(A, F.row_b, F.row_r))
    return Z - border_times(F.H, _effective_y_G(F), F.H_blocks)


def scale_rows(A: BorderedBlockCyclic, row_b, row_r) -> BorderedBlockCyclic:
    return BorderedBlockCyclic(diag=A.diag * row_b[:, :, None], lower=A.lower * row_b[:, :, None],
                               upper=A.upper * row_b[:, :, None], C=A.C * row_b[:, :, None],
                               D=A.D * row_r[None, :, None], E=A.E * row_r[:, None])


def refactorise_border(A: BorderedBlockCyclic, F_ref: BorderedFactorisation, S_ref: jax.Array,
                       columns=(), rows=(), column_blocks=()) -> BorderedFactorisation:
    """Exact factors of ``A`` from those of a matrix ``A_ref`` that differs from it in a few
    roller columns and rows only.

    Precondition (the caller's to guarantee): ``A`` equals ``A_ref`` — factored in ``F_ref``,
    ``S_ref = scaled_schur(A_ref, F_ref)`` — except in the roller columns ``C[:, :, columns]``
    and the roller rows ``D[:, rows, :]`` (static index tuples into the roller unknowns); ``E``
    must be the same. Then the interior factors ``T⁻¹`` are those of ``A`` too, ``T⁻¹ G``
    changes in the listed columns only (one sweep with the kept factors over ``len(columns)``
    right-hand sides) and the Schur complement in the listed columns and rows only; the rest is
    ``F_ref``'s. The rows keep ``F_ref``'s equilibration scales (any positive row scaling
    factors the same system). The result is the exact factorisation of ``A``:
    :func:`factor_solve` with it solves ``A x = r`` to round-off (``tests/unit/linalg/test_bordered.py``
    checks it against :func:`factorise`). For the belt on rollers with tilt DOFs, whose lever
    arm moves with the lateral displacement (§4.2) while nothing else in ``M + Δt² K`` changes
    under the shift transport, this is the whole difference between two steps' matrices
    (:class:`jaxbelt.integrators.DirectBackwardEuler`).

    ``column_blocks`` (static, optional): per listed column, the interior blocks (column ``i`` of
    the belt is block ``i - 1``) where it can be non-zero — a tilt's column lives on its roller's
    columns — so that the sweep over them skips the chains they cannot reach
    (:func:`~jaxbelt.linalg.thomas.chained_thomas_apply_sparse`); empty: anywhere."""
    b = A.block
    row_b, row_r = F_ref.row_b, F_ref.row_r
    cols, rws = jnp.asarray(columns, int), jnp.asarray(rows, int)
    C = A.C[:, :, cols] * row_b[:, :, None]  # (n, b, k) changed roller columns, scaled
    D = A.D * row_r[None, :, None]
    blocks = F_ref.H_blocks
    H = (F_ref.H[0], F_ref.H[1], _flat_roller_rows(D[1:][np.asarray(blocks, int)] if blocks else D[1:]))
    if F_ref.y_G_index:
        raise ValueError("refactorise_border: F_ref must be a reference factorisation (no replaced columns)")
    S = S_ref
    y_new = None
    if len(columns):
        y_new = apply_interior(F_ref.interior, C[1:], column_blocks)
        Z_cols = jnp.concatenate([C[0], A.E[:, cols] * row_r[:, None]], axis=0)
        S = S.at[:, b + cols].set(Z_cols - border_times(H, y_new, blocks))
    if len(rows):
        Z_rows = jnp.concatenate([D[0, rws], A.E[rws] * row_r[rws, None]], axis=1)
        H_r = H[2][rws].reshape(len(rows), -1, b)  # (k, blocks, b)
        kept = blocks or tuple(range(A.n_blocks - 1))
        rows0 = {k: i for i, k in enumerate(F_ref.y_G0_rows)}
        both = [k for k in kept if k in rows0]  # the blocks where both H's rows and T⁻¹ G₀ can be non-zero
        H_r0 = H_r[:, np.asarray([kept.index(k) for k in both], int)].reshape(len(rows), -1)
        Y0 = F_ref.y_G0[np.asarray([rows0[k] for k in both], int)]
        y_R = F_ref.y_GR if y_new is None else F_ref.y_GR.at[:, :, cols].set(y_new)
        y_R = y_R[np.asarray(blocks, int)] if blocks else y_R
        HY = jnp.concatenate([H_r0 @ Y0.reshape(-1, b), H_r.reshape(len(rows), -1) @ y_R.reshape(-1, y_R.shape[-1])],
                             axis=1)
        S = S.at[b + rws, :].set(Z_rows - HY)
    S_lu, S_piv = lu_factor(S)
    return BorderedFactorisation(row_b, row_r, F_ref.interior, F_ref.y_G0, F_ref.y_GR, H, S_lu, S_piv,
                                 y_new, tuple(int(c) for c in columns) if y_new is not None else (),
                                 F_ref.y_G0_rows, blocks)


def factor_solve(F: BorderedFactorisation, rhs_belt, rhs_roll):
    """Solve with the factors: exact for the factored matrix, a preconditioner for a nearby one."""
    rb, rr = rhs_belt * F.row_b, rhs_roll * F.row_r
    b = rb.shape[1]
    y_r = apply_interior(F.interior, rb[1:, :, None])[:, :, 0]
    x_border = lu_solve((F.S_lu, F.S_piv), jnp.concatenate([rb[0], rr]) - border_times(F.H, y_r[:, :, None], F.H_blocks)[:, 0])
    x_0, x_roll = x_border[:b], x_border[b:]
    m = y_r.shape[0]
    x_int = y_r - to_interior(jnp.einsum("nbs,s->nb", F.y_G0, x_0), F.y_G0_rows, m)
    if F.y_G_index:  # the replaced roller columns from y_G_cols, the rest from y_GR
        idx = np.asarray(F.y_G_index)
        keep = np.ones(x_roll.shape[0])
        keep[idx] = 0.0
        x_int = (x_int - jnp.einsum("nbs,s->nb", F.y_GR, x_roll * keep)
                 - jnp.einsum("nbs,s->nb", F.y_G_cols, x_roll[idx]))
    else:
        x_int = x_int - jnp.einsum("nbs,s->nb", F.y_GR, x_roll)
    return jnp.concatenate([x_border[None, :b], x_int], axis=0), x_roll


def factor_solve_transposed(F: BorderedFactorisation, rhs_belt, rhs_roll):
    """Solve ``Aᵀ x = r`` with the factors of ``A`` (the adjoint solve; no refactorisation).

    :func:`factor_solve` is linear in its right-hand side, so its transpose — ``jax.linear_transpose``
    of the same sweeps, run backwards: the interior's reversed Thomas/cyclic-reduction scans,
    the Schur complement's transposed LU and the row scales last — applies ``(A⁻¹)ᵀ = A⁻ᵀ``."""
    spec = (jax.ShapeDtypeStruct(rhs_belt.shape, rhs_belt.dtype), jax.ShapeDtypeStruct(rhs_roll.shape, rhs_roll.dtype))
    return jax.linear_transpose(lambda rb, rr: factor_solve(F, rb, rr), *spec)((rhs_belt, rhs_roll))


def solve_with_adjoint(matvec, rhs_belt, rhs_roll, solve, solve_transposed):
    """``x = A⁻¹ r`` by ``solve``, differentiated by the implicit-function rule, not through ``solve``.

    ``matvec(x_b, x_r) = A x`` carries the dependence of ``A`` on the parameters;
    ``solve(matvec, r_b, r_r)`` applies ``A⁻¹`` and ``solve_transposed(vecmat, r_b, r_r)``
    ``A⁻ᵀ`` (``vecmat = Aᵀ ·``, for refinement; each gets the product it may use as its first
    argument). Forward mode solves ``A ẋ = ṙ - Ȧ x``, reverse mode ``Aᵀ λ = x̄`` and pulls
    ``-λ xᵀ`` back through ``matvec``; whatever the solves close over (factors) is a constant,
    never differentiated (``jax.lax.custom_linear_solve``). The right-hand side goes in as one
    flat vector: ``custom_linear_solve`` fails on a tangent that is zero in one part only (a
    right-hand side whose belt rows do not depend on the parameters, e.g. the first step from
    a fixed state)."""
    n, b = rhs_belt.shape

    def flat(f):
        return lambda op, r: join(*f(lambda xb, xr: split(op(join(xb, xr)), n, b), *split(r, n, b)))

    x = lax.custom_linear_solve(lambda v: join(*matvec(*split(v, n, b))), join(rhs_belt, rhs_roll),
                                solve=flat(solve), transpose_solve=flat(solve_transposed))
    return split(x, n, b)


def bordered_solve(A: BorderedBlockCyclic, rhs_belt: jax.Array, rhs_roll: jax.Array,
                   method: str | None = None):
    """Exact solve of ``A x = r`` exploiting the structure (module docstring).

    Differentiable at the cost of solves: :func:`factorise` runs once, on ``stop_gradient(A)``;
    the derivative comes from :func:`solve_with_adjoint`, the adjoint solve reuses the same
    factors (:func:`factor_solve_transposed`).

    **Arguments:** ``A``; ``rhs_belt`` (n, b); ``rhs_roll`` (q,); ``method`` of the interior.
    **Returns:** ``(x_belt (n, b), x_roll (q,))``.
    """
    if A.n_blocks < 3:
        return dense_solve(A, rhs_belt, rhs_roll)
    F = factorise(lax.stop_gradient(A), method)
    return solve_with_adjoint(A.matvec, rhs_belt, rhs_roll, lambda _, rb, rr: factor_solve(F, rb, rr),
                              lambda _, rb, rr: factor_solve_transposed(F, rb, rr))


def dense_solve(A: BorderedBlockCyclic, rhs_belt: jax.Array, rhs_roll: jax.Array):
    """Reference: dense ``jnp.linalg.solve`` on the assembled, row-equilibrated matrix."""
    A, rhs_belt, rhs_roll = row_equilibrate(A, rhs_belt, rhs_roll)
    x = jnp.linalg.solve(A.to_dense(), join(rhs_belt, rhs_roll))
    return split(x, A.n_blocks, A.block)
