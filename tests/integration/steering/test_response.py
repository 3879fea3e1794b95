"""The measured response of a steering loop (jaxbelt.steering.response): the one step response
against two runs of ``simulate`` made here, and the measured transfer against the plant it samples."""

import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.control import walk_rate
from jaxbelt.steering.plant import SteeringPlant
from jaxbelt.steering.response import (STEP_RAD, WALK_WINDOW_S, MeasuredResponse, actuator_step,
                                       open_loop_response, run_batch)
from jaxbelt.steering.transfer import margins


@pytest.fixture(scope="module")
def machine():
    scene = jb.load_scene("two-roller-steered")
    return jb.build_model(scene), jb.RunOptions.from_scene(scene).replace(n_steps=300)


def test_open_loop_response_is_the_stepped_run_minus_the_open_run(machine):
    """The response equals (stepped − open) / amplitude of two runs made one at a time with
    :func:`jaxbelt.simulate`, its rate the walk rate over the last seconds of that record, and the
    stepped run holds the actuator at the step."""
    model, options = machine
    a = 2 * STEP_RAD
    r = open_loop_response(model, options, amplitude=a)
    opened = model.replace(control=model.control.with_gains(0.0, 0.0, 0.0))
    stepped = opened.replace(control=actuator_step(opened.control, a))
    runs = [jb.simulate(m, options.solver, n_steps=options.n_steps, dt=options.dt)[1] for m in (opened, stepped)]
    ref = (np.asarray(runs[1].sensor_v[:, 0]) - np.asarray(runs[0].sensor_v[:, 0])) / a
    t = np.asarray(runs[0].t)
    np.testing.assert_allclose(r.t, t, rtol=1e-14)
    np.testing.assert_allclose(r.step, ref, rtol=1e-9, atol=1e-12 * np.max(np.abs(ref)))
    assert np.max(np.abs(r.step)) > 0
    assert r.rate == pytest.approx(float(walk_rate(t, ref, (t[-1] - WALK_WINDOW_S, t[-1]))), rel=1e-8)
    assert r.dt == options.dt
    np.testing.assert_allclose(np.asarray(runs[1].control_u[-1, 0]), a, rtol=1e-6)
    assert np.all(np.asarray(runs[0].control_u) == 0.0)


def test_run_batch_equals_runs_one_at_a_time(machine):
    """The vmapped batch of loop settings equals each setting run alone."""
    model, options = machine
    short = options.replace(n_steps=60)
    models = [model.replace(control=model.control.with_gains(kp, 0.0, 0.0)) for kp in (0.0, 0.5)]
    t, v, u, _ = run_batch(models, short)
    for m, vb, ub in zip(models, v, u):
        tr = jb.simulate(m, short.solver, n_steps=short.n_steps, dt=short.dt)[1]
        np.testing.assert_allclose(vb, np.asarray(tr.sensor_v[:, 0]), rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(ub, np.asarray(tr.control_u[:, 0]), rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(t, np.arange(1, short.n_steps + 1) * short.dt, rtol=1e-12)


def test_measured_response_has_the_margins_of_the_plant_it_samples():
    """A plant's step response, sampled and read as a measured response (a Fourier sum), has the
    plant's own margins under the one ``margins``: the two descriptions of a transfer agree."""
    plant = SteeringPlant(-0.0742, 0.05, 0.25)
    dt = 1e-3
    t = np.arange(1, 30001) * dt
    measured = MeasuredResponse(t=t, step=plant.step_response(t), dt=dt, rate=plant.gain)
    for kp, ki in ((1.0, 0.1), (3.0, 1.0)):
        gm, pm, w_pc, w_gc = margins(measured, kp, ki)
        ref = margins(plant, kp, ki)
        assert gm == pytest.approx(ref[0], rel=2e-3) and pm == pytest.approx(ref[1], abs=0.2)
        assert w_pc == pytest.approx(ref[2], rel=2e-3) and w_gc == pytest.approx(ref[3], rel=2e-3)
