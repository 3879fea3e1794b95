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
