"""Steady states at many configurations (:func:`steady_states`, :func:`map_configurations`), the
derivatives of a function that solves for one (:func:`forward_jacobian`), and a nearby solve's
start moved along a steady state's derivatives (:func:`linear_start`). The fixed point itself and its derivatives are
:mod:`jaxbelt.steady.fixed_point`'s.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from ..integrators import AbstractIntegrator
from ..model import BeltModel
from ..state import BeltState
from .fixed_point import SteadyState, state_fields, steady_state, steady_with_tangents, walks


def steady_states(model: BeltModel, solver: AbstractIntegrator | None = None, *, dt, chis, y0s=None,
                  period_steps: int | None = None, **options) -> SteadyState:
    """:func:`steady_state` of ``model`` at each row of ``chis`` (m, q) (its ``chi_static``), each
    solve started at its row of ``y0s`` (a :class:`~jaxbelt.BeltState` with a leading axis m;
    ``None``: the static equilibrium): one :class:`SteadyState` with a leading axis m. ``options``
    as :func:`steady_state`'s.

    On a CPU, called with arrays (not under a trace), each row is one call of
    :func:`steady_with_tangents`'s compiled program, without tangents: whichever batch or caller
    asks, the Newton–GMRES program of a model's shapes is compiled once (a batch inside another compiled program would be a second copy of it, and
    its compilation costs as much as the first), and a CPU runs a batch's solves one after
    another anyway (:func:`map_configurations`). Elsewhere, or under a trace, the rows are one
    :func:`map_configurations` batch."""
    n = period_steps

    def one(chi, y0):
        return steady_state(model.replace(chi_static=chi), solver, dt=dt, y0=y0, period_steps=n, **options)

    traced = any(isinstance(a, jax.core.Tracer) for a in jax.tree.leaves((chis, y0s, model)))
    if traced or jax.default_backend() != "cpu":
        return map_configurations(lambda a: one(*a), (chis, y0s))
    chis = np.asarray(chis)
    y0s = None if y0s is None else jax.tree.map(np.asarray, y0s)
    if chis.shape[0] == 0:  # no configuration: the outputs' shapes without a solve
        shapes = jax.eval_shape(lambda c, y: map_configurations(lambda a: one(*a), (c, y)), chis, y0s)
        return jax.tree.map(lambda a: np.empty(a.shape, a.dtype), shapes)
    if walks(model):
        raise ValueError("steady_states: this machine walks (lateral transport without a steering loop); "
                         "its steady operation is steady_walk's")
    rows = [steady_with_tangents(model.replace(chi_static=chi), solver, dt=dt, n_tangents=0, period_steps=n,
                                 y0=None if y0s is None else jax.tree.map(lambda a: a[i], y0s), **options)[0]
            for i, chi in enumerate(chis)]
    return jax.tree.map(lambda *a: np.stack([np.asarray(x) for x in a]), *rows)


def forward_jacobian(fn, theta, has_aux: bool = False):
    """``jax.jacfwd(fn, has_aux=has_aux)(theta)`` for functions that solve for a steady state: the
    primal solve once (:func:`jax.linearize`), then one tangent solve per component through
    :func:`map_configurations` (``jacfwd`` would batch the tangents' GMRES loops in lockstep). Each output gets
    a trailing axis of ``theta``'s length."""
    out = jax.linearize(fn, theta, has_aux=has_aux)
    lin = out[1]
    columns = map_configurations(lin, jnp.eye(theta.size, dtype=theta.dtype))
    J = jax.tree.map(lambda a: jnp.moveaxis(a, 0, -1), columns)
    return (J, out[2]) if has_aux else J


def linear_start(state: BeltState, tangents, theta) -> BeltState:
    """``x* + (dx*/dθ) θ``: a steady state moved along its derivatives (``tangents``: the
    :func:`state_fields` of ``dx*/dθ``, each with a trailing axis P; ``theta`` (P,)) — the start of
    a nearby steady solve, whose Newton iteration then only removes the nonlinear remainder."""
    u, ud, chi, chid, m, ctrl = jax.tree.map(lambda a, d: a + d @ theta, state_fields(state), tangents)
    control = state.control
    if ctrl is not None:
        control = dataclasses.replace(control, integral=ctrl[0], error=ctrl[1], command=ctrl[2], angle=ctrl[3])
    return dataclasses.replace(state, u=u, u_dot=ud, chi=chi, chi_dot=chid, m_e=m, control=control)


def map_configurations(fn, xs):
    """``fn`` over the leading axis of ``xs`` for functions that solve for a steady state: on a CPU
    one configuration after another (:func:`jax.lax.map`), elsewhere side by side (``vmap``).

    A batched Newton–GMRES runs its members' loops in lockstep: every GMRES iteration and Newton
    step is taken by the whole batch until its slowest member is done, and the Krylov basis's
    update at a batched iteration index is a scatter into the whole basis instead of an in-place
    write; on a CPU the cores a batch could fill are already busy with each solve's own linear
    algebra."""
    if jax.default_backend() == "cpu":
        return lax.map(fn, xs)
    return jax.vmap(fn)(xs)
