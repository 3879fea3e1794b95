"""Snapshots from the belt model, and single-configuration DMD on them (§6.4.1)."""

import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from helpers import load
from jaxbelt.rom import collect_snapshots, first_order, fit_dmd, rmse, tracer_operator


def test_snapshots_are_the_pre_transport_states():
    m, opts = load("two-roller-1d-train2")
    _, X, Xd = collect_snapshots(m, 30, opts.dt)
    _, tr = jb.simulate(m, n_steps=30, dt=opts.dt)
    C = tracer_operator(m)
    np.testing.assert_allclose(np.asarray(C @ X).T, np.asarray(tr.tracer_u_solved), rtol=1e-12, atol=1e-15)
    assert X.shape == (m.n_unknowns, 30) and Xd.shape == X.shape


def test_tracer_operator_2d():
    from helpers import scene_with

    m, opts = load(scene_with(lambda d: d.setdefault("mesh", {}).update(n_eta=3), "three-roller-t72"))
    s, _ = jb.simulate(m, n_steps=9, dt=opts.dt)  # the compiled run of test_model2d / test_vmap (same shapes)
    from jaxbelt.linalg import join
    from jaxbelt.timeloop import tracer_values

    np.testing.assert_allclose(np.asarray(tracer_operator(m) @ join(s.u, s.chi)), np.asarray(tracer_values(m, s.u)[0]),
                               rtol=1e-12, atol=1e-16)


@pytest.mark.slow
def test_single_configuration_dmd_reaches_the_tolerance_1d():
    """Train on the first 150 steps of Table 6.1 run 1 (first-order pre-transport states, as the
    source), predict the next 200 steps' tracers: RMSE well below 0.02 mm."""
    m, opts = load("two-roller-1d-train1")
    state, X, Xd = collect_snapshots(m, 150, opts.dt)
    Z = first_order(X, Xd)
    dmd = fit_dmd(Z).stable()
    _, tr = jb.simulate(m, y0=state, n_steps=200, dt=opts.dt)
    C = tracer_operator(m)
    C2 = jnp.concatenate([C, jnp.zeros_like(C)], axis=1)
    pred = dmd.predict(Z[:, -1], 200, observe=C2)
    err_mm = float(rmse(tr.tracer_u_solved, pred)) * 1e3
    assert err_mm < 0.02
