"""The steering plant measured on the model (jaxbelt.design.steering) against independent references:
the moving-beam walk (jaxbelt.lateral_theory), the scene's geometry (hold angle = the drive's skew),
python-control's gain margin, and closed-loop runs."""

import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt import lateral_theory as th
from jaxbelt.design.steering import SteeringWarning, stability_boundary, steering_report


@pytest.fixture(scope="module")
def scene():
    return jb.load_scene("two-roller-steered")


@pytest.fixture(scope="module")
def report(scene):
    m = jb.build_model(scene)
    return steering_report(m, jb.RunOptions.from_scene(scene).replace(n_steps=600), sensitivity=False)


def test_hold_angle_is_the_drive_skew(report):
    assert report.hold_angle_mrad == pytest.approx(0.150, rel=0.01)
    assert not report.saturated


def test_coefficient_against_moving_beam_theory(scene, report):
    # the coarse grid (34 mm span elements) walks 35 % faster than the reference; the grid
    # converges to it (16/12 elements: +12 %, 32/24: +4.9 %): a loose check on the coarse grid
    alpha = np.zeros((2, 3))
    alpha[1, 1] = 1e-3
    ref = th.scene_walk_rate(scene, alpha)  # m/s for 1 mrad
    assert np.sign(report.coefficient_mm_s_per_mrad) == np.sign(ref)
    assert report.coefficient_mm_s_per_mrad / (ref * 1e3) == pytest.approx(1.0, rel=0.40)


def test_plant_reproduces_step_response(report):
    r = report.step_response
    y = np.asarray(r["sensor_mm_per_mrad"])
    fit = report.identified.step_response(np.asarray(r["t_s"]))
    assert np.max(np.abs(fit - y)) / np.ptp(y) < 0.06


def test_p_boundary_against_python_control_margin(scene, report):
    control = pytest.importorskip("control")
    w = np.geomspace(0.05, 40, 4000)
    plant = report.identified
    L = control.frd(np.sign(plant.gain) * plant.frequency_response(w), w)  # the loop sign folded in
    gm = control.stability_margins(L)[0]
    b = stability_boundary(jb.build_model(scene), jb.RunOptions.from_scene(scene).replace(n_steps=1000),
                           2.0, 5.0, rounds=2)
    assert b.bracket[0] < 3.2 and b.bracket[1] > 3.0
    # the target is 5 %: the identified plant's margin is +6 % from a 40 s step response and +14 % from
    # the 12 s one used here (the low-order recirculating form misses part of the first lap's shape)
    assert gm == pytest.approx(b.kp_mrad_per_mm, rel=0.15)


def test_saturation_is_reported(scene):
    import dataclasses
    specs = (dataclasses.replace(scene.control[0], limit=0.1e-3),)
    m = jb.build_model(scene.replace(control=specs))
    with pytest.warns(SteeringWarning, match=r"idle/y.*0\.15"):
        r = steering_report(m, jb.RunOptions.from_scene(scene).replace(n_steps=600), sensitivity=False)
    assert r.saturated
