"""Snapshots from the belt model, and single-configuration DMD on them (§6.4.1)."""

import jax.numpy as jnp
import numpy as np

import jaxbelt as jb
from helpers import load
from jaxbelt.rom import collect_snapshots, first_order, fit_dmd, rmse, tracer_operator


def test_snapshots_are_the_pre_transport_states():
    m, opts = load("two-roller-1d-train2")
    _, X, Xd = collect_snapshots(m, jb.RunOptions(jb.make_solver(), 30, opts.dt))
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


def test_single_configuration_dmd_reaches_the_tolerance_1d():
    """Train on the first 150 steps of Table 6.1 run 1 (first-order pre-transport states, as the
    source), predict the next 200 steps' tracers: RMSE well below 0.02 mm."""
    m, opts = load("two-roller-1d-train1")
    state, X, Xd = collect_snapshots(m, jb.RunOptions(jb.make_solver(), 150, opts.dt))
    Z = first_order(X, Xd)
    dmd = fit_dmd(Z).stable()
    _, tr = jb.simulate(m, y0=state, n_steps=200, dt=opts.dt)
    C = tracer_operator(m)
    C2 = jnp.concatenate([C, jnp.zeros_like(C)], axis=1)
    pred = dmd.predict(Z[:, -1], 200, observe=C2)
    err_mm = float(rmse(tr.tracer_u_solved, pred)) * 1e3
    assert err_mm < 0.02


def test_dmd_forecast_in_one_program_equals_the_fit_and_prediction_apart():
    """rom.dmd.dmd_forecast (snapshots, randomized fit with the rank as a mask, stability cut and
    forecast in one compiled program) against collect_first_order + the randomized
    fit_dmd(...).stable().predict,
    on the first 60 steps of two-roller-1d-train1, 80 steps forecast; and the forecast against the
    full run."""
    from jaxbelt.rom import collect_first_order
    from jaxbelt.rom.dmd import dmd_forecast

    m, opts = load("two-roller-1d-train1")
    C = tracer_operator(m)
    C2 = jnp.concatenate([C, jnp.zeros_like(C)], axis=1)
    fc = dmd_forecast(m, opts.replace(n_steps=60), 80, C2)
    Z = collect_first_order(m, jb.RunOptions(opts.solver, 60, opts.dt))[1]
    fit = fit_dmd(Z, svd="randomized").stable()  # the same sketch, the rank cut as a shape
    # the masked k × k eigenproblem against the truncated r × r one: round-off, amplified by the
    # conditioning of the non-normal modes, to tens of nanometres on centimetre-sized tracers
    np.testing.assert_allclose(np.asarray(fc.observed), np.asarray(fit.predict(Z[:, -1], 80, observe=C2)),
                               rtol=0, atol=1e-7)
    assert int(fc.rank) == int(fit_dmd(Z, svd="randomized").eigs.shape[0])
    assert bool(fc.sketch_full) == (int(fc.rank) > 48 - 8)
    _, tr = jb.simulate(m, n_steps=140, dt=opts.dt)
    assert float(rmse(np.asarray(tr.tracer_u_solved)[-80:], fc.observed)) * 1e3 < 0.02
