"""A study's question at many configurations at once: :func:`at_configurations`.

A time-stepped study's runs are one ``vmap`` batch. A steady study's solves are not batched inside
a program: each configuration is one call of the single steady solve's compiled program
(:func:`jaxbelt.steady.steady_states`), between two small batched programs — the starts
(each configuration's misalignment and its linear prediction of the steady state) before, the
deviations and whatever is read from them after. So the Newton–GMRES program of a scene is
compiled once, whichever command and whichever question asks for solves (the aligned machine,
a box's corners, a sweep's samples), instead of once more inside every batch that holds it.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..infra.programs import stored_jit
from ..steady import steady_states
from .study import Study, run_deviation, steady_deviation, steady_start


@stored_jit
def _steady_inputs(study: Study, thetas):
    """Each row's misalignment vector ``chi_static`` and the start of its steady solve."""
    return jax.vmap(lambda t: (study.configured(t).chi_static, steady_start(study, t)))(thetas)


@stored_jit
def _from_steady(study: Study, states, from_deviation):
    return jax.vmap(lambda s: from_deviation(study, *steady_deviation(study, s)))(states)


@stored_jit
def _from_runs(study: Study, thetas, from_deviation):
    return jax.vmap(lambda t: from_deviation(study, *run_deviation(study, t)))(thetas)


def at_configurations(study: Study, thetas, from_deviation):
    """``from_deviation(study, d_u, d_v, angle)`` (a module-level function of a configuration's
    deviations, :func:`jaxbelt.design.study.run_deviation`) at every row of ``thetas`` (m, P):
    its outputs with a leading axis m. A steady study's solves run one compiled solve per row
    (module docstring), a time-stepped study's runs as one ``vmap`` batch."""
    thetas = jnp.asarray(thetas, study.base.dtype).reshape(-1, study.space.size)
    if not study.steady:
        return _from_runs(study, thetas, from_deviation)
    chis, starts = _steady_inputs(study, thetas)
    states = steady_states(study.model, study.options.solver, dt=study.options.dt, chis=chis, y0s=starts,
                           period_steps=study.period_steps)
    return _from_steady(study, states, from_deviation)
