"""Whether a steady state is one the machine can hold (:mod:`jaxbelt.steady.checks`)."""

import equinox as eqx
import jax.numpy as jnp
import pytest

from jaxbelt.steady import NoSteadyStateError, check_steady, steady_state


def test_hold_angle_beyond_the_range_is_named(machine):
    """The loop needs more than its range to hold the skewed belt: one line saying how much."""
    model, opts = machine
    narrow = eqx.tree_at(lambda m: m.control.limit, model, jnp.full_like(model.control.limit, 1e-6))
    s = steady_state(narrow, opts.solver, dt=opts.dt)
    with pytest.raises(NoSteadyStateError, match=r"needs .* mrad .* beyond its ±0.001 mrad range"):
        check_steady(s, narrow)
