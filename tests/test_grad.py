"""Gradients through the whole run match central finite differences."""

import jax
import jax.numpy as jnp
import pytest

import jaxbelt as jb


@pytest.fixture(scope="module")
def model():
    return jb.load_model("two-roller-1d-idle-translated")


def _metric(model, translation, n_steps=60):
    m = model.with_misalignment(translation=translation)
    _, tr = jb.simulate(m, n_steps=n_steps)
    return jnp.mean(tr.tracer_u**2) * 1e6 + jnp.mean(tr.tracer_u[-1]) * 1e3


@pytest.mark.parametrize("k", [0, 1])
def test_grad_wrt_roller_translation_matches_central_differences(model, k):
    t0 = jnp.array([0.0, 1e-3])
    g = jax.grad(lambda t: _metric(model, t))(t0)[k]
    h = 1e-7
    e = jnp.zeros(2).at[k].set(h)
    fd = (_metric(model, t0 + e) - _metric(model, t0 - e)) / (2 * h)
    assert abs(float(g - fd)) / abs(float(fd)) < 1e-5


def test_grad_through_eliminated_and_naive(model):
    t0 = jnp.array([0.0, 1e-3])

    def metric(t, name):
        m = model.with_misalignment(translation=t)
        _, tr = jb.simulate(m, name, n_steps=10)
        return jnp.sum(tr.tracer_u[-1] ** 2) * 1e6

    g_direct = jax.grad(lambda t: metric(t, "direct"))(t0)
    g_elim = jax.grad(lambda t: metric(t, "eliminated"))(t0)
    assert float(jnp.max(jnp.abs(g_direct - g_elim))) < 1e-8 * float(jnp.max(jnp.abs(g_direct)))


@pytest.fixture(scope="module")
def model2d():
    from helpers import scene_with

    return jb.compile_scene(scene_with(lambda d: d["mesh"].update(n_eta=3), "three-roller"))


def _metric2d(model, chi, n_steps=8):
    m = model.replace(chi_static=chi)
    _, tr = jb.simulate(m, n_steps=n_steps)
    return jnp.mean(tr.tracer_u[-1]) * 1e3 + jnp.sum(tr.tracer_v**2) * 1e6 + jnp.mean(tr.tracer_v) * 1e3


@pytest.mark.parametrize("dof", [0, 1, 2, 3, 4])
def test_grad_2d_wrt_each_misalignment_component(model2d, dof):
    """Roller 2's dx, dy, dz, αx, αy (index 6 + dof) around a misaligned configuration."""
    chi0 = model2d.chi_static.at[1].set(1e-3).at[9].set(3e-4).at[14].set(1e-3)
    k = 6 + dof
    g = jax.grad(lambda c: _metric2d(model2d, c))(chi0)[k]
    h = 1e-7 if dof < 3 else 1e-8
    e = jnp.zeros_like(chi0).at[k].set(h)
    fd = (_metric2d(model2d, chi0 + e) - _metric2d(model2d, chi0 - e)) / (2 * h)
    assert abs(float(g - fd)) <= 1e-5 * abs(float(fd)) + 1e-12
