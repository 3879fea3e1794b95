"""vmap over misalignment configurations equals separate runs."""

import jax
import jax.numpy as jnp
import numpy as np

import jaxbelt as jb


def test_vmap_over_translations_equals_loop():
    model = jb.load_model("two-roller-1d")
    ts = jnp.array([[0.0, 1e-3], [-2e-3, 0.0], [1e-3, 5e-4], [0.0, -1e-3]])

    def run(t):
        _, tr = jb.simulate(model.with_misalignment(translation=t), n_steps=30)
        return tr.tracer_u

    batched = jax.vmap(run)(ts)
    for k in range(4):
        np.testing.assert_allclose(np.asarray(batched[k]), np.asarray(run(ts[k])), rtol=1e-12, atol=1e-16)


def test_vmap_2d_over_four_misalignments():
    from helpers import scene_with

    model = jb.compile_scene(scene_with(lambda d: d["mesh"].update(n_eta=3), "three-roller"))
    rots = jnp.array([[0.0, 0.0], [4e-4, 0.0], [0.0, -3e-4], [2e-4, 2e-4]])

    def run(r):
        rot = jnp.zeros((3, 3)).at[1, :2].set(r)
        _, tr = jb.simulate(model.with_misalignment(rotation=rot), n_steps=9)  # whole checkpoint chunks
        return tr.tracer_v

    batched = jax.vmap(run)(rots)
    for k in range(4):
        np.testing.assert_allclose(np.asarray(batched[k]), np.asarray(run(rots[k])), rtol=1e-10, atol=1e-15)
