"""The reductions behind one interface (``jaxbelt.rom.reduced_model``): every method fits and
predicts a :class:`~jaxbelt.rom.Prediction`, and :func:`jaxbelt.rom.reduce_and_compare` compares
it with the full model, without the command line and without timing. Short 1D runs (40 steps,
20 of them for training) on the scenes ``jaxbelt reduce``'s tests use."""

import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt import rom

N_STEPS, TRAIN_STEPS = 40, 20


@pytest.fixture(scope="module")
def setup():
    scenes = [jb.load_scene(n) for n in ("two-roller-1d", "two-roller-1d-train1")]
    models = [jb.build_model(s) for s in scenes]
    return models, jb.RunOptions.from_scene(scenes[0])


@pytest.mark.parametrize("method", [rom.ReducedPOD(modes=8), rom.DMD(), rom.DMDc(modes=8), rom.ParametricDMD(modes=8)],
                         ids=lambda m: m.name)
def test_each_method_fits_and_predicts_one_prediction_type(method, setup):
    models, opts = setup
    train = models[:1] if isinstance(method, rom.DMD) else models
    training = rom.TrainingRuns(models=tuple(train), solvers=(opts.solver,) * len(train),
                                own_solvers=(opts.solver,) * len(train), n_steps=TRAIN_STEPS, dt=opts.dt)
    fitted = method.fit(training)
    assert isinstance(fitted, rom.AbstractReducedModel) and fitted.n_modes >= 1
    start, z0 = fitted.start(models[0], opts.dt)
    assert start == (TRAIN_STEPS if isinstance(method, rom.DMD) else 0)
    n = N_STEPS - start
    p = fitted.predict(z0, rom.parameters(models[0]), n)
    assert isinstance(p, rom.Prediction)
    assert p.tracer_u.shape == (n, models[0].n_tracers) and bool(jnp.all(jnp.isfinite(p.tracer_u)))
    assert p.coords.shape == (n + 1, p.basis.shape[1]) and p.z_start.shape == (2 * models[0].n_unknowns,)
    assert p.order == ("pre" if isinstance(method, rom.DMD) else "post")
    # the tracers are those of the predicted states
    Cz = training.observe
    states = p.coords[1:] @ p.basis.T
    np.testing.assert_allclose(states @ Cz.T, p.tracer_u, atol=1e-9)
    assert len(list(method.calibration_cases(fitted, training, TRAIN_STEPS // 2))) >= 1


def test_a_method_checks_its_settings_and_training_set(setup):
    models, opts = setup
    with pytest.raises(ValueError, match="modes"):
        rom.DMDc(modes=0)
    with pytest.raises(ValueError, match="smaller than n_steps"):
        rom.ReduceConfig(method=rom.DMD(), options=opts.replace(n_steps=20), train_steps=20)
    with pytest.raises(ValueError, match="at least two"):
        rom.ReduceConfig(method=rom.ParametricDMD(), options=opts.replace(n_steps=20)).method.check_training(
            models[0], models[:1], (opts.solver,))


def test_reduce_and_compare_without_the_command_line(setup):
    """The pipeline itself: a held-out configuration predicted by DMDc, compared at the full run's
    steps in µm, the error estimate calibrated on the training runs; nothing timed."""
    models, opts = setup
    test = models[0].replace(chi_static=0.6 * models[1].chi_static + 0.4 * models[0].chi_static)
    config = rom.ReduceConfig(method=rom.DMDc(modes=20), options=opts.replace(n_steps=N_STEPS, saveat=jb.SaveAt()),
                              train_steps=TRAIN_STEPS, stride=5)
    r = rom.reduce_and_compare(test, models, config)
    assert r.method.name == "dmdc" and r.modes == 20 and r.cost is None and r.compared == "tracer_u"
    assert r.error_um.shape == (N_STEPS,) and r.rmse_um == pytest.approx(np.sqrt(np.mean(r.error_um**2)))
    assert 0 < r.rmse_um < 1e3  # 20 training steps: tens of µm
    assert r.estimate is not None and r.estimate.rmse_um > 0 and len(r.estimate.calibration) == 2
    d = r.to_dict()
    assert d["method"] == "dmdc" and d["rmse_um"] == r.rmse_um and isinstance(d["error_um"], list)


@pytest.mark.parametrize("method", [rom.ReducedPOD(modes=20), rom.DMDc(modes=20)], ids=lambda m: m.name)
def test_a_prediction_observes_the_predicted_configurations_tracers(method, setup):
    """Tracers sit where the predicted configuration's sensors are: on a held-out configuration
    whose tracers lie a quarter of the belt further on (half an element into it) than the
    training runs', the prediction reads them there and meets the full run as closely as with
    the training runs' tracers (a few µm at most); read at the training runs' tracers it
    would miss by millimetres. Trained over the whole horizon."""
    models, opts = setup
    moved = models[0].replace(chi_static=0.6 * models[1].chi_static + 0.4 * models[0].chi_static)
    shifted = moved.replace(tracer_col=(moved.tracer_col + moved.n_xi // 4) % moved.n_xi,
                            tracer_xi=moved.tracer_xi + 0.5)
    assert not np.allclose(rom.observation(shifted), rom.observation(models[0]))
    config = rom.ReduceConfig(method=method, options=opts.replace(n_steps=N_STEPS, saveat=jb.SaveAt()),
                              train_steps=N_STEPS, stride=0)
    same, other = (rom.reduce_and_compare(m, models, config) for m in (moved, shifted))
    assert same.rmse_um < 5.0 and other.rmse_um < 2 * same.rmse_um + 1.0
    # the tracers of the predicted states at the predicted configuration's tracers
    training = rom.TrainingRuns(models=tuple(models), solvers=(opts.solver,) * 2, own_solvers=(opts.solver,) * 2,
                                n_steps=N_STEPS, dt=opts.dt)
    fitted = method.fit(training)
    _, z0 = fitted.start(shifted, opts.dt)
    p = fitted.predict(z0, rom.parameters(shifted), N_STEPS, rom.observation(shifted))
    np.testing.assert_allclose(p.coords[1:] @ (rom.observation(shifted) @ p.basis).T, p.tracer_u, atol=1e-9)
    _, full = jb.simulate(shifted, opts.solver, n_steps=N_STEPS, dt=opts.dt)
    at_nominal = fitted.predict(z0, rom.parameters(shifted), N_STEPS).tracer_u
    assert float(rom.rmse(full.tracer_u, at_nominal)) * 1e6 > 10 * max(other.rmse_um, 1.0)
