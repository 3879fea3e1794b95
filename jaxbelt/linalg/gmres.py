"""Restarted GMRES for one flat right-hand side, written for XLA's CPU backend.

``gmres(matvec, b, rtol=…)`` solves ``A x = b`` to ``‖b − A x‖₂ ≤ rtol ‖b‖₂`` (Saad & Schultz's
GMRES(m): Arnoldi with classical Gram–Schmidt applied twice, "CGS2", which keeps the basis
orthogonal to working precision; the Hessenberg matrix reduced by Givens rotations as it grows, so
the residual norm of every iterate is known without a least-squares solve; restarted from the true
residual after ``restart`` iterations).

Why not :func:`jax.scipy.sparse.linalg.gmres`: its iteration copies the whole Krylov basis (a
pytree carried through nested loops), which on a CPU costs more than the operator itself when the
operator is a cheap linearised time step (on the steered design machine, a linearised period of
two steps, the basis update cost several times the product). Here the basis is one array written vector by vector in
place, in blocks of :data:`BLOCK` vectors, and an iteration's Gram–Schmidt passes read only the
blocks filled so far: its cost grows with the iteration count, not with the restart length.
"""

from __future__ import annotations

import jax.numpy as jnp
from jax import lax
from jax.scipy.linalg import solve_triangular


def _givens(a, b):
    """``(c, s)`` with ``[c s; −s c] [a; b] = [r; 0]``."""
    r = jnp.hypot(a, b)
    safe = jnp.where(r == 0, 1.0, r)
    return jnp.where(r == 0, 1.0, a / safe), jnp.where(r == 0, 0.0, b / safe)


BLOCK = 16  # Krylov vectors per block of the basis (the orthogonalisation skips the blocks not yet filled)


def _project(V, w, k):
    """``(Vᵀw restricted to the blocks holding vectors 0..k, w − V h)``: classical Gram–Schmidt
    against the basis ``V`` (blocks, BLOCK, n) over its first ``k // BLOCK + 1`` blocks only, so an
    iteration costs in proportion to the vectors it has, not to the restart length."""
    used = k // BLOCK + 1

    def dots(j, h):
        return h.at[j].set(V[j] @ w)

    h = lax.fori_loop(0, used, dots, jnp.zeros(V.shape[:2], w.dtype))

    def subtract(j, w):
        return w - h[j] @ V[j]

    return h, lax.fori_loop(0, used, subtract, w)


def _cycle(matvec, precondition, x, b, tol_abs, restart: int):
    """One GMRES(``restart``) cycle from ``x`` on ``A M⁻¹`` (right preconditioning: the residual
    GMRES minimises is the true one): ``(x_new, iterations)``."""
    n = b.shape[0]
    dtype = b.dtype
    r = b - matvec(x)
    beta = jnp.linalg.norm(r)
    blocks = (restart + 1 + BLOCK - 1) // BLOCK
    V = jnp.zeros((blocks, BLOCK, n), dtype).at[0, 0].set(r / jnp.where(beta == 0, 1.0, beta))
    R = jnp.zeros((restart + 1, restart), dtype)
    cs = jnp.zeros((restart,), dtype)
    sn = jnp.zeros((restart,), dtype)
    g = jnp.zeros((restart + 1,), dtype).at[0].set(beta)

    def cond(carry):
        k, _, _, _, _, g, done = carry
        return (k < restart) & (jnp.abs(g[k]) > tol_abs) & ~done

    def body(carry):
        k, V, R, cs, sn, g, _ = carry
        w = matvec(precondition(V[k // BLOCK, k % BLOCK]))
        h, w = _project(V, w, k)  # rows beyond k are zero
        h2, w = _project(V, w, k)  # the second pass restores the orthogonality the first lost to rounding
        h = (h + h2).reshape(-1)[: restart + 1]
        hn = jnp.linalg.norm(w)
        breakdown = hn <= 1e-14 * jnp.linalg.norm(h)  # the Krylov space is invariant: the solution lies in it
        V = V.at[(k + 1) // BLOCK, (k + 1) % BLOCK].set(jnp.where(breakdown, 0.0, w / jnp.where(hn == 0, 1.0, hn)))
        h = h.at[k + 1].set(hn)

        def rotate(j, h):
            hj, hj1 = h[j], h[j + 1]
            return h.at[j].set(cs[j] * hj + sn[j] * hj1).at[j + 1].set(-sn[j] * hj + cs[j] * hj1)

        h = lax.fori_loop(0, k, rotate, h)
        c, s = _givens(h[k], h[k + 1])
        h = h.at[k].set(c * h[k] + s * h[k + 1]).at[k + 1].set(0.0)
        gk = g[k]
        g = g.at[k].set(c * gk).at[k + 1].set(-s * gk)
        R = R.at[:, k].set(h)
        return k + 1, V, R, cs.at[k].set(c), sn.at[k].set(s), g, breakdown

    k, V, R, _, _, g, _ = lax.while_loop(cond, body, (jnp.zeros((), jnp.int32), V, R, cs, sn, g, beta == 0))
    idx = jnp.arange(restart)
    used = idx < k
    Rk = jnp.where(used[:, None] & used[None, :], R[:restart], jnp.eye(restart, dtype=dtype))
    y = solve_triangular(Rk, jnp.where(used, g[:restart], 0.0), lower=False)
    return x + precondition(y @ V.reshape(-1, n)[:restart]), k


def gmres(matvec, b, *, rtol: float, restart: int = 64, max_cycles: int = 10, x0=None, precondition=None):
    """Solve ``matvec(x) = b`` (flat arrays) to ``‖b − A x‖₂ ≤ rtol ‖b‖₂``: ``(x, relative residual,
    iterations)``. ``restart`` Krylov vectors per cycle, at most ``max_cycles`` cycles; each cycle
    starts from the true residual, so the reported residual is the true one (not the Givens
    estimate). ``precondition`` ``z ↦ M⁻¹ z``, applied on the right (GMRES on ``A M⁻¹``, ``x = M⁻¹ z``).
    A zero ``b`` gives ``x = 0``. jit- and vmap-able."""
    precondition = (lambda v: v) if precondition is None else precondition
    x = jnp.zeros_like(b) if x0 is None else x0
    bnorm = jnp.linalg.norm(b)
    tol_abs = rtol * bnorm

    def cond(carry):
        _, res, cycles, _ = carry
        return (res > tol_abs) & (cycles < max_cycles)

    def body(carry):
        x, _, cycles, its = carry
        x, k = _cycle(matvec, precondition, x, b, tol_abs, restart)
        return x, jnp.linalg.norm(b - matvec(x)), cycles + 1, its + k

    res0 = jnp.linalg.norm(b - matvec(x)) if x0 is not None else bnorm
    x, res, _, its = lax.while_loop(cond, body, (x, res0, jnp.zeros((), jnp.int32), jnp.zeros((), jnp.int32)))
    return x, res / jnp.where(bnorm == 0, 1.0, bnorm), its
