"""The three integrators of §3.4 agree, and elimination gives the source's counts."""

import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from helpers import scene_fixtures, solve_step


loaded, model, dt = scene_fixtures("two-roller-1d-train1")


@pytest.fixture(scope="module")
def reference(model, dt):
    # 30 steps: whole checkpoint chunks (one compiled step), a direct run other modules compile too
    return jb.simulate(model, jb.make_solver("direct"), n_steps=30, dt=dt)


@pytest.mark.parametrize("name", ["naive", "eliminated"])
def test_integrators_agree(model, dt, reference, name):
    s_ref, tr_ref = reference
    s, tr = jb.simulate(model, jb.make_solver(name), n_steps=30, dt=dt)
    scale = float(jnp.max(jnp.abs(s_ref.u)))
    assert float(jnp.max(jnp.abs(s.u - s_ref.u))) < 1e-11 * scale
    assert float(jnp.max(jnp.abs(tr.tracer_u - tr_ref.tracer_u))) < 1e-11 * scale
    np.testing.assert_allclose(np.asarray(tr.roller_velocity), np.asarray(tr_ref.roller_velocity), rtol=1e-10, atol=1e-10)


def test_dense_linear_solver_agrees(model, dt, reference):
    s_ref, tr_ref = reference
    s, tr = jb.simulate(model, jb.DirectBackwardEuler(jb.Dense()), n_steps=30, dt=dt)
    scale = float(jnp.max(jnp.abs(s_ref.u)))
    assert float(jnp.max(jnp.abs(tr.tracer_u - tr_ref.tracer_u))) < 1e-11 * scale


def test_elimination_counts(model):
    dyn, alg = model.partition
    assert model.n_unknowns == 224
    assert len(dyn) == 139 and len(alg) == 85  # 69 + 69 free nodes + α of the idle roller


def test_naive_step_satisfies_backward_euler(model, dt):
    """One naive step: ẋ = (x - x₀)/Δt and ẍ consistent, the DAE rows hold."""
    from jaxbelt.assembly import dae_matrices, dae_rhs
    from jaxbelt.linalg import join

    s0 = jb.initial_state(model)
    s1 = solve_step(model, jb.NaiveBackwardEuler(), s0, dt)
    x0, x1 = join(s0.u, s0.chi), join(s1.u, s1.chi)
    v0, v1 = join(s0.u_dot, s0.chi_dot), join(s1.u_dot, s1.chi_dot)
    np.testing.assert_allclose(np.asarray((x1 - x0) / dt), np.asarray(v1), rtol=1e-9, atol=1e-9)
    K, M = dae_matrices(model, s0.m_e)
    a1 = (v1 - v0) / dt
    F = join(*dae_rhs(model, s0.u, s0.chi, dt))
    res = K.to_dense() @ x1 + M.to_dense() @ a1 - F
    assert float(jnp.max(jnp.abs(res))) < 1e-8 * float(jnp.max(jnp.abs(F)) + 1)
