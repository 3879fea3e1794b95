"""The reductions behind one interface (``jaxbelt.rom.reduced_model``): every method fits and
predicts a :class:`~jaxbelt.rom.Prediction` and checks its settings and training set. Short 1D
runs (``conftest.py``'s ``setup``) on the scenes ``jaxbelt reduce``'s tests use."""

import jax.numpy as jnp
import numpy as np
import pytest

from jaxbelt import rom

from .conftest import N_STEPS, TRAIN_STEPS


@pytest.mark.parametrize("method", [rom.ReducedPOD(modes=8), rom.DMD(), rom.DMDc(modes=8), rom.ParametricDMD(modes=8)],
                         ids=lambda m: m.name)
def test_each_method_fits_and_predicts_one_prediction_type(method, setup):
    models, opts = setup
    train = models[:1] if isinstance(method, rom.DMD) else models
    training = rom.TrainingRuns(models=tuple(train), runs=(opts.replace(n_steps=TRAIN_STEPS),) * len(train),
                                own_solvers=(opts.solver,) * len(train))
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
