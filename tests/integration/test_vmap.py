"""vmap over misalignment configurations equals separate runs."""

import jax
import jax.numpy as jnp
import numpy as np

import jaxbelt as jb
from helpers import load, scene_with


def test_vmap_over_translations_equals_loop():
    model, opts = load("two-roller-1d")
    ts = jnp.array([[0.0, 1e-3], [-2e-3, 0.0], [1e-3, 5e-4], [0.0, -1e-3]])

    def run(t):
        _, tr = jb.simulate(jb.with_misalignment(model, translation=t), opts.solver, n_steps=30, dt=opts.dt)
        return tr.tracer_u

    batched = jax.vmap(run)(ts)
    for k in range(4):
        np.testing.assert_allclose(np.asarray(batched[k]), np.asarray(run(ts[k])), rtol=1e-12, atol=1e-16)


def test_vmap_2d_over_four_misalignments():
    model, opts = load(scene_with(lambda d: d["mesh"].update(n_eta=3), "three-roller"))
    rots = jnp.array([[0.0, 0.0], [4e-4, 0.0], [0.0, -3e-4], [2e-4, 2e-4]])

    def run(r):
        rot = jnp.zeros((3, 3)).at[1, :2].set(r)
        # whole checkpoint chunks
        _, tr = jb.simulate(jb.with_misalignment(model, rotation=rot), opts.solver, n_steps=9, dt=opts.dt)
        return tr.tracer_v

    batched = jax.vmap(run)(rots)
    for k in range(4):
        np.testing.assert_allclose(np.asarray(batched[k]), np.asarray(run(rots[k])), rtol=1e-10, atol=1e-15)


def test_vmap_over_time_steps_equals_loop():
    """``dt`` is traced: a batch of time steps runs as one program and gives the separate runs."""
    model, opts = load("two-roller-1d")
    dts = jnp.array([0.8, 1.0, 1.1]) * opts.dt

    def run(dt):
        return jb.simulate(model, opts.solver, n_steps=30, dt=dt)[1].tracer_u

    batched = jax.vmap(run)(dts)
    for k in range(3):
        np.testing.assert_allclose(np.asarray(batched[k]), np.asarray(run(dts[k])), rtol=1e-12, atol=1e-16)
    assert float(jnp.max(jnp.abs(batched[0] - batched[2]))) > 0  # the time step does change the run
