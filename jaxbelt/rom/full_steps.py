"""The full-order step as a map on scaled first-order states, as the error estimates evaluate it:
one step (or several) of a model's solver, batched over states, and its Jacobian-vector
products, each a compiled program reused by every configuration of the same mesh
(:mod:`jaxbelt.rom.error_estimate` is its user)."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..integrators import AbstractIntegrator, make_solver
from ..state import initial_state
from ..timeloop import SaveAt, make_step
from ..transport import transport_step
from .snapshots import state_to_z, z_to_state


def full_step_map(model, dt, solver: AbstractIntegrator | None = None, order: str = "post", run_data=None):
    """``z -> F(z)``: one full-order step of size ``dt`` (``solver``, default
    :func:`jaxbelt.make_solver`'s, and its transport rule) on scaled first-order states.
    ``order="post"``: states after transport (solve, then transport); ``"pre"``: states before
    transport (transport, then solve), as for DMD on pre-transport snapshots. ``run_data``: what
    ``solver.init`` gives at the model's initial state (computed here when ``None``; a
    caller that applies ``F`` many times passes it once, see :func:`run_data_at_start`)."""
    if order not in ("post", "pre"):
        raise ValueError("order must be 'post' or 'pre'")
    solver = make_solver() if solver is None else solver
    if run_data is None:
        run_data = run_data_at_start(model, solver, dt)
    step = make_step(model, solver, dt, run_data, SaveAt(solved=True))

    def post(z):
        return state_to_z(model, step(z_to_state(model, z, dt))[0], dt)

    def pre(z):
        st = z_to_state(model, z, dt)
        u, ud, chi, m_e = transport_step(model, st.u, st.u_dot, st.chi, st.m_e, rule=solver.transport)
        moved = st.__class__(u=u, u_dot=ud, chi=chi, chi_dot=st.chi_dot, m_e=m_e, step=st.step)
        _, rec = step(moved)
        return jnp.concatenate([rec["x_solved"], dt * rec["v_solved"]])

    return post if order == "post" else pre


@eqx.filter_jit
def run_data_at_start(model, solver, dt):
    """``solver.init`` at ``model``'s initial state (the static solve and, for the reuse
    solver, its factors): computed once per estimate and passed to every batch of full steps,
    instead of again inside each compiled batch."""
    return solver.init(model, initial_state(model), dt)


def step_map(model, dt, solver, order: str, steps: int, run_data=None):
    """``z -> F^steps(z)``: ``steps`` full-order steps (a reduced model whose one step spans
    several full ones, e.g. DMDc fitted on every 4th snapshot)."""
    F = full_step_map(model, dt, solver, order, run_data)

    def Fs(z):
        for _ in range(steps):
            z = F(z)
        return z

    return Fs


@eqx.filter_jit
def apply_steps(model, dt, solver, order, steps, Z, run_data=None):
    """``F`` on each row of ``Z`` (b, 2N), one compiled program per batch shape."""
    return jax.vmap(step_map(model, dt, solver, order, steps, run_data))(Z)


@eqx.filter_jit
def jvp_columns(model, dt, solver, order, steps, z_ref, V, run_data=None):
    """``J V``: the step's Jacobian at ``z_ref`` on each column of ``V`` (2N, b)."""
    F = step_map(model, dt, solver, order, steps, run_data)
    return jax.vmap(lambda v: jax.jvp(F, (z_ref,), (v,))[1], in_axes=1, out_axes=1)(V)


@eqx.filter_jit
def jvp_one(model, dt, solver, order, steps, z_ref, v, run_data=None):
    """``J v`` for one vector (the quasi-static solve's iterations, one after the other)."""
    return jax.jvp(step_map(model, dt, solver, order, steps, run_data), (z_ref,), (v,))[1]


def in_chunks(fn, X, chunk, axis):
    """``fn`` on fixed-size chunks of ``X`` along ``axis`` (the last one zero-padded), concatenated
    (a NumPy array): one compiled program whatever the count, bounded memory. The chunks are cut
    and joined in NumPy (on a CPU a copy; op by op in JAX each slice and join of a new shape is a
    compile)."""
    X = np.asarray(X)
    n = X.shape[axis]
    out = []
    if n == 0:  # no columns: the output's other axes from one zero chunk
        shape = list(X.shape)
        shape[axis] = chunk
        return np.take(np.asarray(fn(jnp.zeros(shape, X.dtype))), np.arange(0), axis=axis)
    for i in range(0, n, chunk):
        part = np.take(X, np.arange(i, min(i + chunk, n)), axis=axis)
        pad = chunk - part.shape[axis]
        if pad:
            widths = [(0, 0)] * X.ndim
            widths[axis] = (0, pad)
            part = np.pad(part, widths)
        res = np.asarray(fn(jnp.asarray(part)))
        out.append(np.take(res, np.arange(chunk - pad), axis=axis))
    return np.concatenate(out, axis=axis)
