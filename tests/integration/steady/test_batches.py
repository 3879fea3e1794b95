"""Steady states at many configurations (:mod:`jaxbelt.steady.batches`)."""

import jax
import jax.numpy as jnp
import numpy as np

from jaxbelt.misalignment import apply, parameter_space
from jaxbelt.steady import period_steps, steady_state, steady_states


def test_steady_states_of_a_batch_equal_one_solve_each(machine, steady):
    """:func:`jaxbelt.steady.steady_states` (one compiled single solve per row on a CPU) gives each
    row's :func:`steady_state`, and the same under ``jit`` (a ``lax.map`` batch)."""
    model, opts = machine
    space = parameter_space(model, "idle:dz,drive:ay")
    chis = jnp.stack([apply(model, space, t).chi_static for t in (jnp.array([0.01, 0.0]), jnp.array([0.0, -0.02]))])
    n_p = period_steps(model, opts.dt)
    batch = steady_states(model, opts.solver, dt=opts.dt, chis=chis, period_steps=n_p)
    for i in range(2):
        one = steady_state(model.replace(chi_static=chis[i]), opts.solver, dt=opts.dt)
        np.testing.assert_array_equal(np.asarray(batch.tracer_v[i]), np.asarray(one.tracer_v))
    traced = jax.jit(lambda c: steady_states(model, opts.solver, dt=opts.dt, chis=c, period_steps=n_p).tracer_v)(chis)
    np.testing.assert_allclose(np.asarray(traced), np.asarray(batch.tracer_v), rtol=0, atol=1e-11)
