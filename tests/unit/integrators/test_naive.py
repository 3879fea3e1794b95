"""The source's 3N Backward-Euler system (:mod:`jaxbelt.integrators.naive`) on a coarse
pre-tensioned idle-translated 1D belt from a perturbed state with non-uniform masses, against numpy:
its step equals the N-unknown dense step ``(M + Δt² K) ẍ = F − K (x + Δt ẋ)`` (``np.linalg.solve``);
the drive turns by its prescribed ``ω Δt``; the transport rule it carries is the one asked for."""

import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.integrators.naive import NaiveBackwardEuler
from jaxbelt.linalg import join
from helpers import (dense_backward_euler, load, perturbed_state, scene_with,
                     solve_step)

DT = 0.004


@pytest.mark.parametrize("seed", [2, 3])
def test_step_equals_the_n_unknown_dense_step(model, seed):
    state = perturbed_state(model, seed)
    x_ref, v_ref = dense_backward_euler(model, state, DT)
    s1 = solve_step(model, NaiveBackwardEuler(), state, DT)
    np.testing.assert_allclose(np.asarray(join(s1.u, s1.chi)), x_ref, rtol=1e-8, atol=1e-9 * np.abs(x_ref).max())
    np.testing.assert_allclose(np.asarray(join(s1.u_dot, s1.chi_dot)), v_ref, rtol=1e-7,
                               atol=1e-8 * np.abs(v_ref).max())
    np.testing.assert_array_equal(np.asarray(s1.m_e), np.asarray(state.m_e))
    assert int(s1.step) == int(state.step)


def test_the_drive_turns_by_its_prescribed_angle_in_one_step():
    """From the initial state the drive's angle advances by ``ω Δt`` (its prescribed row) and its
    Backward-Euler rate is ``ω``."""
    model = load(scene_with(lambda d: d["mesh"].update(roller_elements=[5, 5], free_elements=[6, 6])))[0]
    s0 = jb.initial_state(model)
    s1 = solve_step(model, NaiveBackwardEuler(), s0, DT)
    omega = np.asarray(model.omega)
    drive = int(np.argmax(np.abs(omega)))
    assert float(s1.chi[drive]) == pytest.approx(float(s0.chi[drive]) + omega[drive] * DT, rel=1e-9)
    np.testing.assert_allclose(float(s1.chi_dot[drive]), omega[drive], rtol=1e-9)


def test_transport_rule_is_carried_and_checked():
    assert NaiveBackwardEuler().transport == "shift"
    assert NaiveBackwardEuler(transport="source").transport == "source"
    with pytest.raises(ValueError, match="transport = 'upwind': unknown rule"):
        NaiveBackwardEuler(transport="upwind")
