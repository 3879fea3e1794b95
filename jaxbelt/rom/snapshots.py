"""Snapshot matrices from full-order runs (§6.3, §6.4, model specification §5).

The reduced models work on the state *before* transport (eq. 6.10): the solve's result ``x̃``,
which still carries the mean displacement that the transport removes. :func:`collect_snapshots`
runs the full model (one ``lax.scan``) and records ``x̃_k = [u; χ]`` and ``x̃̇_k`` at every step;
:func:`first_order` stacks them into DMD's first-order state ``[x; ẋ]`` (§6.4).

Every function that runs the model takes its run settings as one
:class:`~jaxbelt.timeloop.RunOptions`: the ``solver`` (:mod:`jaxbelt.integrators`), ``n_steps``
and the time step ``dt`` (s, a traced value: another ``dt`` reuses the compiled program); the
options' ``saveat`` is not read (every step is recorded).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import lax

from ..linalg import join, split
from ..state import BeltState, initial_state
from ..timeloop import RunOptions, SaveAt, make_step


def collect_snapshots(model, options: RunOptions, state: BeltState | None = None):
    """Run ``options.n_steps`` steps of size ``options.dt`` with ``options.solver`` from ``state``
    (default the initial state) and return ``(final_state, X, Xdot)``, each snapshot matrix
    (N, n_steps) with columns ``x̃_1 … x̃_n`` (pre-transport, flat ``[belt; rollers]`` order)."""
    state = initial_state(model) if state is None else state
    final, rec = _scan_recorded(model, options.solver, state, jnp.asarray(options.dt, model.ell.dtype),
                                int(options.n_steps))
    return final, rec["x_solved"].T, rec["v_solved"].T


def collect_first_order(model, options: RunOptions, state: BeltState | None = None):
    """Run ``options.n_steps`` steps of size ``options.dt`` with ``options.solver`` from ``state``
    (default the initial state) and return ``(final_state, Z_pre, Z_post)``: the
    scaled first-order states ``z = [x; Δt ẋ]`` before each step's transport (2N, n_steps) and
    after it, the start state first (2N, n_steps + 1). The velocity is scaled by ``Δt`` so both
    halves are lengths (a POD of mixed m and m/s would weigh them by the unit system). These are
    the snapshots of the fully reduced step (:mod:`jaxbelt.rom.pod_step`)."""
    state = initial_state(model) if state is None else state
    dt = jnp.asarray(options.dt, model.ell.dtype)
    final, rec = _scan_recorded(model, options.solver, state, dt, int(options.n_steps))
    return (final,) + _first_order_snapshots(model, rec, state, dt)


@eqx.filter_jit
def _first_order_snapshots(model, rec, state, dt):
    """``(Z_pre, Z_post)`` of :func:`collect_first_order` from the recorded run (one program)."""
    Z_pre = jnp.concatenate([rec["x_solved"], dt * rec["v_solved"]], axis=1).T
    Z_post = jnp.concatenate([rec["x_grid"], dt * rec["v_grid"]], axis=1).T
    return Z_pre, jnp.concatenate([state_to_z(model, state, dt)[:, None], Z_post], axis=1)


@eqx.filter_jit
def _scan_recorded(model, solver, state, dt, n_steps: int):
    step = make_step(model, solver, dt, solver.init(model, state, dt), SaveAt(solved=True))
    return lax.scan(lambda c, _: step(c), state, None, length=n_steps)


def state_to_z(model, state: BeltState, dt):
    """The scaled first-order state ``[x; Δt ẋ]`` (2N,) of a :class:`BeltState`."""
    return jnp.concatenate([join(state.u, state.chi), dt * join(state.u_dot, state.chi_dot)])


def z_to_state(model, z, dt, m_e=None, step=0) -> BeltState:
    """Inverse of :func:`state_to_z` (element masses ``m_e`` default to the initial ones)."""
    N, n, b = model.n_unknowns, model.n_xi, model.block
    (u, chi), (ud, chid) = split(z[:N], n, b), split(z[N:] / dt, n, b)
    return BeltState(u=u, u_dot=ud, chi=chi, chi_dot=chid, m_e=model.m_e0 if m_e is None else m_e,
                     step=jnp.asarray(step, jnp.int32))


def first_order(X, Xdot):
    """DMD's first-order state ``[x; ẋ]`` (2N, m)."""
    return jnp.concatenate([X, Xdot], axis=0)


def tracer_operator(model, direction: str = "x"):
    """Matrix ``C`` (n_tr, N) with ``C x̃ = `` tracer displacement (linear shape functions) along
    the belt (``direction="x"``) or across it (``"z"``, 2D only), so reduced models can predict
    tracers without forming full fields."""
    if direction not in ("x", "z") or (direction == "z" and model.kind == "1d"):
        raise ValueError(f"no tracer direction {direction!r} in a {model.kind} model")
    off = 0 if direction == "x" else 1
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
                C[k, ((col + dc) % n) * b + 2 * (row + dr) + off] += wx * wz
    return jnp.asarray(C)
