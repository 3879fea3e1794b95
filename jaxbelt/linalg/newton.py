"""Newton's method with GMRES on pytrees: the steady-state solves' nonlinear and linear iterations
(:mod:`jaxbelt.steady`), written for programs whose operator is a linearised time-step map.

:func:`newton_krylov` solves ``f(y) = 0`` by inexact Newton steps on :func:`jax.linearize`'s
linearisation, :func:`krylov_solve` one linear system ``A x = b`` with pytree unknowns; both call
:func:`jaxbelt.linalg.gmres.gmres`.
"""

from __future__ import annotations

import jax
import jax.flatten_util
import jax.numpy as jnp
from jax import lax

from .gmres import gmres

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
    y0f, unravel = jax.flatten_util.ravel_pytree(y0)
    F = lambda yf: jax.flatten_util.ravel_pytree(f(unravel(yf)))[0]  # noqa: E731
    rms = lambda v: jnp.sqrt(jnp.mean(v * v))  # noqa: E731

    def body(carry):
        # one linearisation per pass, its primal the residual that decides whether to step: the map
        # appears once in the compiled program (and once more, linearised, inside GMRES)
        y, _, k, its, _ = carry
        Fy, lin = jax.linearize(F, y)
        stop = ~(rms(Fy) > tol) | (k >= max_steps) | ~jnp.all(jnp.isfinite(Fy))
        rtol = jnp.clip(FORCING_SAFETY * tol / rms(Fy), NEWTON_KRYLOV_RTOL, 0.1)
        # a stopped pass solves for a zero right-hand side: GMRES returns at once
        dy, _, n_its = gmres(lin, jnp.where(stop, 0.0, -Fy), rtol=rtol, restart=restart, max_cycles=cycles,
                             precondition=precondition)
        return jnp.where(stop, y, y + dy), Fy, k + (~stop).astype(k.dtype), its + n_its, stop

    zero = jnp.zeros((), jnp.int32)
    start = (y0f, jnp.zeros_like(y0f), zero, zero, jnp.zeros((), bool))
    y, Fy, k, its, _ = lax.while_loop(lambda c: ~c[4], body, start)
    return unravel(y), rms(Fy), jnp.max(jnp.abs(Fy)), k, its
