"""One step of the direct Backward-Euler integrator (:mod:`jaxbelt.integrators.direct`) with each
linear solver of the registry, on a coarse pre-tensioned idle-translated 1D belt from a perturbed
state, against numpy: ``(M + Δt² K) ẍ = F − K (x + Δt ẋ)`` solved densely
(``np.linalg.solve``), then ``ẋ₁ = ẋ + Δt ẍ``, ``x₁ = x + Δt ẋ₁``; masses and step count untouched."""

import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.integrators.direct import DirectBackwardEuler
from jaxbelt.linalg import join
from jaxbelt.registry import LINEAR_SOLVERS
from helpers import dense_backward_euler, perturbed_state, solve_step

DT = 0.004


@pytest.fixture(scope="module")
def state(model):
    """The initial state, displacements and velocities perturbed; the element masses the model's
    (as the shift transport rule keeps them)."""
    return perturbed_state(model, moved_masses=False)


@pytest.fixture(scope="module")
def moved_masses_state(model):
    """The same, the element masses no longer uniform (as the source transport rule moves them)."""
    return perturbed_state(model)


@pytest.mark.parametrize("linear_solver", list(LINEAR_SOLVERS))
def test_step_equals_the_dense_backward_euler_step(model, state, linear_solver):
    x_ref, v_ref = dense_backward_euler(model, state, DT)
    s1 = solve_step(model, jb.make_solver("direct", linear_solver), state, DT)
    x1, v1 = np.asarray(join(s1.u, s1.chi)), np.asarray(join(s1.u_dot, s1.chi_dot))
    np.testing.assert_allclose(x1, x_ref, rtol=1e-9, atol=1e-10 * np.abs(x_ref).max())
    np.testing.assert_allclose(v1, v_ref, rtol=1e-9, atol=1e-10 * np.abs(v_ref).max())
    np.testing.assert_array_equal(np.asarray(s1.m_e), np.asarray(state.m_e))
    assert int(s1.step) == int(state.step)


@pytest.mark.parametrize("linear_solver", ["structured", "cyclic-reduction", "reuse", "dense"])
def test_solvers_that_factor_the_step_matrix_follow_moved_masses(model, moved_masses_state, linear_solver):
    """The kept-interior solve factors the interior once at the model's masses (constant under the
    shift rule) and is left out here; the others see the state's own masses."""
    x_ref, v_ref = dense_backward_euler(model, moved_masses_state, DT)
    s1 = solve_step(model, jb.make_solver("direct", linear_solver), moved_masses_state, DT)
    np.testing.assert_allclose(np.asarray(join(s1.u, s1.chi)), x_ref, rtol=1e-9, atol=1e-10 * np.abs(x_ref).max())
    np.testing.assert_allclose(np.asarray(join(s1.u_dot, s1.chi_dot)), v_ref, rtol=1e-9,
                               atol=1e-10 * np.abs(v_ref).max())


def test_a_solver_name_instead_of_an_object_is_refused_naming_the_choices():
    with pytest.raises(TypeError, match=r"linear_solver = 'dense': a linear solver object .*jaxbelt.make_solver takes"):
        DirectBackwardEuler("dense")


def test_default_solver_is_the_kept_interior_structured_solve():
    assert isinstance(DirectBackwardEuler().linear_solver, jb.KeptInterior)
    assert DirectBackwardEuler().transport == "shift"
