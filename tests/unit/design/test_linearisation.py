"""The linear model of a study's runs (jaxbelt.design.linearisation): ``d(θ) = d(0) + ∂d θ`` for
every deviation it holds, ``None`` where the machine has none (1D: no lateral deviation; no loop:
no actuator angle), and a pytree that a compiled program takes as an argument."""

import jax
import jax.numpy as jnp
import numpy as np

from jaxbelt.design.linearisation import LinearDeviation, linear_deviation


def _linear(with_loop: bool) -> LinearDeviation:
    rng = np.random.default_rng(0)
    du, ddu = jnp.asarray(rng.normal(size=(3, 4))), jnp.asarray(rng.normal(size=(3, 4, 2)))
    angle, dangle = (jnp.asarray(rng.normal(size=(3, 1))), jnp.asarray(rng.normal(size=(3, 1, 2)))) if with_loop \
        else (None, None)
    return linear_deviation((du, None, angle), (ddu, None, dangle))


def test_deviation_is_the_value_at_zero_plus_the_derivatives_times_theta():
    lin = _linear(with_loop=True)
    theta = jnp.array([0.3, -1.2])
    du, dv, angle = lin.deviation(theta)
    np.testing.assert_allclose(du, lin.d_u_um + np.einsum("ijk,k->ij", lin.d_u_um_per_theta, theta), rtol=1e-14)
    np.testing.assert_allclose(angle, lin.angle_mrad + np.einsum("ijk,k->ij", lin.angle_mrad_per_theta, theta),
                               rtol=1e-14)
    assert dv is None  # a 1D scene has no lateral deviation
    np.testing.assert_array_equal(lin.deviation(jnp.zeros(2))[0], lin.at_zero[0])


def test_a_machine_without_a_loop_has_no_angle_and_the_model_passes_through_jit():
    lin = _linear(with_loop=False)
    assert lin.at_zero[2] is None and lin.derivatives[2] is None
    f = jax.jit(lambda model, t: model.deviation(t)[0])
    np.testing.assert_allclose(f(lin, jnp.array([1.0, 0.0])), lin.d_u_um + lin.d_u_um_per_theta[..., 0], rtol=1e-14)
