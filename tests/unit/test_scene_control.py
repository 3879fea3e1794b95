"""The ``[[control]]`` table: every rejection names the key and the value, before any work."""

import math

import pytest

import jaxbelt as jb
from helpers import builtin_dict, scene_with


def _steered(mutate=None):
    def edit(d):
        if mutate is not None:
            mutate(d)
    return scene_with(edit, "two-roller-steered")


def _reject(mutate, *fragments):
    with pytest.raises(jb.SceneError) as e:
        _steered(mutate)
    msg = str(e.value)
    for f in fragments:
        assert f in msg, msg


def _loop(d):
    return d["control"][0]


def test_the_table_is_read_in_si_units():
    c = _steered().control[0]
    assert (c.actuator, c.axis) == ("idle", "y")
    assert c.sensor == pytest.approx((0.689, 0.025))
    assert (c.kp, c.ki, c.kd) == (2.0, 1.0, 0.0)  # mrad/mm = rad/m
    assert c.limit == pytest.approx(2e-3) and c.sample is None and c.rate_limit is None


def test_optional_keys_and_edge_profile():
    def edit(d):
        _loop(d).update(sample_s=0.06, rate_limit_mrad_s=1.5, lag_s=0.1, setpoint_mm=0.01, noise_um=2.0, seed=7,
                        edge_profile_um=[[1, 5.0, 0.3], [3, 2.0, 0.0]])
    c = _steered(edit).control[0]
    assert c.sample == 0.06 and c.rate_limit == pytest.approx(1.5e-3) and c.lag == 0.1
    assert c.setpoint == pytest.approx(1e-5) and c.noise == pytest.approx(2e-6) and c.seed == 7
    assert [list(h) for h in c.edge_profile] == [pytest.approx([1.0, 5e-6, 0.3]), pytest.approx([3.0, 2e-6, 0.0])]


@pytest.mark.parametrize("key, value, fragment", [
    ("actuator", "roller 9", "no roller of that name"),
    ("axis", "z", "must be one of x, y"),
    ("sensor_mm", [689.0, 30.0], "off the belt"),
    ("sensor_mm", [-5.0, 0.0], "must not be negative"),
    ("sample_s", 0.03, "whole multiple of time.dt_s"),
    ("limit_mrad", -1.0, "must be positive"),
    ("limit_mrad", 60.0, "beyond the model's range"),
    ("lag_s", -0.1, "must not be negative"),
    ("noise_um", -1.0, "must not be negative"),
    ("kp_mrad_per_mm", math.nan, "must be finite"),
    ("ki_mrad_per_mm_s", -1.0, "must not be negative"),
    ("rate_limit_mrad_s", 0.0, "must be positive"),
    ("seed", -3, "non-negative integer"),
    ("edge_profile_um", [[0.5, 1.0, 0.0]], "whole number"),
    ("edge_profile_um", [[1, 1.0]], "triples"),
    ("gain", 3.0, "unknown key"),
])
def test_bad_values_name_key_and_value(key, value, fragment):
    _reject(lambda d: _loop(d).update({key: value}), f"control[0].{key}", fragment)


def test_missing_actuator_and_sensor():
    _reject(lambda d: _loop(d).pop("actuator"), "control[0].actuator", "required")
    _reject(lambda d: _loop(d).pop("sensor_mm"), "control[0].sensor_mm", "required")


def test_control_needs_lateral_transport():
    _reject(lambda d: d["solver"].update(lateral_transport=False), "lateral_transport", "[[control]]")


def test_an_actuator_on_a_torque_loaded_dof_is_refused():
    def edit(d):  # a variant's roller table: the idle roller becomes a tension roller with a torque about y
        d.setdefault("variant", {})["idle"] = dict(role="tension", torque_nm=[0.0, 0.5, 0.0])
    _reject(edit, "control[0].axis", "torque-loaded")


def test_a_sensor_beyond_the_path_is_refused_when_the_grid_is_built():
    sc = _steered(lambda d: _loop(d).update(sensor_mm=[5000.0, 0.0]))
    with pytest.raises(jb.SceneError, match=r"control\[0\].sensor_mm.*off the belt"):
        jb.build_model(sc)


def test_two_loops_on_one_actuated_rotation_are_refused():
    def edit(d):
        d["control"].append(dict(_loop(d), sensor_mm=[100.0, 0.0]))
    _reject(edit, "control[1]", "already drives this actuator about this axis")


def test_two_loops_on_different_axes_of_one_roller_are_accepted():
    def edit(d):
        d["control"].append(dict(_loop(d), axis="x"))
    assert [(c.actuator, c.axis) for c in _steered(edit).control] == [("idle", "y"), ("idle", "x")]


def test_a_single_control_table_is_refused():
    def edit(d):
        d["control"] = _loop(d)  # [control], not [[control]]
    _reject(edit, "control", "[[control]]", "one per loop")


def test_a_loop_on_a_1d_scene_names_the_2d_model_at_once():
    def edit(d, lateral):  # the 2D scene's valid loop, on the 1D machine
        d["control"] = [dict(builtin_dict("two-roller-steered")["control"][0], sensor_mm=[100.0, 0.0])]
        if lateral:
            d.setdefault("solver", {})["lateral_transport"] = True
    for lateral in (False, True):
        with pytest.raises(jb.SceneError) as e:
            scene_with(lambda d: edit(d, lateral), "two-roller-1d")
        assert "needs a 2D scene" in str(e.value), str(e.value)
