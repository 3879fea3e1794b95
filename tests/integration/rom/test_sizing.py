"""A DMDc model over a box of misalignments trained only as much as the tolerance needs
(:func:`jaxbelt.rom.train_over_box`, ``jaxbelt reduce --method dmdc --train-ranges``), on
``two-roller-1d`` over a short horizon: the sizing loop's levels and stops, its estimate against
the full model on a configuration it has not seen, and the command line's report."""

import json

import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from helpers import TWO_ROLLER_BOX
from jaxbelt.cli import main
from jaxbelt.misalignment import aligned, apply, parameter_space
from jaxbelt.rom import belt_inputs, error_rom, fit_dmdc, parameters, rmse, state_to_z, tracer_operator, train_over_box
from jaxbelt.rom.sizing import held_out_configurations
from jaxbelt.rom.dmdc import prediction_trajectory
from jaxbelt.rom.dmdc import fit_dmdc_in_basis

COMPONENTS, HALF_WIDTHS = ["drive:dx", "idle:dx"], [12.0, 6.0]  # the box of helpers.TWO_ROLLER_BOX
STEPS = 150  # the horizon predicted
SCHEDULE = ((25, 4), (50, 8), (100, 12))


@pytest.fixture(scope="module")
def setup():
    scene = jb.load_scene("two-roller-1d")
    return jb.build_model(scene), jb.RunOptions.from_scene(scene)


@pytest.fixture(scope="module")
def sized(setup):
    model, opts = setup
    levels = []
    trained = train_over_box(model, COMPONENTS, HALF_WIDTHS, opts.replace(n_steps=STEPS), tol_um=2.0, held_out=3,
                             schedule=SCHEDULE, progress=levels.append)
    return trained, levels


def test_levels_grow_until_the_held_out_estimate_meets_the_target_or_stops_paying(sized):
    trained, levels = sized
    assert 1 <= len(levels) <= len(SCHEDULE) and len(trained.levels) == len(levels)
    same = [i for i in range(len(levels)) if i != trained.chosen]  # only the chosen level is re-calibrated
    assert [trained.levels[i] for i in same] == [levels[i] for i in same]
    assert [lv.train_steps for lv in levels] == [s for s, _ in SCHEDULE[: len(levels)]]
    assert len(trained.models) == 5 and all(Z.shape[1] == trained.train_steps + 1 for Z in trained.trajectories)
    assert trained.target_um == pytest.approx(0.2) and trained.held_out.shape == (3, 2)
    assert np.all(np.abs(trained.held_out) <= np.asarray(HALF_WIDTHS))
    for lv in levels[:-1]:  # every level before the last failed on some held-out configuration
        assert not lv.passed and max(lv.estimate_um) >= trained.target_um
    last = trained.levels[trained.chosen]
    assert trained.stop in ("met", "stalled", "horizon", "schedule")
    assert trained.converged == (trained.stop == "met") == last.passed
    if last.passed:
        assert trained.chosen == len(levels) - 1
        assert len(last.estimate_um) == 3 and max(last.estimate_um) < trained.target_um
    else:  # unconverged: the level with the lowest estimate of the first held-out configuration
        first = [lv.estimate_um[0] / lv.safety_factor for lv in trained.levels]
        assert trained.chosen == int(np.argmin(first))
    assert trained.train_steps == last.train_steps and trained.modes == last.modes
    # the returned model's factor is its own calibrated one, at least the margin
    assert last.safety_factor == trained.calibration.safety_factor >= 1.5


def test_estimate_bounds_the_error_of_a_configuration_it_has_not_seen(setup, sized):
    model, opts = setup
    trained, _ = sized
    space = parameter_space(model, COMPONENTS)
    base = aligned(model)
    theta = held_out_configurations(HALF_WIDTHS, 1, seed=7)[0]
    m = apply(base, space, theta, base=base.chi_static)
    _, ref = jb.simulate(m, opts.solver, n_steps=STEPS, dt=opts.dt)
    C = tracer_operator(m)
    z0 = state_to_z(m, jb.initial_state(m), opts.dt)
    u = belt_inputs(parameters(m), 1)[:, 0]
    pred = trained.fit.predict(z0, u, STEPS, observe=jnp.concatenate([C, jnp.zeros_like(C)], axis=1))
    steps = np.rint(np.asarray(ref.t) / opts.dt).astype(int)
    keep = steps >= 1
    true_um = float(rmse(np.asarray(ref.tracer_u)[keep], np.asarray(pred)[steps[keep] - 1])) * 1e6
    traj = prediction_trajectory(trained.fit, z0, u, STEPS)
    est = error_rom(m, traj.basis, traj.coords, opts.dt, traj.z_true0, stride=10, order="post",
                    solver=opts.solver)
    est_t = trained.safety_factor * np.asarray(est.error_um)[steps[keep] - 1]
    estimate_um = float(np.sqrt(np.mean(est_t**2)))
    assert true_um < 20  # the source's tolerance
    assert 1.0 <= estimate_um / true_um <= 3.0


def test_fit_in_a_basis_is_the_pod_method_after_its_svd():
    rng = np.random.default_rng(0)
    X, Y, U = rng.normal(size=(30, 40)), rng.normal(size=(30, 40)), rng.normal(size=(3, 40))
    ref = fit_dmdc(jnp.asarray(X), jnp.asarray(Y), jnp.asarray(U), rank=6)
    V = np.linalg.svd(np.concatenate([X, Y], axis=1), full_matrices=False)[0][:, :6]
    got = fit_dmdc_in_basis(jnp.asarray(V), X, Y, U)
    signs = np.sign(np.sum(np.asarray(ref.basis) * V, axis=0))  # SVD vectors are defined up to sign
    np.testing.assert_allclose(np.asarray(ref.basis) * signs, V, atol=1e-10)
    np.testing.assert_allclose(np.asarray(ref.A), signs[:, None] * np.asarray(got.A) * signs[None, :], atol=1e-9)
    np.testing.assert_allclose(np.asarray(ref.B), signs[:, None] * np.asarray(got.B), atol=1e-9)


def test_train_over_box_rejects_bad_input(setup):
    model, opts = setup
    with pytest.raises(ValueError, match="held-out"):
        train_over_box(model, COMPONENTS, HALF_WIDTHS, opts.replace(n_steps=STEPS), held_out=0)
    with pytest.raises(ValueError, match="schedule"):
        train_over_box(model, COMPONENTS, HALF_WIDTHS, opts.replace(n_steps=STEPS), schedule=((1, 4),))


def test_cli_sizes_the_training_to_the_tolerance(tmp_path, capsys):
    box = tmp_path / "box.toml"
    box.write_text(TWO_ROLLER_BOX)
    argv = ["reduce", "two-roller-1d-train1", "--method", "dmdc", "--train-ranges", str(box), "--steps", str(STEPS),
            "--held-out", "2", "--json"]
    assert main(argv + ["--tol-um", "1000"]) == 0  # a loose tolerance: met within the horizon
    r = json.loads(capsys.readouterr().out)
    sz = r["sizing"]
    last = sz["levels"][-1]
    assert sz["converged"] and sz["stop"] == "met" and last["passed"] and sz["target_um"] == pytest.approx(100)
    assert not any(lv["passed"] for lv in sz["levels"][:-1]) and max(last["estimate_um"]) < 100
    assert r["train_steps"] == last["train_steps"] and r["modes"] == last["modes"]
    assert "sized to 1000 µm on 2 held-out" in r["train"][0]
    assert r["rmse_um"] < 100 and r["error_estimate"]["safety_factor"] == pytest.approx(last["safety_factor"])
    assert r["timings"]["offline_s"] == pytest.approx(sz["seconds"])
    for bad, word in ((["--held-out", "0"], "--held-out"), (["--tol-um", "-1"], "--tol-um"),
                      (["--tol-um", "100", "--modes", "8"], "no effect")):
        assert main(argv + bad) == 2
        assert word in capsys.readouterr().err
