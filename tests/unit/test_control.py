"""The steering controller's law on small arrays (no runs): sampling and hold, the PID terms,
saturation with anti-windup, the actuator's lag and rate limit, the sensor's edge profile and
noise (jaxbelt.control)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxbelt.control import (ControllerState, SteeringLoops, controller_update, edge_profile, measure,
                             sensor_displacement)


def loops(**kw):
    base = dict(sensor_col=jnp.array([1]), sensor_xi=jnp.array([0.25]), sensor_row=jnp.array([0]),
                sensor_eta=jnp.array([0.5]), sensor_s=jnp.array([0.3]), kp=jnp.array([2.0]), ki=jnp.array([0.0]),
                kd=jnp.array([0.0]), sign=jnp.array([1.0]), sample=jnp.array([0.01]), limit=jnp.array([1e-3]),
                rate_limit=jnp.array([jnp.inf]), lag=jnp.array([0.0]), setpoint=jnp.array([0.0]),
                noise=jnp.array([0.0]), key=jax.random.key_data(jax.random.key(0))[None],
                profile_harmonic=jnp.array([[1.0]]), profile_amplitude=jnp.array([[0.0]]),
                profile_phase=jnp.array([[0.0]]), loop_length=jnp.asarray(2.0), actuator_dof=(4,), labels=("r/y",))
    base.update({k: jnp.atleast_1d(jnp.asarray(v, float)) if k not in ("key",) else v for k, v in kw.items()})
    return SteeringLoops(**base)


def rest():
    z = jnp.zeros(1)
    return ControllerState(integral=z, error=z, command=z, angle=z, travel=jnp.zeros(()))


def run(lp, readings, dt=0.01, state=None):
    state = rest() if state is None else state
    angles = []
    for k, y in enumerate(readings):
        state, a = controller_update(lp, state, jnp.array([y]), k, dt)
        angles.append(float(a[0]))
    return state, np.array(angles)


def test_proportional_command_acts_against_the_error_through_the_sign():
    _, a = run(loops(kp=2.0, sign=1.0), [1e-4])
    assert a[0] == pytest.approx(-2e-4)
    _, a = run(loops(kp=2.0, sign=-1.0), [1e-4])
    assert a[0] == pytest.approx(2e-4)


def test_integral_accumulates_the_sampled_error():
    _, a = run(loops(kp=0.0, ki=3.0), [1e-4] * 4)
    assert a == pytest.approx(-3.0 * 1e-4 * 0.01 * np.arange(1, 5))


def test_derivative_acts_on_the_change_of_the_error():
    _, a = run(loops(kp=0.0, kd=0.5), [0.0, 1e-5, 1e-5])
    assert a == pytest.approx([0.0, -0.5 * 1e-5 / 0.01, 0.0])


def test_sample_and_hold_every_n_steps():
    _, a = run(loops(kp=1.0, sample=0.03), [1e-4, 2e-4, 3e-4, 4e-4, 5e-4, 6e-4, 7e-4])
    assert a == pytest.approx(-np.array([1e-4, 1e-4, 1e-4, 4e-4, 4e-4, 4e-4, 7e-4]))


def test_saturation_clamps_the_command_and_the_integral_does_not_wind_up():
    lp = loops(kp=1.0, ki=10.0, limit=1e-4)
    state, a = run(lp, [1e-3] * 50)
    assert np.max(np.abs(a)) == pytest.approx(1e-4)
    # no integration while saturated in the error's direction: a reversed error unsaturates at once
    assert float(state.integral[0]) == 0.0
    _, a = run(lp, [-1e-5], state=state)
    assert a[0] == pytest.approx(1e-5 + 10.0 * 0.01 * 1e-5)
    state, a = run(loops(kp=0.0, ki=10.0, limit=1e-4), [1e-3] * 50)  # integral alone: held at the range
    assert float(state.integral[0]) == pytest.approx(1e-4) and a[-1] == pytest.approx(-1e-4)


def test_actuator_lag_is_a_first_order_backward_euler_response():
    _, a = run(loops(kp=1.0, lag=0.09, limit=1.0), [-1e-3] * 3)
    target, f = 1e-3, 0.01 / (0.09 + 0.01)
    assert a == pytest.approx(target * (1 - (1 - f) ** np.arange(1, 4)))


def test_rate_limit_bounds_the_angle_change_per_step():
    _, a = run(loops(kp=1.0, rate_limit=0.02, limit=1.0), [-1e-3] * 8)
    assert np.diff(np.concatenate([[0.0], a])) == pytest.approx(np.r_[[0.0002] * 5, [0.0], [0.0], [0.0]])


def test_sensor_reads_bilinearly_and_sees_the_edge_profile_once_per_loop():
    u = jnp.zeros((4, 6)).at[1, 1].set(1.0).at[2, 1].set(3.0).at[1, 3].set(5.0)  # v at (col, row): 1, 3, 5
    lp = loops()
    # ξ = 0.25 between columns 1 and 2, η = 0.5 between rows 0 and 1
    want = 0.75 * 0.5 * 1.0 + 0.25 * 0.5 * 3.0 + 0.75 * 0.5 * 5.0
    assert float(sensor_displacement(lp, u)[0]) == pytest.approx(want)
    lp = loops(profile_harmonic=[[2.0]], profile_amplitude=[[4e-6]], profile_phase=[[0.1]])
    p0 = float(edge_profile(lp, 0.0)[0])
    assert p0 == pytest.approx(4e-6 * np.sin(2 * np.pi * 2 * 0.3 / 2.0 + 0.1))
    assert float(edge_profile(lp, 2.0)[0]) == pytest.approx(p0)  # one loop later: the same material
    assert float(edge_profile(lp, 1.0)[0]) == pytest.approx(p0)  # harmonic 2: half a loop as well
    assert float(edge_profile(lp, 0.25)[0]) == pytest.approx(4e-6 * np.sin(2 * np.pi * 2 * 0.05 / 2.0 + 0.1))


def test_sensor_noise_has_its_sigma_and_repeats_with_the_seed():
    u = jnp.zeros((4, 6))
    lp = loops(noise=2e-6)
    y = jax.vmap(lambda k: measure(lp, u, 0.0, k))(jnp.arange(4000))[:, 0]
    assert float(jnp.std(y)) == pytest.approx(2e-6, rel=0.05) and abs(float(jnp.mean(y))) < 2e-7
    again = jax.vmap(lambda k: measure(lp, u, 0.0, k))(jnp.arange(4000))[:, 0]
    assert np.array_equal(np.asarray(y), np.asarray(again))
    other = loops(noise=2e-6, key=jax.random.key_data(jax.random.key(1))[None])
    y1 = jax.vmap(lambda k: measure(other, u, 0.0, k))(jnp.arange(100))[:, 0]
    assert not np.allclose(np.asarray(y1), np.asarray(y[:100]))
