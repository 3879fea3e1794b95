"""The fully reduced POD step (solve and transport projected) on the 1D scenes."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.rom import collect_first_order, fit_reduced_pod, fit_reduced_pod_ranks, parameters, pod_basis, rmse
from jaxbelt.rom.pod_step import reduced_operators

N_TRAIN, N_TEST = 150, 400  # 150: the training run of test_rom_dmdc / test_rom_error_estimate (one compiled program)
DT = jb.load_scene("two-roller-1d").time.dt  # the time step of every two-roller-1d scene


@pytest.fixture(scope="module")
def runs():
    out = {}
    for name in ("two-roller-1d", "two-roller-1d-train1", "two-roller-1d-train2"):
        m = jb.load_model(name)
        _, Zp, Zq = collect_first_order(m, jb.RunOptions(jb.make_solver(), N_TRAIN, DT))
        out[name] = (m, jnp.concatenate([Zp, Zq], axis=1))
    return out


def _predict(rom, model, n=N_TEST):
    return rom.run(rom.project(model, jb.initial_state(model)), parameters(model), n)


def test_full_basis_reproduces_the_full_model_exactly():
    # in 1D the solve is affine and the transport bilinear: the projection with V = I is exact
    m = jb.load_model("two-roller-1d-train1")
    V = jnp.eye(2 * m.n_unknowns)
    rom = reduced_operators(m, V, DT)
    _, ref = jb.simulate(m, n_steps=100, dt=DT)
    out = _predict(rom, m, 100)
    assert float(jnp.max(jnp.abs(out.tracer_u - ref.tracer_u))) < 1e-12
    assert float(jnp.max(jnp.abs(out.tracer_u_solved - ref.tracer_u_solved))) < 1e-12


def test_single_configuration_error_falls_with_modes_and_meets_tolerance(runs):
    m, Z = runs["two-roller-1d-train1"]
    _, ref = jb.simulate(m, n_steps=N_TEST, dt=DT)  # 250 steps beyond the training window
    # one projection at r = 20, truncated (= a fit at each rank: test_rom_ranks)
    roms = fit_reduced_pod_ranks(m, Z, (5, 10, 20), DT)
    errs = [float(rmse(ref.tracer_u, _predict(roms[r], m).tracer_u)) * 1e3 for r in (5, 10, 20)]
    assert errs[0] > errs[1] > errs[2]
    assert errs[2] < 0.02  # mm


def test_held_out_configuration_from_multi_configuration_training(runs):
    # trained on the nominal scene and Table 6.1 runs 1 and 2 (-10 mm / 10 rad/s, -4 mm / 7 rad/s);
    # tested on a configuration none of them had: -6 mm at 9 rad/s
    m0 = runs["two-roller-1d"][0]
    Z = jnp.concatenate([z for _, z in runs.values()], axis=1)
    rom = fit_reduced_pod(m0, Z, DT, n_modes=30)
    test = jb.with_misalignment(m0, translation=jnp.array([-6e-3, 0.0])).replace(omega=0.9 * m0.omega)
    _, ref = jb.simulate(test, n_steps=N_TEST, dt=DT)
    err = float(rmse(ref.tracer_u, _predict(rom, test).tracer_u)) * 1e3
    assert err < 0.02
    # the online loop only sees r-sized operators
    assert rom.A.shape == (30, 30) and rom.C_tracer.shape == (m0.n_tracers, 30)


def test_gradient_of_pod_basis_wrt_snapshots_matches_finite_differences():
    X = jax.random.normal(jax.random.PRNGKey(0), (30, 8)) * jnp.logspace(0, -3, 8)[None, :]
    W = jax.random.normal(jax.random.PRNGKey(1), (30, 30))

    def f(X):  # a sign-invariant function of the 3-mode basis: the projector's action
        V, _ = pod_basis(X, n_modes=3)
        return jnp.sum((V @ V.T) * W)

    dX = jax.random.normal(jax.random.PRNGKey(2), X.shape)
    g = jnp.vdot(jax.grad(f)(X), dX)
    h = 1e-6
    fd = (f(X + h * dX) - f(X - h * dX)) / (2 * h)
    assert abs(float(g - fd)) < 1e-6 * max(1.0, abs(float(fd)))


def test_gradient_through_the_whole_chain_wrt_a_misalignment():
    # misalignment -> full-order training run -> POD basis -> reduced operators -> reduced run
    m = jb.load_model("two-roller-1d-train1")

    def metric(dx):
        mm = jb.with_misalignment(m, translation=jnp.stack([dx, 0.0]))
        _, Zp, Zq = collect_first_order(mm, jb.RunOptions(jb.make_solver(), 40, DT))
        rom = fit_reduced_pod(mm, jnp.concatenate([Zp, Zq], axis=1), DT, n_modes=8)
        out = _predict(rom, mm, 60)
        return jnp.mean(out.tracer_u ** 2) * 1e6

    x0 = jnp.asarray(-10e-3)
    g = jax.jit(jax.grad(metric))(x0)  # compiled whole: cheaper than op by op
    f, h = jax.jit(metric), 1e-5
    fd = (f(x0 + h) - f(x0 - h)) / (2 * h)
    assert np.isfinite(float(g))
    assert abs(float(g - fd)) < 1e-4 * abs(float(fd))
