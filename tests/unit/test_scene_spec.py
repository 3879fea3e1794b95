"""The scene's plain dataclasses (:mod:`jaxbelt.scene_spec`) against hand-computed values: the belt's
cross-section area and uniform pre-strain ``L_path / L_belt − 1``, the step count of a time span
(rounded, not truncated), the defaults a scene file may leave out (equal to what the parser fills
in), immutability and ``Scene.replace``."""

import dataclasses

import pytest

from jaxbelt import registry
from jaxbelt.scene_spec import BeltSpec, ControlSpec, MeshSpec, OutputSpec, SolverSpec, TimeSpec
from helpers import builtin_dict, scene_with


def _belt(length=None):
    return BeltSpec(width=0.05, thickness=1e-4, youngs_modulus=2.5e9, poisson_ratio=0.34, density=1420.0,
                    length=length)


def test_area_is_width_times_thickness():
    assert _belt().area == pytest.approx(5e-6, rel=1e-15)


@pytest.mark.parametrize("belt_length,path_length,strain", [(1.0, 1.002, 0.002), (0.5, 0.5, 0.0),
                                                             (2.0, 2.1, 0.05)])
def test_pre_strain_of_a_belt_shorter_than_its_path(belt_length, path_length, strain):
    assert _belt(belt_length).pre_strain(path_length) == pytest.approx(strain, rel=1e-12, abs=1e-15)


def test_belt_without_a_length_has_no_pre_strain():
    assert _belt().pre_strain(1.37) == 0.0


@pytest.mark.parametrize("dt,t_end,n", [(0.1, 0.3, 3), (0.005, 5.0, 1000), (0.1, 0.7, 7), (0.002, 0.0119, 6),
                                        (0.25, 1.0, 4)])
def test_step_count_is_the_rounded_ratio(dt, t_end, n):
    """``0.3 / 0.1 = 2.9999999999999996`` in floating point: truncation would lose a step."""
    assert TimeSpec(dt, t_end).n_steps == n


def test_scene_file_without_optional_tables_gets_the_dataclass_defaults():
    def strip(d):
        d.pop("output", None)
        d.pop("solver", None)
        d["time"].pop("start", None)

    scene = scene_with(strip)
    assert scene.output == OutputSpec() and scene.solver == SolverSpec()
    assert scene.time.start == TimeSpec(1.0, 2.0).start == "rest"
    assert (SolverSpec().integrator, SolverSpec().linear_solver, SolverSpec().transport) == (
        registry.DEFAULT_INTEGRATOR, registry.DEFAULT_LINEAR_SOLVER, registry.DEFAULT_TRANSPORT)


def test_mesh_defaults_are_one_row_of_incompatible_mode_quads():
    m = MeshSpec()
    assert (m.n_eta, m.n_xi, m.element_length, m.roller_elements, m.free_elements, m.element) == (
        1, None, None, None, None, "qm6")


def test_specs_are_frozen_and_replace_returns_a_changed_copy():
    scene = scene_with(lambda d: None)
    with pytest.raises(dataclasses.FrozenInstanceError):
        scene.kind = "2d"
    with pytest.raises(dataclasses.FrozenInstanceError):
        scene.belt.width = 1.0
    other = scene.replace(description="changed", time=TimeSpec(0.01, 0.1))
    assert other.description == "changed" and other.time.n_steps == 10
    assert scene.description == builtin_dict()["model"]["description"] and scene.time.dt == 0.005
    assert other.rollers is scene.rollers and other.belt is scene.belt


def test_roller_specs_hold_si_values_of_the_file():
    scene = scene_with(lambda d: None)
    rollers = builtin_dict()["roller"]
    assert [r.name for r in scene.rollers] == [r["name"] for r in rollers]
    for spec, raw in zip(scene.rollers, rollers):
        assert spec.radius == pytest.approx(raw["radius_mm"] * 1e-3)
        assert spec.width == pytest.approx(raw["width_mm"] * 1e-3)
        assert spec.mass == raw["mass_kg"] and spec.role == raw["role"]
        assert spec.translation == (0.0, 0.0, 0.0) and spec.rotation == (0.0, 0.0, 0.0)


def test_control_defaults_are_a_pure_proportional_loop_within_five_mrad():
    c = ControlSpec(actuator="idle", axis="x", sensor=(0.1, 0.0), kp=1.0)
    assert (c.ki, c.kd, c.sample, c.limit, c.rate_limit, c.lag, c.setpoint, c.noise, c.edge_profile) == (
        0.0, 0.0, None, 5e-3, None, 0.0, 0.0, 0.0, ())
