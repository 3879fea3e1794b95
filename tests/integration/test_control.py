"""Closed-loop runs (jaxbelt.control inside the time loop): the records, the loop doing its job,
gradients and vmap through the gains, no recompile for new gains, and the command line's report."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from helpers import central_difference, scene_fixtures
from jaxbelt.cli import main

loaded, model, dt = scene_fixtures("two-roller-steered")
N = 300  # 6 s


def with_gains(model, kp, ki=0.0, kd=0.0):
    return model.replace(control=model.control.with_gains(kp, ki, kd))


def run(model, options, n_steps=N):
    return jb.simulate(model, options.solver, n_steps=n_steps, dt=options.dt, check=False)[1]


@pytest.fixture(scope="module")
def open_and_closed(loaded):
    model, options = loaded
    return run(with_gains(model, 0.0), options, 900), run(model, options, 900)


def test_records_of_a_steered_run_and_none_without_a_loop(loaded, open_and_closed):
    model, options = loaded
    _, closed = open_and_closed
    assert closed.control_u.shape == (900, 1) and closed.sensor_v.shape == (900, 1)
    # the actuated rotation is the roller's static value plus the controller's angle
    dof = model.control.actuator_dof[0]
    p, d = model.n_rollers, len(model.dofs)
    chi = np.asarray(closed.roller_state).reshape(-1, p * d)[:, dof]
    assert chi == pytest.approx(float(model.chi_static[dof]) + np.asarray(closed.control_u)[:, 0], abs=1e-15)
    plain = run(model.replace(control=None), options, 5)
    assert plain.control_u is None and plain.sensor_v is None


def test_open_loop_walks_and_the_loop_stops_the_walk(open_and_closed):
    open_, closed = open_and_closed
    t = np.asarray(open_.t)
    late = slice(600, 900)
    walk_open = np.polyfit(t[late], np.asarray(open_.sensor_v)[late, 0], 1)[0]
    walk_closed = np.polyfit(t[late], np.asarray(closed.sensor_v)[late, 0], 1)[0]
    assert walk_open > 5e-6  # m/s: the skewed drive walks the belt (about 11 µm/s)
    assert np.all(np.asarray(open_.control_u) == 0.0)
    # the loop is taking over the drive's skew (hold angle 0.15 mrad; the PI loop settles in ~100 s)
    assert 0.3 < float(closed.control_u[-1, 0]) / 0.15e-3 < 1.5
    assert abs(walk_closed) < walk_open
    assert np.max(np.abs(np.asarray(closed.sensor_v)[late, 0])) < 0.5 * abs(np.asarray(open_.sensor_v)[-1, 0])


def test_gradient_wrt_the_gains_matches_central_differences(loaded):
    model, options = loaded

    def final_sensor(gains):
        tr = run(with_gains(model, gains[0], gains[1]), options, 150)
        return tr.sensor_v[-1, 0] * 1e6

    g0 = jnp.array([1.5, 0.8])
    value_and_grad = jax.jit(jax.value_and_grad(final_sensor))  # one program for both
    grad = value_and_grad(g0)[1]
    for i in range(2):
        e = jnp.zeros(2).at[i].set(1.0)
        fd = central_difference(lambda h: value_and_grad(g0 + h * e)[0], 0.0, 1e-3)
        assert float(grad[i]) == pytest.approx(float(fd), rel=1e-5, abs=1e-9)


def test_vmap_over_gains_equals_separate_runs_and_new_gains_do_not_compile(loaded):
    model, options = loaded
    kps = jnp.array([0.5, 2.0])
    batched = jax.vmap(lambda kp: run(with_gains(model, kp, 1.0), options, 40).sensor_v)(kps)
    for i, kp in enumerate(kps):
        one = run(with_gains(model, kp, 1.0), options, 40).sensor_v
        assert np.asarray(batched[i]) == pytest.approx(np.asarray(one), rel=1e-9, abs=1e-15)
    events = []

    def listener(event, duration, **kwargs):
        if event == "/jax/core/compile/backend_compile_duration":
            events.append(event)

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        run(with_gains(model, 0.7, 0.3), options, 40)
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)
    assert events == []


def test_simulate_json_reports_the_loop_and_warns_when_it_saturates(capsys, tmp_path):
    scene = tmp_path / "tight.toml"
    scene.write_text('extends = "two-roller-steered"\n[time]\nt_end_s = 6.0\n'
                     '[[control]]\nactuator = "idle"\naxis = "y"\nsensor_mm = [689.0, 25.0]\n'
                     'kp_mrad_per_mm = 2.0\nki_mrad_per_mm_s = 1.0\nlimit_mrad = 0.05\n')
    assert main(["simulate", str(scene), "--json"]) == 0
    out, err = capsys.readouterr()
    (c,) = json.loads(out)["control"]
    assert set(c) >= {"actuator", "axis", "sensor_um_final", "u_mrad_final", "u_mrad_max", "saturated"}
    assert (c["actuator"], c["axis"]) == ("idle", "y")
    assert c["saturated"] and c["u_mrad_max"] == pytest.approx(0.05)  # it needs 0.15 mrad
    assert "steering loop idle/y saturated" in err and "±0.05 mrad" in err
