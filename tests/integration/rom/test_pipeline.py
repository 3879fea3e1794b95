"""The reduction pipeline without the command line (``jaxbelt.rom.pipeline``):
:func:`jaxbelt.rom.reduce_and_compare` fits, predicts a held-out configuration and compares it with
its full run in µm, untimed, and a prediction reads the predicted configuration's own tracers. Short
1D runs (``conftest.py``'s ``setup``)."""

import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt import rom

from .conftest import N_STEPS, TRAIN_STEPS


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
    training = rom.TrainingRuns(models=tuple(models), runs=(opts.replace(n_steps=N_STEPS),) * 2,
                                own_solvers=(opts.solver,) * 2)
    fitted = method.fit(training)
    _, z0 = fitted.start(shifted, opts.dt)
    p = fitted.predict(z0, rom.parameters(shifted), N_STEPS, rom.observation(shifted))
    np.testing.assert_allclose(p.coords[1:] @ (rom.observation(shifted) @ p.basis).T, p.tracer_u, atol=1e-9)
    _, full = jb.simulate(shifted, opts.solver, n_steps=N_STEPS, dt=opts.dt)
    at_nominal = fitted.predict(z0, rom.parameters(shifted), N_STEPS).tracer_u
    assert float(rom.rmse(full.tracer_u, at_nominal)) * 1e6 > 10 * max(other.rmse_um, 1.0)
