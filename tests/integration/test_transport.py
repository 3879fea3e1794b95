"""The transport step: weights, mass flux, and the steady state of a translated idle roller.

Backs the numbers quoted in ``jaxbelt.transport`` (source rule vs. reference shift).
"""

import dataclasses

import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.transport import upwind_weights
from helpers import load, solve_step, span_strains, whole_chunks


def test_weights_are_exact_linear_interpolation_of_displaced_positions():
    ell = jnp.array([1.0, 1.5, 0.8, 1.2])
    u = jnp.array([[0.3], [0.5], [-0.2], [0.1]])
    a, fwd = upwind_weights(u, ell)
    x = jnp.concatenate([jnp.zeros(1), jnp.cumsum(ell)[:-1]])
    for i in range(4):
        if fwd[i, 0]:
            j = (i - 1) % 4
            pos_j = x[j] - (ell.sum() if j > i else 0) + u[j, 0]
        else:
            j = (i + 1) % 4
            pos_j = x[j] + (ell.sum() if j < i else 0) + u[j, 0]
        pos_i = x[i] + u[i, 0]
        # the grid point x_i is the point a of the way from material point i to j
        np.testing.assert_allclose(float(pos_i + a[i, 0] * (pos_j - pos_i)), float(x[i]), atol=1e-14)


def _steady_strain(transport, dt, refine=1):
    sc = jb.load_scene("two-roller-1d-idle-translated")
    sc = sc.replace(
        mesh=dataclasses.replace(sc.mesh, roller_elements=(40 * refine,) * 2, free_elements=(70 * refine,) * 2),
        time=dataclasses.replace(sc.time, dt=dt),
        solver=dataclasses.replace(sc.solver, transport=transport),
    )
    mesh = jb.build_mesh(sc)
    model = jb.build_model(sc, mesh)
    integ = jb.RunOptions.from_scene(sc).solver  # the scene's transport rule
    s, tr = jb.simulate(model, integ, n_steps=whole_chunks(int(round(6.0 / dt))), dt=dt)  # ~6 s, whole chunks
    solved = solve_step(model, integ, s, dt)
    eps = span_strains(model, mesh, solved.u)
    w = np.asarray(tr.roller_velocity)[-1, :, 1]
    return eps, w


def test_shift_transport_reaches_analytic_steady_strain():
    """Running belt, idle roller out by d: the belt strain spreads over arcs and spans,
    ε = d / (D + π r), the same in both spans, for any Δt; idle speed = drive speed."""
    d, D, r = 1e-3, 0.275, 0.05
    for dt in (0.005, 0.0025):
        eps, w = _steady_strain("shift", dt)
        for e in eps:
            np.testing.assert_allclose(e, d / (D + np.pi * r), rtol=1e-9)
        assert w[1] == pytest.approx(w[0], rel=1e-9)


def test_shift_transport_mesh_independent():
    eps, _ = _steady_strain("shift", 0.00125, refine=2)
    np.testing.assert_allclose(eps[0], 1e-3 / (0.275 + np.pi * 0.05), rtol=1e-9)


def test_source_transport_depends_on_dt():
    """eq. 3.56 as written: the steady strain drifts with Δt (numbers quoted in jaxbelt.transport)."""
    eps5, w5 = _steady_strain("source", 0.005)
    eps25, _ = _steady_strain("source", 0.0025)
    assert float(np.mean(eps5[0])) == pytest.approx(0.002185, abs=2e-6)
    assert float(np.mean(eps25[0])) == pytest.approx(0.001965, abs=2e-6)
    assert abs(w5[1] / w5[0] - 1) < 1e-3  # still within the 0.1 % speed tolerance at 1 mm


def test_plain_interpolation_on_arcs_erases_a_translation(monkeypatch):
    """Why the arcs carry w = u - R_r χ: interpolating u itself (eq. 3.55) lets the span strain
    of a translated idle roller decay to zero; with the roller-relative transport it persists."""
    import jaxbelt.transport as T

    model, opts = load("two-roller-1d-idle-translated")
    mesh = jb.build_mesh(jb.load_scene("two-roller-1d-idle-translated"))
    integ, dt = jb.DirectBackwardEuler(), opts.dt
    s, _ = jb.simulate(model, integ, n_steps=1024, dt=dt)  # 1024 and 992: whole checkpoint chunks
    kept = span_strains(model, mesh, solve_step(model, integ, s, dt).u)[0]
    monkeypatch.setattr(T, "roller_relative_correction", lambda *a: 0.0)
    s, _ = jb.simulate(model, integ, n_steps=992, dt=dt)  # a new n_steps (static) forces a fresh trace
    lost = span_strains(model, mesh, solve_step(model, integ, s, dt).u)[0]
    assert np.all(np.abs(lost) < 1e-9)
    np.testing.assert_allclose(kept, 1e-3 / (0.275 + np.pi * 0.05), rtol=1e-9)
