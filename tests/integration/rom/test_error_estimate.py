"""A-posteriori error estimate of reduced models (the error ROM) and the snapshot-count rule.

Small 1D scenes, short runs. The models are fitted once per module on the nominal scene and Table
6.1 run 1 (100 steps each); the safety factor is calibrated on those training runs only (a fit on
their first half predicting the whole window), and the effectivity is checked on configurations
no fit has seen: the drive moved -6 mm (and for POD, which takes the drive rate as an input,
turning at 0.9 of the nominal rate). Single-configuration DMD (pre-transport states) is checked
through ``jaxbelt reduce`` in ``tests/integration/cli/test_reduce.py``."""

import logging

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.rom import (belt_inputs, collect_first_order, fit_dmd, fit_dmdc, fit_reduced_pod_ranks, parameters,
                         rmse, stack_controlled, tracer_operator)
from jaxbelt.rom.calibration import calibrate, safety_factor, snapshot_count
from jaxbelt.rom.error_estimate import (BasisTrajectory, ErrorRomOptions, _quasi_static_response, _split_changing_windows,
                                  error_rom, residual_indicator, warm_error_rom)

N_TRAIN, N_TEST = 100, 200
DT = jb.load_scene("two-roller-1d").time.dt  # the time step of every two-roller-1d scene


def _rmse_um(a, b):
    return float(rmse(a, b)) * 1e6


@pytest.fixture(scope="module")
def setup():
    names = ["two-roller-1d", "two-roller-1d-train1"]
    ms = [jb.load_model(n) for n in names]
    runs = [collect_first_order(m, jb.RunOptions(jb.make_solver(), N_TRAIN, DT)) for m in ms]
    same = jb.with_misalignment(ms[0], translation=jnp.array([-6e-3, 0.0]))
    new = same.replace(omega=0.9 * ms[0].omega)
    truth = {}
    for key, m in (("same", same), ("new", new)):
        Z = collect_first_order(m, jb.RunOptions(jb.make_solver(), N_TEST, DT))[2]
        truth[key] = (m, Z)
    C = tracer_operator(ms[0])
    return dict(ms=ms, runs=runs, truth=truth, C=C, Cz=jnp.concatenate([C, jnp.zeros_like(C)], axis=1))


@pytest.fixture(scope="module")
def pod(setup):
    """Fully reduced POD at ranks 10 and 20 (one projection), its safety factor from the first
    halves of the training runs, and the held-out predictions."""
    ms, runs, C = setup["ms"], setup["runs"], setup["C"]
    ranks = (10, 20)
    roms = fit_reduced_pod_ranks(ms[0], jnp.concatenate([z for r in runs for z in r[1:]], axis=1), ranks, DT)
    half = N_TRAIN // 2
    cal_roms = fit_reduced_pod_ranks(ms[0], jnp.concatenate([z for r in runs for z in (r[1][:, :half], r[2][:, :half + 1])],
                                                            axis=1), ranks, DT)
    m, Z = setup["truth"]["new"]
    out = {}
    for r in ranks:
        cases = []
        for mc, run in zip(ms, runs):
            x0 = cal_roms[r].project(mc, jb.initial_state(mc))
            o = cal_roms[r].run(x0, parameters(mc), N_TRAIN)
            cases.append((mc, (C @ run[2][: mc.n_unknowns, 1:]).T, o.tracer_u,
                          BasisTrajectory(cal_roms[r].basis, jnp.concatenate([x0[None], o.xi]), run[2][:, 0]), None))
        cal = calibrate(cases, DT)
        xi0 = roms[r].project(m, jb.initial_state(m))
        o = roms[r].run(xi0, parameters(m), N_TEST)
        coords = jnp.concatenate([xi0[None], o.xi])
        est = error_rom(m, roms[r].basis, coords, DT, z_true0=Z[:, 0])
        true = jnp.sqrt(jnp.mean((o.tracer_u - (C @ Z[: m.n_unknowns, 1:]).T) ** 2, axis=1)) * 1e6
        out[r] = dict(cal=cal, est=est, true_um=float(jnp.sqrt(jnp.mean(true**2))), true_max_um=float(jnp.max(true)),
                      states=coords @ roms[r].basis.T)
    return out


def test_error_rom_vanishes_on_a_full_order_trajectory(setup):
    m, Z = setup["truth"]["same"]
    Z = Z[:, :41]
    U = jnp.linalg.svd(Z, full_matrices=False)[0]  # the trajectory's own span
    est = error_rom(m, U, (U.T @ Z).T, DT, z_true0=Z[:, 0], stride=1)
    assert est.max_um < 1e-6
    assert est.error.shape == (40, m.n_tracers) and est.cost.full_steps == 41


@pytest.mark.parametrize("r", [10, 20])
def test_pod_effectivity_on_a_held_out_configuration(pod, r):
    p = pod[r]
    # the estimator itself is sharp: the raw estimate is within 25 % of the true RMSE and max
    assert 0.8 < p["est"].rmse_um / p["true_um"] < 1.25
    assert 0.8 < p["est"].max_um / p["true_max_um"] < 1.25
    # calibrated on the training runs only, it errs on the safe side by less than 3x
    kappa = p["cal"].safety_factor
    assert kappa >= 1.5 and len(p["cal"].cases) == 2
    assert 1.0 <= kappa * p["est"].rmse_um / p["true_um"] <= 3.0
    assert 1.0 <= kappa * p["est"].max_um / p["true_max_um"] <= 3.0
    # cheap: windows of 10 steps (every step for the first 10, and where the residual still
    # changes), one JVP per subspace direction and per quasi-static iteration
    cost = p["est"].cost
    assert 10 + (N_TEST - 10) // 10 <= cost.windows < cost.full_steps <= N_TEST // 2
    assert cost.jvps == p["est"].dim + cost.quasi_static_iterations and p["est"].dim < 60
    assert cost.quasi_static_iterations <= 40


def test_estimate_ranks_models_and_flags_the_one_above_tolerance(pod):
    est = {r: pod[r]["cal"].safety_factor * pod[r]["est"].rmse_um for r in pod}
    assert pod[10]["true_um"] > 20 > pod[20]["true_um"]
    assert est[10] > 20 > est[20]


def test_dmdc_effectivity_on_a_held_out_configuration(setup):
    ms, runs, Cz = setup["ms"], setup["runs"], setup["Cz"]
    post = [r[2] for r in runs]
    params = [parameters(m) for m in ms]

    def fit(trajs):
        X, Y, U = stack_controlled(trajs, [belt_inputs(p, z.shape[1] - 1) for p, z in zip(params, trajs)])
        return fit_dmdc(X, Y, U, rank=30)

    def inputs(f, z, u, n):
        return BasisTrajectory(f.basis, jnp.concatenate([(f.basis.T @ z)[None], f.predict(z, u, n, observe=f.basis.T)]), z)

    cf = fit([z[:, : N_TRAIN // 2 + 1] for z in post])
    cases = []
    for m, p, z in zip(ms, params, post):
        u = belt_inputs(p, 1)[:, 0]
        cases.append((m, (Cz @ z[:, 1:]).T, cf.predict(z[:, 0], u, N_TRAIN, observe=Cz), inputs(cf, z[:, 0], u, N_TRAIN), None))
    kappa = calibrate(cases, DT).safety_factor
    f = fit(post)
    m, Z = setup["truth"]["same"]
    u = belt_inputs(parameters(m), 1)[:, 0]
    true = _rmse_um((Cz @ Z[:, 1:]).T, f.predict(Z[:, 0], u, N_TEST, observe=Cz))
    est = error_rom(m, *inputs(f, Z[:, 0], u, N_TEST)[:2], DT, Z[:, 0]).rmse_um
    assert 0.8 < est / true < 1.25
    assert 1.0 <= kappa * est / true <= 3.0


def test_warm_up_compiles_what_the_estimate_runs(setup, caplog):
    """warm_error_rom compiles error_rom's batched full steps and Jacobian products without
    running them: error_rom then traces and compiles neither again. Against it, the same
    estimate in chunks of another size, not warmed up, does."""
    m, Z = setup["truth"]["same"]
    B = np.linalg.qr(np.asarray(Z[:, :40]))[0][:, :5]
    coords = (B.T @ np.asarray(Z[:, :41])).T
    programs = ("apply_steps", "jvp_columns")
    compiled = {}
    for chunk, warm in ((7, True), (5, False)):  # batch shapes no other test compiles
        options = ErrorRomOptions(chunk=chunk)
        if warm:
            warm_error_rom(m, DT, options=options)
        caplog.clear()
        with jax.log_compiles(), caplog.at_level(logging.WARNING, logger="jax"):
            error_rom(m, B, coords, DT, stride=10, options=options)
        compiled[warm] = {p for p in programs if any(p in r.getMessage() for r in caplog.records)}
    assert compiled == {True: set(), False: set(programs)}


def test_quasi_static_response_solves_i_minus_j_by_gmres():
    """The settled error level ``(I - J)⁻¹ r`` for a non-normal contraction J (spectral radius
    0.95, as the 2D step's slowest modes): the residual tolerance is met, and the answer is the
    dense solve's; an iteration cap returns the best iterate so far."""
    rng = np.random.default_rng(0)
    n = 80
    Q = np.linalg.qr(rng.standard_normal((n, n)))[0]
    T = np.diag(np.linspace(-0.5, 0.95, n)) + np.triu(0.05 * rng.standard_normal((n, n)), 1)
    J = Q @ T @ Q.T
    r = rng.standard_normal(n)
    x, its = _quasi_static_response(lambda v: J @ np.asarray(v), r, 1e-10, 200)
    exact = np.linalg.solve(np.eye(n) - J, r)
    assert its < n and np.linalg.norm(x - exact) < 1e-8 * np.linalg.norm(exact)
    x5, its5 = _quasi_static_response(lambda v: J @ np.asarray(v), r, 1e-10, 5)
    assert its5 == 5 and 0 < np.linalg.norm((np.eye(n) - J) @ x5 - r) < np.linalg.norm(r)
    assert _quasi_static_response(lambda v: v, np.zeros(n), 1e-3, 10)[1] == 0


def test_windows_whose_mean_residual_changes_are_cut_into_single_steps():
    starts = np.array([0, 1, 2, 10, 20, 30, 40])  # 2 single steps, then windows of 10 up to n = 50
    steady = np.ones((7, 3))
    assert np.array_equal(_split_changing_windows(starts, 50, steady, 0.5, 0.0), starts)
    D = steady.copy()
    D[3] = 4.0  # window [10, 20) differs from both neighbours: it and they are evaluated step by step
    fine = _split_changing_windows(starts, 50, D, 0.5, 0.0)
    assert np.array_equal(fine, np.concatenate([np.arange(0, 30), [30, 40]]))
    # below the floor a change is noise: nothing is cut
    assert np.array_equal(_split_changing_windows(starts, 50, 1e-9 * D, 0.5, 1e-6), starts)


def test_safety_factor_rule():
    assert safety_factor([1.2, 1.1]) == pytest.approx(1.5)  # never below the margin
    assert safety_factor([0.5, 1.0]) == pytest.approx(3.0)  # an estimate that was short is scaled up
    assert safety_factor([np.nan]) == pytest.approx(1.5)  # a calibration case without error says nothing


def test_the_triangle_inequality_indicator_errs_high_by_far_more(setup, pod):
    """The sum of one-step residuals (kept for comparison): zero on a full-order trajectory, but
    tens of times the true error of a reduced one, where the error ROM is within 25 %."""
    m, Z = setup["truth"]["new"]
    assert float(jnp.max(residual_indicator(m, Z.T, DT, stride=20).residual_um)) < 1e-7
    old = float(residual_indicator(m, pod[20]["states"], DT, stride=10).estimate_um[-1])
    assert old > 10 * pod[20]["true_max_um"]


def test_snapshot_rule_stops_when_new_data_are_predicted():
    m = jb.load_model("two-roller-1d-train1")
    C = tracer_operator(m)
    Cz = jnp.concatenate([C, jnp.zeros_like(C)], axis=1)

    def fit_predict(Z, n):
        return fit_dmd(Z).predict(Z[:, -1], n, observe=Cz)

    res = snapshot_count(m, fit_predict, jb.RunOptions(jb.make_solver(), 600, DT), chunk=50)
    assert res.converged
    assert res.history[-1][1] < 0.1 * 20  # µm
    assert all(e >= 2 for _, e in res.history[:-1])  # stopped at the first chunk that passed
    # a model trained on that many snapshots predicts the next 200 steps within tolerance
    Z = res.Z
    state = jb.simulate(m, n_steps=res.n_steps, dt=DT)[0]
    _, tr = jb.simulate(m, y0=state, n_steps=200, dt=DT)
    pred = fit_dmd(Z).predict(Z[:, -1], 200, observe=Cz)
    assert float(rmse(tr.tracer_u, pred)) * 1e6 < 20
