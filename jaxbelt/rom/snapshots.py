"""Snapshot matrices from full-order runs (§6.3, §6.4, MODEL.md §5).

The reduced models work on the state *before* transport (eq. 6.10): the solve's result ``x̃``,
which still carries the mean displacement that the transport removes. :func:`collect_snapshots`
runs the full model (one ``lax.scan``) and records ``x̃_k = [u; χ]`` and ``x̃̇_k`` at every step;
:func:`first_order` stacks them into DMD's first-order state ``[x; ẋ]`` (§6.4).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax import lax

from ..integrators import make_integrator
from ..state import BeltState, initial_state
from ..timeloop import make_step


def collect_snapshots(model, n_steps: int, integrator=None, state: BeltState | None = None):
    """Run ``n_steps`` and return ``(final_state, X, Xdot)``, each snapshot matrix (N, n_steps)
    with columns ``x̃_1 … x̃_n`` (pre-transport, flat ``[belt; rollers]`` order)."""
    if integrator is None or isinstance(integrator, str):
        integrator = make_integrator(integrator or model.integrator, model)
    state = initial_state(model) if state is None else state
    step = make_step(model, integrator, record_solved=True)
    final, rec = jax.jit(lambda s: lax.scan(lambda c, _: step(c), s, None, length=n_steps))(state)
    return final, rec["x_solved"].T, rec["v_solved"].T


def first_order(X, Xdot):
    """DMD's first-order state ``[x; ẋ]`` (2N, m)."""
    return jnp.concatenate([X, Xdot], axis=0)


def tracer_operator(model):
    """Matrix ``C`` (n_tr, N) with ``C x̃ = `` longitudinal tracer displacement (linear shape
    functions), so reduced models can predict tracers without forming full fields."""
    import numpy as np

    n, b, q = model.n_xi, model.block, model.n_roller_dofs
    col, xi = np.asarray(model.tracer_col), np.asarray(model.tracer_xi)
    C = np.zeros((len(col), n * b + q))
    if model.kind == "1d":
        C[np.arange(len(col)), col * b] += 1 - xi
        C[np.arange(len(col)), ((col + 1) % n) * b] += xi
    else:
        row, eta = np.asarray(model.tracer_row), np.asarray(model.tracer_eta)
        k = np.arange(len(col))
        for dc, wx in ((0, 1 - xi), (1, xi)):
            for dr, wz in ((0, 1 - eta), (1, eta)):
                C[k, ((col + dc) % n) * b + 2 * (row + dr)] += wx * wz
    return jnp.asarray(C)
