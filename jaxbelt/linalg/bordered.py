"""Cyclic block-tridiagonal matrices bordered by roller unknowns (MODEL.md §4).

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
``n - 1`` blocks form a plain block-tridiagonal matrix solved by block Thomas elimination
(``lax.scan``) for ``s + 1`` right-hand sides at once; a dense ``s × s`` Schur complement
closes the system. Everything is ordinary ``jnp`` code: it jit-compiles, vmaps and is
differentiable in both arguments by JAX's own rules. Block Thomas does not pivot across
blocks; the belt blocks of ``M + Δt² K`` are diagonally dominant (lumped mass plus
stiffness, identity rows for the no-slip constraints), which is what makes that safe.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jax import lax


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
        z = jnp.einsum("nqj,nj->q", self.D, x_belt) + self.E @ x_roll
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


def _block_thomas(diag, lower, upper, rhs):
    """Solve a (non-cyclic) block-tridiagonal system with ``k`` right-hand sides.

    ``diag, lower, upper``: (m, b, b) with ``lower[0]`` and ``upper[m-1]`` ignored;
    ``rhs``: (m, b, k). Returns (m, b, k).
    """

    def forward(carry, blk):
        c_prev, y_prev = carry
        a, l, u, r = blk
        den = a - l @ c_prev
        sol = jnp.linalg.solve(den, jnp.concatenate([u, r - l @ y_prev], axis=1))
        c, y = sol[:, : u.shape[1]], sol[:, u.shape[1]:]
        return (c, y), (c, y)

    b, k = rhs.shape[1], rhs.shape[2]
    zero_l = lower.at[0].set(0.0)
    init = (jnp.zeros((b, b), rhs.dtype), jnp.zeros((b, k), rhs.dtype))
    _, (cs, ys) = lax.scan(forward, init, (diag, zero_l, upper, rhs))
    return _back_substitute(cs, ys)


def _back_substitute(cs, ys):
    """Backward sweep of block Thomas: ``x_m = y_m``, ``x_i = y_i - Ĉ_i x_{i+1}``."""

    def backward(x_next, blk):
        c, y = blk
        x = y - c @ x_next
        return x, x

    _, xs = lax.scan(backward, jnp.zeros_like(ys[0]), (cs, ys), reverse=True)
    return xs


def row_equilibrate(A: BorderedBlockCyclic, rhs_belt, rhs_roll):
    """Scale every row by ``1 / max|row|`` (same solution, far better conditioning).

    The belt DAE mixes rows of very different size: Backward-Euler constraint rows are
    ``Δt²`` times unit coefficients, stiffness rows ``~EA/ℓ``, roller rows ``r EA``. On the
    small three-roller scene row scaling brings the condition number of ``M + Δt² K`` from
    3e8 to 1e4 (``tests/test_linalg.py``)."""
    absmax = lambda a, axes: jnp.max(jnp.abs(a), axis=axes)
    rb = jnp.maximum(jnp.maximum(absmax(A.diag, 2), jnp.maximum(absmax(A.lower, 2), absmax(A.upper, 2))),
                     absmax(A.C, 2) if A.C.shape[2] else 0.0)
    rr = jnp.maximum(jnp.max(jnp.abs(A.D), axis=(0, 2)), absmax(A.E, 1)) if A.E.shape[0] else jnp.zeros(0)
    sb, sr = 1.0 / jnp.where(rb > 0, rb, 1.0), 1.0 / jnp.where(rr > 0, rr, 1.0)
    As = BorderedBlockCyclic(diag=A.diag * sb[:, :, None], lower=A.lower * sb[:, :, None],
                             upper=A.upper * sb[:, :, None], C=A.C * sb[:, :, None],
                             D=A.D * sr[None, :, None], E=A.E * sr[:, None])
    return As, rhs_belt * sb, rhs_roll * sr


def bordered_solve(A: BorderedBlockCyclic, rhs_belt: jax.Array, rhs_roll: jax.Array):
    """Exact solve of ``A x = r`` exploiting the structure (see module docstring), after
    :func:`row_equilibrate`.

    **Arguments:** ``A``; ``rhs_belt`` (n, b); ``rhs_roll`` (q,).
    **Returns:** ``(x_belt (n, b), x_roll (q,))``.
    """
    A, rhs_belt, rhs_roll = row_equilibrate(A, rhs_belt, rhs_roll)
    n, b, q = A.n_blocks, A.block, A.n_border
    s = b + q
    if n < 3:
        x = jnp.linalg.solve(A.to_dense(), join(rhs_belt, rhs_roll))
        return split(x, n, b)
    # interior blocks 1..n-1 couple to the border (block 0 + rollers) through G (rows) / H (cols)
    G = jnp.zeros((n - 1, b, s), A.diag.dtype)
    G = G.at[0, :, :b].add(A.lower[1])  # A[1, 0]
    G = G.at[n - 2, :, :b].add(A.upper[n - 1])  # A[n-1, 0]
    G = G.at[:, :, b:].set(A.C[1:])
    H = jnp.zeros((n - 1, s, b), A.diag.dtype)
    H = H.at[0, :b, :].add(A.upper[0])  # A[0, 1]
    H = H.at[n - 2, :b, :].add(A.lower[0])  # A[0, n-1]
    H = H.at[:, b:, :].set(A.D[1:])
    Z = jnp.block([[A.diag[0], A.C[0]], [A.D[0], A.E]])
    r_border = jnp.concatenate([rhs_belt[0], rhs_roll])
    rhs = jnp.concatenate([rhs_belt[1:, :, None], G], axis=2)  # (n-1, b, 1 + s)
    sol = _block_thomas(A.diag[1:], A.lower[1:], A.upper[1:], rhs)
    y_r, y_G = sol[:, :, 0], sol[:, :, 1:]
    S = Z - jnp.einsum("nsb,nbt->st", H, y_G)
    x_border = jnp.linalg.solve(S, r_border - jnp.einsum("nsb,nb->s", H, y_r))
    x_int = y_r - jnp.einsum("nbs,s->nb", y_G, x_border)
    x_belt = jnp.concatenate([x_border[None, :b], x_int], axis=0)
    return x_belt, x_border[b:]


def dense_solve(A: BorderedBlockCyclic, rhs_belt: jax.Array, rhs_roll: jax.Array):
    """Reference: dense ``jnp.linalg.solve`` on the assembled, row-equilibrated matrix."""
    A, rhs_belt, rhs_roll = row_equilibrate(A, rhs_belt, rhs_roll)
    x = jnp.linalg.solve(A.to_dense(), join(rhs_belt, rhs_roll))
    return split(x, A.n_blocks, A.block)


# ----------------------------------------------------------------------------- factorisation reuse


class BorderedFactorisation(eqx.Module):
    """LU factors of a row-equilibrated bordered block-cyclic matrix, for repeated solves.

    Holds the block-Thomas factors of the interior (the inverse of every pivot block,
    ``C_hat = den⁻¹ U``, the sub-diagonal blocks), ``y_G = T⁻¹ G``, the border coupling ``H``
    and the LU of the ``(b + q)²`` Schur complement. A solve with them costs
    ``O(n b (b + q))`` instead of ``O(n b³)``."""

    row_b: jax.Array
    row_r: jax.Array
    inv: jax.Array
    C_hat: jax.Array
    L: jax.Array
    y_G: jax.Array
    H: jax.Array
    S_lu: jax.Array
    S_piv: jax.Array


def _border_parts(A):
    n, b = A.n_blocks, A.block
    s = b + A.n_border
    G = jnp.zeros((n - 1, b, s), A.diag.dtype)
    G = G.at[0, :, :b].add(A.lower[1]).at[n - 2, :, :b].add(A.upper[n - 1]).at[:, :, b:].set(A.C[1:])
    H = jnp.zeros((n - 1, s, b), A.diag.dtype)
    H = H.at[0, :b, :].add(A.upper[0]).at[n - 2, :b, :].add(A.lower[0]).at[:, b:, :].set(A.D[1:])
    Z = jnp.block([[A.diag[0], A.C[0]], [A.D[0], A.E]])
    return G, H, Z


def _thomas_apply(inv, C_hat, L, rhs):
    b, k = rhs.shape[1], rhs.shape[2]
    L = L.at[0].set(0.0)

    def forward(y_prev, blk):
        inv_i, l, r = blk
        y = inv_i @ (r - l @ y_prev)
        return y, y

    _, ys = lax.scan(forward, jnp.zeros((b, k), rhs.dtype), (inv, L, rhs))
    return _back_substitute(C_hat, ys)


def factorise(A: BorderedBlockCyclic) -> BorderedFactorisation:
    """Factor ``A`` (after row equilibration) for :func:`factor_solve` (needs ``n >= 3``)."""
    from jax.scipy.linalg import lu_factor

    n, b = A.n_blocks, A.block
    As, row_b, row_r = row_equilibrate(A, jnp.ones((n, b)), jnp.ones(A.n_border))  # scales = scaled ones
    diag, lower, upper = As.diag[1:], As.lower[1:], As.upper[1:]

    from jax.scipy.linalg import lu_solve

    eye = jnp.eye(b, dtype=A.diag.dtype)

    def forward(c_prev, blk):
        a, l, u = blk
        lu_piv = lu_factor(a - l @ c_prev)
        inv = lu_solve(lu_piv, eye)
        return inv @ u, (inv, inv @ u)

    _, (inv, C_hat) = lax.scan(forward, jnp.zeros((b, b), A.diag.dtype), (diag, lower.at[0].set(0.0), upper))
    G, H, Z = _border_parts(As)
    y_G = _thomas_apply(inv, C_hat, lower, G)
    S_lu, S_piv = lu_factor(Z - jnp.einsum("nsb,nbt->st", H, y_G))
    return BorderedFactorisation(row_b, row_r, inv, C_hat, lower, y_G, H, S_lu, S_piv)


def factor_solve(F: BorderedFactorisation, rhs_belt, rhs_roll):
    """Solve with frozen factors: exact for the factored matrix, a preconditioner for a nearby one."""
    from jax.scipy.linalg import lu_solve

    rb, rr = rhs_belt * F.row_b, rhs_roll * F.row_r
    b = rb.shape[1]
    y_r = _thomas_apply(F.inv, F.C_hat, F.L, rb[1:, :, None])[:, :, 0]
    r_border = jnp.concatenate([rb[0], rr])
    x_border = lu_solve((F.S_lu, F.S_piv), r_border - jnp.einsum("nsb,nb->s", F.H, y_r))
    x_int = y_r - jnp.einsum("nbs,s->nb", F.y_G, x_border)
    return jnp.concatenate([x_border[None, :b], x_int], axis=0), x_border[b:]
