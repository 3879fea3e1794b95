"""The checks of a run (:mod:`jaxbelt.run_checks`) against hand values on a coarse 1D belt (5
elements on each 50 mm arc, 6 on each 275 mm span; drive surface 0.5 m/s): the belt speed, the
CFL limit of the time step (the shortest element π·50/5 mm), the start masses a kept-factor solver
accepts, and the first non-finite part of a state or a trajectory, with their exact messages;
every check is skipped for traced values."""

import math
from types import SimpleNamespace

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from helpers import load, pretensioned_idle_translated_machine, scene_with
from jaxbelt.run_checks import (NONFINITE_CAUSES, NonFiniteStateError, belt_speed, check_finite, check_start_masses,
                                check_time_step, first_nonfinite, nonfinite_code)

ELL_MIN = math.pi * 0.05 / 5  # m: an arc element, shorter than a span's 0.275 / 6


@pytest.fixture(scope="module")
def model():
    return pretensioned_idle_translated_machine()


def test_belt_speed_is_the_drive_surface_speed(model):
    assert belt_speed(model) == pytest.approx(0.5, rel=1e-12)
    fast = load(scene_with(lambda d: (d["mesh"].update(roller_elements=[5, 5], free_elements=[6, 6]),
                                      d["roller"][0].update(speed_m_s=0.8))))[0]
    assert belt_speed(fast) == pytest.approx(0.8, rel=1e-12)


def test_time_step_within_the_cfl_limit_passes_and_beyond_it_is_refused(model):
    assert float(np.min(np.asarray(model.ell))) == pytest.approx(ELL_MIN, rel=1e-12)
    limit = ELL_MIN / 0.5  # 62.83 ms
    check_time_step(model, 0.99 * limit)
    check_time_step(model, np.float32(0.01))
    with pytest.raises(ValueError) as e:
        check_time_step(model, 0.063)
    assert str(e.value).startswith("dt = 0.063 s violates the CFL condition of the transport step (belt speed "
                                   "0.5 m/s × dt = 31.5 mm >= smallest element 31.42 mm); ")
    with pytest.raises(ValueError, match="violates the CFL condition"):
        check_time_step(model, limit)  # V Δt = ℓ_min: not strictly less


@pytest.mark.parametrize("dt,shown", [(0.0, "0.0"), (-0.001, "-0.001"), (float("nan"), "nan"), (float("inf"), "inf")])
def test_time_step_that_is_not_a_positive_number_is_refused(model, dt, shown):
    with pytest.raises(ValueError, match=rf"^dt = {shown}: must be a positive number of seconds$"):
        check_time_step(model, dt)


def test_checks_are_skipped_for_traced_values(model):
    """Inside a trace the caller checks: a time step over the CFL limit, masses off the model's and
    a non-finite trajectory pass without an error."""
    solver = jb.DirectBackwardEuler(jb.KeptInterior())

    def traced(dt, m_e, code):
        check_time_step(model, dt)
        check_start_masses(model, solver, SimpleNamespace(m_e=m_e))  # the state's masses are all it reads
        check_finite(SimpleNamespace(nonfinite=code, t=jnp.ones(2)), 0.01)
        return dt

    jax.make_jaxpr(traced)(1.0, 2.0 * np.asarray(model.m_e0), jnp.array([0, 1], jnp.int8))


def _with_masses(m_e):
    """A start state as the check reads it: its element masses."""
    return SimpleNamespace(m_e=jnp.asarray(m_e))


def test_kept_factors_refuse_start_masses_off_the_model(model):
    solver = jb.DirectBackwardEuler(jb.KeptInterior())
    m0 = np.asarray(model.m_e0)
    moved = m0.copy()
    moved[3] *= 1.25
    with pytest.raises(ValueError) as e:
        check_start_masses(model, solver, _with_masses(moved))
    assert str(e.value) == ("y0's element masses differ from the model's (by up to 0.25 relative) and KeptInterior "
                            "keeps its factors at the model's for the whole run; step it with a solver that factors "
                            "every step (DirectBackwardEuler(Structured()))")
    check_start_masses(model, solver, _with_masses(m0 * (1 + 5e-7)))  # round-off: within 10⁻⁶
    with pytest.raises(ValueError, match="by up to 2e-06 relative"):
        check_start_masses(model, solver, _with_masses(m0 * (1 + 2e-6)))
    with pytest.raises(ValueError, match="by up to nan relative"):
        check_start_masses(model, solver, _with_masses(m0[:-1]))
    check_start_masses(model, solver, None)


def test_solvers_that_factor_at_the_state_accept_any_start_masses(model):
    moved = _with_masses(1.3 * np.asarray(model.m_e0))
    for solver in (jb.DirectBackwardEuler(jb.KeptInterior(), transport="source"),  # masses move every step
                   jb.DirectBackwardEuler(jb.Structured()), jb.DirectBackwardEuler(jb.Reuse()),
                   jb.NaiveBackwardEuler()):
        check_start_masses(model, solver, moved)


@pytest.mark.parametrize("bad,code", [("u", 1), ("u_dot", 2), ("chi", 3), ("chi_dot", 3)])
def test_nonfinite_code_names_the_first_bad_part(bad, code):
    parts = dict(u=np.zeros((4, 2)), u_dot=np.zeros((4, 2)), chi=np.zeros(3), chi_dot=np.zeros(3))
    assert int(nonfinite_code(**parts)) == 0
    parts[bad] = parts[bad].copy()
    parts[bad].flat[1] = np.nan if code != 2 else np.inf
    got = nonfinite_code(**parts)
    assert got.dtype == jnp.int8 and int(got) == code
    assert NONFINITE_CAUSES[code] == {1: "belt displacement", 2: "belt velocity", 3: "roller state"}[code]


def test_nonfinite_code_reports_the_displacement_before_the_velocity():
    bad = np.full((2, 1), np.nan)
    assert int(nonfinite_code(bad, bad, np.full(2, np.inf), np.zeros(2))) == 1


def test_first_nonfinite_step_and_the_error_naming_it():
    traj = SimpleNamespace(nonfinite=np.array([0, 0, 2, 3], np.int8), t=np.array([0.005, 0.01, 0.015, 0.02]))
    assert first_nonfinite(traj) == (2, 0.015, "belt velocity")
    with pytest.raises(NonFiniteStateError) as e:
        check_finite(traj, 0.005)
    assert str(e.value) == ("the simulation diverged: non-finite belt velocity at step 3 (t = 0.015 s); check the time "
                            "step against the CFL limit, the transport weights and the scene")
    assert isinstance(e.value, FloatingPointError)
    # recorded every 4th step: the step number comes from the time, not the row
    every4 = SimpleNamespace(nonfinite=np.array([0, 1], np.int8), t=np.array([0.02, 0.04]))
    with pytest.raises(NonFiniteStateError, match=r"non-finite belt displacement at step 8 \(t = 0.04 s\)"):
        check_finite(every4, 0.005)
    with pytest.raises(NonFiniteStateError, match=r"non-finite belt displacement at step 2 \(t = 0.04 s\)"):
        check_finite(every4)  # no time step: the row's number


def test_a_finite_trajectory_passes():
    traj = SimpleNamespace(nonfinite=np.zeros(5, np.int8), t=np.arange(1, 6) * 0.01)
    assert first_nonfinite(traj) is None
    assert check_finite(traj, 0.01) is None
