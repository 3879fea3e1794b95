"""POD bases, mode rules and POD-Galerkin on the 1D model (§6.3)."""

import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from helpers import load
from jaxbelt.rom import choose_modes, collect_snapshots, fit_pod, rmse


def test_mode_rules_on_hand_made_singular_values():
    s = np.array([10.0, 1.0, 0.1, 1e-12])
    assert choose_modes(s, n_modes=2) == 2
    assert choose_modes(s, energy_tol=1e-2) == 1  # 100 / 101.01 > 0.99
    assert choose_modes(s, energy_tol=1e-5) == 3
    assert choose_modes(s, rule="source") == 3  # 1e-24 / 25.25 < 1e-20
    with pytest.raises(ValueError):
        choose_modes(s)


@pytest.fixture(scope="module")
def train1():
    m, opts = load("two-roller-1d-train1")
    state, X, _ = collect_snapshots(m, jb.RunOptions(jb.make_solver(), 50, opts.dt))
    _, ref = jb.simulate(m, jb.make_solver("eliminated"), y0=state, n_steps=100, dt=opts.dt)
    return m, opts.dt, state, X, ref


def test_pod_with_all_modes_reproduces_the_full_model(train1):
    m, dt, state, X, ref = train1
    rom = fit_pod(m, X, n_modes=10**6)  # as many as there are
    assert rom.basis.shape == (139, 50)  # all snapshot modes
    # a full orthonormal basis of the 139 dynamic unknowns is the identity in disguise
    full = fit_pod(m, jnp.eye(m.n_unknowns), n_modes=139)
    _, tr = jb.simulate(m, full, y0=state, n_steps=100, dt=dt)
    assert float(jnp.max(jnp.abs(tr.tracer_u - ref.tracer_u))) < 1e-12


def test_pod_error_decreases_with_modes_and_reaches_tolerance(train1):
    m, dt, state, X, ref = train1
    errs = []
    for r in (1, 3, 5, 10):
        _, tr = jb.simulate(m, fit_pod(m, X, n_modes=r), y0=state, n_steps=100, dt=dt)
        errs.append(float(rmse(ref.tracer_u, tr.tracer_u)) * 1e3)
    assert all(a > b for a, b in zip(errs, errs[1:]))  # strictly better with every step up
    assert errs[2] < 0.02  # mm: 5 modes already meet the tolerance on this run
    # energy rule of the source (eq. 7.2) keeps enough modes too
    _, tr = jb.simulate(m, fit_pod(m, X, rule="source"), y0=state, n_steps=100, dt=dt)
    assert float(rmse(ref.tracer_u, tr.tracer_u)) * 1e3 < 0.02
