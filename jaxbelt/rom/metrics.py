"""Error measures of a reduced trajectory against the full one (§6.1, eq. 6.1–6.2).

Both take arrays of the same shape (time × tracers, say) and reduce over ``axis`` (all axes by
default); per direction (x, z) is simply one call per direction's array.
"""

import functools

import jax
import jax.numpy as jnp


@functools.partial(jax.jit, static_argnames="axis")  # one program per shape, not one per operation
def rmse(x, x_approx, axis=None):
    """``(mean |x - x̃|²)^½`` (eq. 6.1), in the unit of ``x``."""
    return jnp.sqrt(jnp.mean(jnp.abs(x - x_approx) ** 2, axis=axis))


@functools.partial(jax.jit, static_argnames="axis")
def rrmse(x, x_approx, axis=None):
    """``(Σ |x - x̃|² / Σ |x|²)^½`` (eq. 6.2); blows up when ``x`` is small."""
    return jnp.sqrt(jnp.sum(jnp.abs(x - x_approx) ** 2, axis=axis) / jnp.sum(jnp.abs(x) ** 2, axis=axis))
