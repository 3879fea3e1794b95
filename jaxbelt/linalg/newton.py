"""Newton's method with GMRES on pytrees: the steady-state solves' nonlinear and linear iterations
(:mod:`jaxbelt.steady`), written for programs whose operator is a linearised time-step map.

:func:`newton_krylov` solves ``f(y) = 0`` by inexact Newton steps on :func:`jax.linearize`'s
linearisation, :func:`newton_krylov_tangents` the same and then the root's derivatives with
respect to a parameter vector in the same loop, :func:`krylov_solve` one linear system ``A x = b``
with pytree unknowns; all call :mod:`jaxbelt.linalg.gmres`.
"""

from __future__ import annotations

import jax
import jax.flatten_util
import jax.numpy as jnp
from jax import lax

from .gmres import gmres, gmres_affine

DEFAULT_GMRES_RESTART = 120
DEFAULT_GMRES_CYCLES = 6
NEWTON_KRYLOV_RTOL = 1e-3  # the most GMRES reduces the residual in one Newton step (newton_krylov)
FORCING_SAFETY = 0.3  # a Newton step's GMRES aims this far below the tolerance (newton_krylov)


def krylov_solve(matvec, b, rtol: float, restart: int = DEFAULT_GMRES_RESTART, cycles: int = DEFAULT_GMRES_CYCLES,
                 precondition=None):
    """Restarted GMRES (:func:`jaxbelt.linalg.gmres.gmres`) on ``matvec(x) = b`` (pytrees) stopped at
    ``‖r‖₂ ≤ rtol ‖b‖₂``: ``(x, missed)``, ``missed`` true where the solve ended a thousand times
    above the tolerance. ``restart`` should exceed the iterations a solve needs: a restart drops the
    Krylov vectors of the slow, transported directions, which the next cycle must find again, and
    a short restart stagnates."""
    b_flat, unravel = jax.flatten_util.ravel_pytree(b)
    mv = lambda x: jax.flatten_util.ravel_pytree(matvec(unravel(x)))[0]  # noqa: E731
    x, res, _ = gmres(mv, b_flat, rtol=rtol, restart=restart, max_cycles=cycles, precondition=precondition)
    missed = ~(res <= 1e3 * rtol)  # (NaN counts as missed)
    return unravel(x), missed


def newton_krylov(f, y0, tol, max_steps: int, restart: int = DEFAULT_GMRES_RESTART,
                  cycles: int = DEFAULT_GMRES_CYCLES, precondition=None):
    """Newton's method on ``f(y) = 0`` (pytrees) from ``y0``, each step's linear system solved by GMRES
    (:func:`jaxbelt.linalg.gmres.gmres`) on the linearisation at the step's start (:func:`jax.linearize`:
    a product replays the linearised period, the primal map is not evaluated again).

    Returns ``(y, rms, max, steps, krylov_iterations)``, ``rms``/``max`` the final residual's RMS and
    largest entry. The iteration ends when ``RMS(f) ≤ tol`` — tested *before* a step, so a residual
    already within the tolerance costs no further linear solve — or after ``max_steps``, or when
    ``f`` is not finite.

    **Forcing** (inexact Newton): GMRES reduces the residual by ``max(NEWTON_KRYLOV_RTOL,
    min(0.1, FORCING_SAFETY · tol / RMS(f)))``, i.e. by no more than the step needs to end within
    the tolerance (a step's nonlinear remainder is far below its linear one once the large start
    residual is gone), and by at least 1e-3 when the residual is far above it. :mod:`optimistix`'s
    ``Newton`` tests after the step, one step late: on this problem a whole extra linear solve, the
    most expensive one (the last step's GMRES works on the slowest directions)."""
    theta = jnp.zeros((0,), jax.flatten_util.ravel_pytree(y0)[0].dtype)
    y, rms, mx, k, its, _, _ = newton_krylov_tangents(lambda y, _: f(y), y0, theta, tol, max_steps, 1.0, restart,
                                                      cycles, precondition)
    return y, rms, mx, k, its


def newton_krylov_tangents(f, y0, theta, tol, max_steps: int, tangent_rtol, restart: int = DEFAULT_GMRES_RESTART,
                           cycles: int = DEFAULT_GMRES_CYCLES, precondition=None, count=None):
    """:func:`newton_krylov` on ``f(y, θ) = 0`` in ``y`` at ``θ`` ((P,)), then the root's tangents
    ``∂y/∂θᵢ = −(∂f/∂y)⁻¹ (∂f/∂θ) eᵢ`` (implicit function theorem), each to GMRES's relative
    residual ``tangent_rtol``, in one loop.

    Each pass linearises ``f`` in ``(y, θ)`` jointly at the current ``y`` (:func:`jax.linearize`) and
    solves one linear system by :func:`jaxbelt.linalg.gmres.gmres_affine` on ``lin(v, s d) + s c``:
    a Newton step (``d = 0``, ``c = f``) while the iteration runs, then one tangent per pass (``d =
    eᵢ``, ``c = 0``; the right-hand side is the linearisation's own product, at the restart pass).
    The map thus appears in the compiled program once as a primal and once linearised, whatever
    the number of tangents: a program that solved first and then differentiated would hold the map
    three or four times, and XLA's compilation time grows with that. The tangents of a
    Newton iteration that ended unconverged are not computed (NaN). ``count`` (traced, at most P;
    default P): only the first ``count`` tangents are computed, the others are NaN — so one compiled
    program serves a solve with its tangents and solves without them.

    Returns ``(y, rms, max, steps, krylov_iterations, tangents, tangent_iterations)``: ``tangents``
    like ``y`` with a leading axis P (NaN where GMRES ended a thousand times above ``tangent_rtol``),
    ``tangent_iterations`` their GMRES iterations in all."""
    y0f, unravel = jax.flatten_util.ravel_pytree(y0)
    F = lambda yf, th: jax.flatten_util.ravel_pytree(f(unravel(yf), th))[0]  # noqa: E731
    rms = lambda v: jnp.sqrt(jnp.mean(v * v))  # noqa: E731
    n, P, dtype = y0f.size, theta.size, y0f.dtype
    count = jnp.asarray(P if count is None else count, jnp.int32)

    def body(carry):
        y, _, k, its, t_its, i, cols, _ = carry
        Fy, lin = jax.linearize(F, y, theta)
        newton = i < 0
        stop = ~(rms(Fy) > tol) | (k >= max_steps) | ~jnp.all(jnp.isfinite(Fy))
        step = newton & ~stop
        # tangents only at a root: a failed iteration ends here (zero right-hand side: GMRES returns at once)
        skip = ~step & ((rms(Fy) > tol) | (count == 0))
        col = jnp.where(newton, 0, i)
        d = jnp.where(step | skip, 0.0, (jnp.arange(P) == col).astype(dtype))
        c = jnp.where(step, Fy, 0.0)
        rtol = jnp.where(step, jnp.clip(FORCING_SAFETY * tol / rms(Fy), NEWTON_KRYLOV_RTOL, 0.1), tangent_rtol)
        v, res, n_its = gmres_affine(lambda v, s: lin(v, s * d) + s * c, n, dtype, rtol=rtol, restart=restart,
                                     max_cycles=cycles, precondition=precondition)
        tangent = ~step & ~skip
        column = jnp.where(res <= 1e3 * tangent_rtol, v, jnp.nan)  # (NaN counts as missed)
        if P:
            cols = jnp.where(tangent, cols.at[jnp.minimum(col, P - 1)].set(column), cols)
        i_next = jnp.where(step, -1, jnp.where(skip, count, col + 1))
        return (jnp.where(step, y + v, y), Fy, k + step.astype(k.dtype), its + jnp.where(step, n_its, 0),
                t_its + jnp.where(tangent, n_its, 0), i_next, cols, i_next >= count)

    zero = jnp.zeros((), jnp.int32)
    start = (y0f, jnp.zeros_like(y0f), zero, zero, zero, -jnp.ones((), jnp.int32),
             jnp.full((P, n), jnp.nan, dtype), jnp.zeros((), bool))
    y, Fy, k, its, t_its, _, cols, _ = lax.while_loop(lambda c: ~c[7], body, start)
    return unravel(y), rms(Fy), jnp.max(jnp.abs(Fy)), k, its, jax.vmap(unravel)(cols), t_its
