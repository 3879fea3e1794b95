"""Model construction (:mod:`jaxbelt.build`) of coarse two-roller scenes against hand values from
the scene files: the 1D bar stiffness ``EA/ℓ`` on free elements only, the element masses ``ρAℓ``,
the pre-tension ``EA ε₀`` at the spans' ends, the roller DOFs (prescribed and loaded, the drive rate
``V/r``, inertias ``m`` and ``½ m r²``, translations in metres), and the steering loop of
``two-roller-steered`` (gains in SI, the sensor's element and row, the actuator's DOF index), with
the refusal of a sensor off the belt."""

import dataclasses
import math

import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.build import build_model, steering_loops, steering_sign
from jaxbelt.mesh import build_mesh
from jaxbelt.scene_values import SceneError
from helpers import scene_with

E, AREA, RHO = 2.5e9, 0.05 * 1e-4, 1420.0  # the two-roller belt: 50 mm × 0.1 mm polyimide
R, SPAN, V = 0.05, 0.275, 0.5
ARC = math.pi * R


def _coarse(d):
    d["mesh"].update(roller_elements=[5, 5], free_elements=[6, 6])


@pytest.fixture(scope="module")
def pretensioned():
    def mutate(d):
        _coarse(d)
        d["belt"]["length_mm"] = 863.0
        d["roller"][1]["translation_mm"] = [0.7, 0.0, 0.0]

    return build_model(scene_with(mutate))


def test_free_bars_give_ea_over_length_and_arcs_no_stiffness(pretensioned):
    m = pretensioned
    k = E * AREA / (SPAN / 6)
    Kd, Kl, Ku = (np.asarray(a)[:, 0, 0] for a in (m.K_diag, m.K_lower, m.K_upper))
    free_interior = [7, 8, 9, 18, 19, 20]
    np.testing.assert_allclose(Kd[free_interior], 2 * k, rtol=1e-12)
    np.testing.assert_allclose(Kl[free_interior], -k, rtol=1e-12)
    np.testing.assert_allclose(Ku[free_interior], -k, rtol=1e-12)
    np.testing.assert_allclose(Kd[[5, 11, 16, 0]], k, rtol=1e-12)  # contact lines: one free bar each
    assert np.all(Kd[[1, 2, 3, 4, 12, 13, 14, 15]] == 0)  # inside an arc


def test_element_masses_are_line_density_times_length(pretensioned):
    m_e = np.asarray(pretensioned.m_e0)
    np.testing.assert_allclose(m_e[:5], RHO * AREA * ARC / 5, rtol=1e-12)
    np.testing.assert_allclose(m_e[5:11], RHO * AREA * SPAN / 6, rtol=1e-12)
    np.testing.assert_allclose(m_e.sum(), RHO * AREA * (2 * ARC + 2 * SPAN), rtol=1e-12)


def test_pre_tension_acts_at_the_ends_of_each_span(pretensioned):
    """A belt of 863 mm on a path of 2πr + 550 mm: ``T = EA (L_path / L_belt − 1)``; inside a span
    the two bars' forces cancel."""
    f0 = np.asarray(pretensioned.f0)[:, 0]
    T = E * AREA * ((2 * ARC + 2 * SPAN) / 0.863 - 1.0)
    for first, last in ((5, 11), (16, 0)):  # the contact lines that bound span 1 and span 2
        assert abs(f0[first]) == pytest.approx(T, rel=1e-9) and f0[last] == pytest.approx(-f0[first], rel=1e-12)
    inside = [6, 7, 8, 9, 10, 17, 18, 19, 20, 21]
    assert np.abs(f0[inside]).max() < 1e-9 * T and np.abs(f0[[1, 2, 3, 4, 12, 13, 14, 15]]).max() == 0


def test_roller_dofs_of_a_drive_and_a_translated_idle_roller(pretensioned):
    m = pretensioned
    np.testing.assert_allclose(np.asarray(m.chi_static), [0.0, 0.0, 0.7e-3, 0.0], atol=1e-18)
    assert np.asarray(m.dynamic).tolist() == [False, False, False, True]  # the idle roller turns freely
    assert np.asarray(m.is_az).tolist() == [False, True, False, True]
    assert abs(float(m.omega[1])) == pytest.approx(V / R) and np.asarray(m.omega)[[0, 2, 3]].tolist() == [0, 0, 0]
    np.testing.assert_allclose(np.asarray(m.M_roller), [0.5, 0.5 * 0.5 * R ** 2] * 2, rtol=1e-15)
    np.testing.assert_allclose(np.asarray(m.roller_half_width), [0.03, 0.03])
    assert m.contact_columns == (*range(0, 6), *range(11, 17))
    assert m.contact_rollers == (0,) * 6 + (1,) * 6


def test_a_tension_roller_is_loaded_along_x():
    m = build_model(scene_with(_coarse, "two-roller-1d-tension"))
    assert np.asarray(m.dynamic).tolist() == [False, False, True, True]
    np.testing.assert_allclose(np.asarray(m.Q_ext), [0.0, 0.0, 100.0, 0.0])


@pytest.fixture(scope="module")
def steered():
    scene = jb.load_scene("two-roller-steered")
    return scene, build_mesh(scene)


def test_steering_loop_of_the_steered_scene_in_si_units(steered):
    scene, mesh = steered
    loops = steering_loops(scene, mesh)
    assert loops.labels == ("idle/y",) and loops.actuator_dof == (1 * 6 + 4,)  # (dx dy dz ax ay az) per roller
    np.testing.assert_allclose(np.asarray(loops.kp), [2.0])  # 2 mrad/mm = 2 rad/m
    np.testing.assert_allclose(np.asarray(loops.ki), [1.0])
    np.testing.assert_allclose(np.asarray(loops.limit), [2e-3])
    np.testing.assert_allclose(np.asarray(loops.sample), [scene.time.dt])  # no sample period: every step
    assert np.isinf(np.asarray(loops.rate_limit)).all() and np.asarray(loops.profile_amplitude).max() == 0
    assert float(loops.loop_length) == pytest.approx(mesh.length)
    assert abs(float(loops.sign[0])) == 1.0 and float(loops.sign[0]) == steering_sign(scene, "idle", "y")


def test_steering_sensor_is_located_on_its_element_and_row_by_hand(steered):
    """s = 689 mm lies on the second span (after an arc of 6, a span of 8 and an arc of 6 elements),
    z = 25 mm on the belt's edge (rows at −25, 0, 25 mm)."""
    scene, mesh = steered
    loops = steering_loops(scene, mesh)
    into = 0.689 - (2 * ARC + SPAN)
    h = SPAN / 8
    assert int(loops.sensor_col[0]) == 20 + int(into // h)
    assert float(loops.sensor_xi[0]) == pytest.approx(into / h - int(into // h), rel=1e-9)
    assert int(loops.sensor_row[0]) == 1 and float(loops.sensor_eta[0]) == pytest.approx(1.0)


def test_a_sensor_off_the_belt_is_refused(steered):
    scene, mesh = steered
    moved = scene.replace(control=(dataclasses.replace(scene.control[0], sensor=(0.9, 0.0)),))
    with pytest.raises(SceneError, match=r"control\[0\]\.sensor_mm = \[900\.0, 0\.0\]: s is off the belt "
                                         r"\(the path is 864\.159 mm long\)"):
        steering_loops(moved, mesh)
