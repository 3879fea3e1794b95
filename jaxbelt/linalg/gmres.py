"""Restarted GMRES for one flat right-hand side, written for XLA's CPU backend.

``gmres(matvec, b, rtol=…)`` solves ``A x = b`` to ``‖b − A x‖₂ ≤ rtol ‖b‖₂`` (Saad & Schultz's
GMRES(m): Arnoldi with classical Gram–Schmidt applied twice, "CGS2", which keeps the basis
orthogonal to working precision; the Hessenberg matrix reduced by Givens rotations as it grows, so
the residual norm of every iterate is known without a least-squares solve; restarted from the true
residual after ``restart`` iterations). :func:`gmres_affine` is the same loop for a right-hand side
known only through the operator (``x, s ↦ A x − s b``).

Why not :func:`jax.scipy.sparse.linalg.gmres`: its iteration copies the whole Krylov basis (a
pytree carried through nested loops), which on a CPU costs more than the operator itself when the
operator is a cheap linearised time step (on the steered design machine, a linearised period of
two steps, the basis update cost several times the product). Here the basis is one array written vector by vector in
place, in blocks of :data:`BLOCK` vectors, and an iteration's Gram–Schmidt passes read only the
blocks filled so far: its cost grows with the iteration count, not with the restart length.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
from jax import lax
from jax.scipy.linalg import solve_triangular


def _givens(a, b):
    """``(c, s)`` with ``[c s; −s c] [a; b] = [r; 0]``."""
    r = jnp.hypot(a, b)
    safe = jnp.where(r == 0, 1.0, r)
    return jnp.where(r == 0, 1.0, a / safe), jnp.where(r == 0, 0.0, b / safe)


BLOCK = 16  # Krylov vectors per block of the basis (the orthogonalisation skips the blocks not yet filled)


def _project(V, w, k, used):
    """``(Vᵀw, w − V h)`` against the basis vectors ``0..k`` of ``V`` (blocks, BLOCK, n): classical
    Gram–Schmidt over the blocks filled so far only (``used`` of them; 0: nothing projected), so an
    iteration costs in proportion to the vectors it has, not to the restart length. The slots
    beyond ``k`` of the last block may hold an earlier cycle's vectors: their coefficients are zero."""
    filled = jnp.arange(V.shape[0] * V.shape[1]).reshape(V.shape[:2]) <= k

    def dots(j, h):
        return h.at[j].set(jnp.where(filled[j], V[j] @ w, 0.0))

    h = lax.fori_loop(0, used, dots, jnp.zeros(V.shape[:2], w.dtype))

    def subtract(j, w):
        return w - h[j] @ V[j]

    return h, lax.fori_loop(0, used, subtract, w)


class _Carry(NamedTuple):
    x: jax.Array  # the iterate
    V: jax.Array  # the Krylov basis, (blocks, BLOCK, n)
    R: jax.Array  # the Hessenberg matrix reduced to triangular by the rotations, (restart + 1, restart)
    cs: jax.Array  # the Givens rotations so far
    sn: jax.Array
    g: jax.Array  # the rotated right-hand side: |g[k]| is the residual norm after k iterations
    k: jax.Array  # Arnoldi iterations in this cycle
    restarting: jax.Array  # the next product is the true residual's (a cycle starts or the solve ends)
    cycles: jax.Array
    iterations: jax.Array
    residual: jax.Array  # the last true residual norm
    bnorm: jax.Array  # ‖b‖₂ (NaN until the first true residual, for a start from zero)
    done: jax.Array


def gmres(matvec, b, *, rtol: float, restart: int = 64, max_cycles: int = 10, x0=None, precondition=None):
    """Solve ``matvec(x) = b`` (flat arrays) to ``‖b − A x‖₂ ≤ rtol ‖b‖₂``: ``(x, relative residual,
    iterations)``. ``restart`` Krylov vectors per cycle, at most ``max_cycles`` cycles; each cycle
    starts from the true residual, so the reported residual is the true one (not the Givens
    estimate). ``precondition`` ``z ↦ M⁻¹ z``, applied on the right (GMRES on ``A M⁻¹``, ``x = M⁻¹ z``).
    A zero ``b`` gives ``x = 0``. jit- and vmap-able.

    The whole solve is one loop that applies ``matvec`` once per pass — to the next Arnoldi vector,
    or to the iterate when a cycle starts (its true residual) — so the operator appears once in the
    compiled program: when it is a linearised time-step map, the program's size, and XLA's
    compilation time, is that of one copy of it."""
    bnorm = jnp.linalg.norm(b)
    x = jnp.zeros_like(b) if x0 is None else x0
    return _gmres(lambda v, s: matvec(v) - jnp.where(s, b, 0.0), x, bnorm, rtol, restart, max_cycles, precondition)


def gmres_affine(affine, n: int, dtype, *, rtol, restart: int = 64, max_cycles: int = 10, precondition=None):
    """:func:`gmres` for a right-hand side known only through the operator: ``affine(x, s) = A x − s b``
    (``s`` 0 or 1) solved for ``A x = b`` from ``x = 0``, to ``‖b − A x‖₂ ≤ rtol ‖b‖₂`` (``‖b‖`` is
    the first true residual's norm). ``(x, relative residual, iterations)``.

    For ``A`` and ``b`` that come from one linearisation — ``A = ∂F/∂y`` and ``b = −(∂F/∂θ) e`` of a
    linearised ``F(y, θ)``, ``affine(x, s) = lin(x, s e)`` — the linearisation is applied at one place
    in the loop, so it appears once in the compiled program (the right-hand side is the restart
    pass's product, not a second copy of the operator)."""
    nan = jnp.full((), jnp.nan, dtype)
    return _gmres(affine, jnp.zeros((n,), dtype), nan, rtol, restart, max_cycles, precondition)


def _gmres(apply, x, bnorm, rtol, restart, max_cycles, precondition):
    """The loop of :func:`gmres` and :func:`gmres_affine`: ``apply(v, s) = A v − s b``; ``bnorm``
    ``‖b‖₂``, or NaN for the first true residual's norm (a start from ``x = 0``)."""
    precondition = (lambda v: v) if precondition is None else precondition
    n = x.shape[0]
    dtype = x.dtype
    blocks = (restart + 1 + BLOCK - 1) // BLOCK
    zero = jnp.zeros((), jnp.int32)

    def body(c: _Carry) -> _Carry:
        k, rs = c.k, c.restarting
        w = apply(jnp.where(rs, c.x, precondition(c.V[k // BLOCK, k % BLOCK])), rs.astype(dtype))
        # a cycle's start: the true residual, which ends the solve or becomes the first basis vector
        r = -w
        beta = jnp.linalg.norm(r)
        bnorm = jnp.where(jnp.isnan(c.bnorm), beta, c.bnorm)
        tol_abs = rtol * bnorm
        finished = rs & ((beta <= tol_abs) | (c.cycles >= max_cycles))
        # an Arnoldi iteration: the second Gram–Schmidt pass restores the orthogonality the first lost
        used = jnp.where(rs, 0, k // BLOCK + 1)
        h, w = _project(c.V, w, k, used)  # rows beyond k are zero
        h2, w = _project(c.V, w, k, used)
        h = (h + h2).reshape(-1)[: restart + 1]
        hn = jnp.linalg.norm(w)
        breakdown = ~rs & (hn <= 1e-14 * jnp.linalg.norm(h))  # an invariant Krylov space holds the solution
        v_new = jnp.where(rs, r / jnp.where(beta == 0, 1.0, beta),
                          jnp.where(breakdown, 0.0, w / jnp.where(hn == 0, 1.0, hn)))
        slot = jnp.where(rs, 0, k + 1)
        V = c.V.at[slot // BLOCK, slot % BLOCK].set(v_new)
        h = h.at[k + 1].set(hn)

        def rotate(j, h):
            hj, hj1 = h[j], h[j + 1]
            return h.at[j].set(c.cs[j] * hj + c.sn[j] * hj1).at[j + 1].set(-c.sn[j] * hj + c.cs[j] * hj1)

        h = lax.fori_loop(0, jnp.where(rs, 0, k), rotate, h)
        cg, sg = _givens(h[k], h[k + 1])
        h = h.at[k].set(cg * h[k] + sg * h[k + 1]).at[k + 1].set(0.0)
        gk = c.g[k]
        g_arnoldi = c.g.at[k].set(cg * gk).at[k + 1].set(-sg * gk)
        g = jnp.where(rs, jnp.zeros_like(c.g).at[0].set(beta), g_arnoldi)
        kc = jnp.minimum(k, restart - 1)  # (k may equal restart on a restart pass, which writes nothing)
        R = jnp.where(rs, c.R, c.R.at[:, kc].set(h))
        cs = jnp.where(rs, c.cs, c.cs.at[kc].set(cg))
        sn = jnp.where(rs, c.sn, c.sn.at[kc].set(sg))
        k_next = jnp.where(rs, 0, k + 1)
        cycle_end = ~rs & ((k_next == restart) | (jnp.abs(g[k_next]) <= tol_abs) | breakdown)

        def update(x):  # the cycle's correction: the least-squares solution in its Krylov space
            idx = jnp.arange(restart)
            filled = idx < k_next
            Rk = jnp.where(filled[:, None] & filled[None, :], R[:restart], jnp.eye(restart, dtype=dtype))
            y = solve_triangular(Rk, jnp.where(filled, g[:restart], 0.0), lower=False)
            return x + precondition(y @ V.reshape(-1, n)[:restart])

        x = lax.cond(cycle_end, update, lambda x: x, c.x)
        return _Carry(x, V, R, cs, sn, g, k_next, ~rs & cycle_end,
                      c.cycles + (rs & ~finished), c.iterations + (~rs).astype(jnp.int32),
                      jnp.where(rs, beta, c.residual), bnorm, finished)

    init = _Carry(x, jnp.zeros((blocks, BLOCK, n), dtype), jnp.zeros((restart + 1, restart), dtype),
                  jnp.zeros((restart,), dtype), jnp.zeros((restart,), dtype), jnp.zeros((restart + 1,), dtype),
                  zero, jnp.ones((), bool), zero, zero, jnp.zeros((), dtype), bnorm, jnp.zeros((), bool))
    out = lax.while_loop(lambda c: ~c.done, body, init)
    return out.x, out.residual / jnp.where(out.bnorm == 0, 1.0, out.bnorm), out.iterations
