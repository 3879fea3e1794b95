"""Modal decomposition of the eliminated ODE (§6.2)."""

import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from helpers import load
from jaxbelt.integrators import eliminated_system
from jaxbelt.rom.modal import forcing_order, modal_basis


def test_modes_solve_the_generalised_eigenproblem_and_half_are_unforced():
    m, opts = load("two-roller-1d-train1")
    s, _ = jb.simulate(m, n_steps=200, dt=opts.dt)
    omega, Phi, force = modal_basis(m, s, opts.dt)
    dyn, alg = m.partition
    M, K, *_ = eliminated_system(m, s, opts.dt, dyn, alg)
    assert Phi.shape == (139, 139)
    np.testing.assert_allclose(np.asarray(Phi.T @ M @ Phi), np.eye(139), atol=1e-8)
    res = K @ Phi - (M @ Phi) * omega[None, :] ** 2
    assert float(jnp.max(jnp.abs(res))) < 1e-8 * float(jnp.max(jnp.abs(K @ Phi)))
    assert np.all(np.diff(np.asarray(omega)) >= 0)
    # §6.2: the forcing (eliminated boundary values) excites only part of the modes; with two equal
    # spans about half of the low span modes have (almost) no projection on it
    proj = np.abs(np.asarray(Phi.T @ force))[1:13]  # the 12 lowest span modes (mode 0: idle roller)
    weak = proj < 1e-2 * proj.max()
    assert 4 <= weak.sum() <= 8
    # the forcing-aware order of §6.2 puts a strongly forced mode first
    first = int(forcing_order(omega, Phi, force)[0])
    assert np.abs(np.asarray(Phi.T @ force))[first] / omega[first] >= np.max(np.abs(np.asarray(Phi.T @ force)) / np.asarray(omega)) * (1 - 1e-12)


def test_modal_integrator_with_all_modes_is_the_full_model_and_converges_with_modes():
    from jaxbelt.rom import fit_modal, rmse

    m, opts = load("two-roller-1d-train1")
    dt = opts.dt
    _, ref = jb.simulate(m, jb.make_solver("eliminated"), n_steps=100, dt=dt)
    dyn, _ = m.partition
    full = fit_modal(m, len(dyn), dt, order="frequency")
    _, tr = jb.simulate(m, full, n_steps=100, dt=dt)
    assert float(jnp.max(jnp.abs(tr.tracer_u - ref.tracer_u))) < 1e-10  # the whole span: exact
    errs = {o: [float(rmse(ref.tracer_u, jb.simulate(m, fit_modal(m, r, dt, order=o), n_steps=100, dt=dt)[1].tracer_u))
                for r in (10, 100)] for o in ("forcing", "frequency")}
    for o, e in errs.items():
        assert e[1] < e[0], (o, e)


def test_fit_modal_rejects_bad_input():
    from jaxbelt.rom import fit_modal

    m, opts = load("two-roller-1d-train1")
    with pytest.raises(ValueError, match="n_modes"):
        fit_modal(m, 0, opts.dt)
    with pytest.raises(ValueError, match="order"):
        fit_modal(m, 5, opts.dt, order="energy")
