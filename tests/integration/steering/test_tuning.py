"""Steering-loop tuning (:mod:`jaxbelt.steering.tuning`, ``jaxbelt tune``) on ``two-roller-steered``.

Closed-loop runs of 30 s, the measured response's own length, and few Adam iterations; one
measured response and one tuning shared by the module, and the command line run in-process on the
same run length, so it reuses the compiled programs."""

import json

import control
import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.cli import main
from jaxbelt.steering import tuning
from jaxbelt.steering.plant import SteeringPlant
from jaxbelt.steering.response import open_loop_response

T_END = 30.0


@pytest.fixture(scope="module")
def setup():
    jb.enable_x64()
    scene = jb.load_scene("two-roller-steered")
    model = jb.build_model(scene)
    options = jb.RunOptions.from_scene(scene)
    options = options.replace(n_steps=int(round(T_END / options.dt)))
    response = open_loop_response(model, options)
    return model, options, response


@pytest.fixture(scope="module")
def result(setup):
    model, options, response = setup
    return tuning.tune(model, options, iterations=4, response=response)


def test_gradient_matches_central_differences(setup):
    model, options, _ = setup
    g = np.array([1.5, 0.3])
    v, grad = tuning.objective_and_grad(model, g, options)
    assert v == pytest.approx(float(tuning.objective(model, g, options)), rel=1e-10)
    for i in range(2):
        h = np.zeros(2)
        h[i] = 1e-4 * g[i]
        fd = (float(tuning.objective(model, g + h, options)) - float(tuning.objective(model, g - h, options))) / (2 * h[i])
        assert grad[i] == pytest.approx(fd, rel=1e-4)


def test_tuning_lowers_the_objective_within_the_margins(result, setup):
    r = result
    c = setup[0].control
    result_model_gains = (float(c.kp[0]), float(c.ki[0]))  # rad/m = mrad/mm
    assert r.tuned.objective < r.start.objective and r.improvement > 0
    assert len(r.history) == r.iterations + 1 and min(r.history) == pytest.approx(r.tuned.objective, rel=1e-9)
    for p in (r.start, r.tuned):
        assert p.feasible and p.gain_margin_db >= 6.0 and p.phase_margin_deg >= 45.0
        assert p.response_gain_margin_db >= 6.0 and p.response_phase_margin_deg >= 45.0
    assert {c.rule for c in r.classical} == {"SIMC", "Ziegler–Nichols"}
    # the start is the scene's gains where they meet the margins, else those gains halved; the note says which
    kp, ki = float(r.start.kp_mrad_per_mm), float(r.start.ki_mrad_per_mm_s)
    kp0, ki0 = float(result_model_gains[0]), float(result_model_gains[1])
    if (kp, ki) == (kp0, ki0):
        assert r.start_note == f"start: the scene's gains (k_p, k_i) = ({kp:.4g}, {ki:.4g})"
    else:
        assert "miss GM ≥ 6 dB or PM ≥ 45°" in r.start_note and kp <= kp0 and ki <= ki0


def test_a_start_that_misses_the_margins_is_halved_and_said(setup):
    model, options, response = setup
    r = tuning.tune(model, options, iterations=0, response=response, start=(20.0, 5.0))
    assert r.start.kp_mrad_per_mm < 20.0 and r.start.feasible
    assert "the given gains" in r.start_note and "miss GM" in r.start_note and "halved" in r.start_note


def _control_margins(plant: SteeringPlant, kp, ki):
    """GM (dB), PM (deg) of sign(k) G C by python-control: the recirculating plant with both delays
    as 10th-order Padé approximants."""
    s = control.tf("s")
    pade = lambda t: control.tf(*control.pade(t, 10)) if t > 0 else control.tf([1], [1])  # noqa: E731
    shape = plant.gain * (1 + plant.zero * s) / ((1 + plant.lag * s) * (1 + plant.lag2 * s))
    lap = (1 + plant.loop_lag * s) ** 2
    q = plant.loop_time * lap / (lap - pade(plant.loop_delay)) if plant.recirculating else 1 / s
    G = pade(plant.delay) * (plant.feedthrough + shape * q)
    gm, pm, _, _ = control.margin(np.sign(plant.gain) * G * (kp + ki / s))
    return 20 * np.log10(gm), pm


def test_margins_match_python_control(result):
    plant = result.plant
    assert plant.recirculating
    for p in (result.start, result.tuned):
        gm, pm = _control_margins(plant, p.kp_mrad_per_mm, p.ki_mrad_per_mm_s)
        assert p.gain_margin_db == pytest.approx(gm, abs=0.05)
        assert p.phase_margin_deg == pytest.approx(pm, abs=0.1)


def test_cli_json(setup, capsys):
    assert main(["tune", "--t-end", str(T_END), "--iterations", "1", "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert {"scene", "loop", "objective", "objective_unit", "plant", "start", "tuned", "classical", "history",
            "improvement", "gm_min_db", "pm_min_deg"} <= set(r)
    assert r["scene"] == "two-roller-steered" and r["objective"] == "ise" and len(r["history"]) == 2
    assert {"kp_mrad_per_mm", "ki_mrad_per_mm_s", "objective", "gain_margin_db", "phase_margin_deg",
            "response_gain_margin_db", "feasible"} <= set(r["tuned"])


@pytest.mark.parametrize("argv", [["tune", "--objective", "max"], ["tune", "--iterations", "-1"],
                                  ["tune", "two-roller-1d"], ["tune", "--t-end", "0.2"]])
def test_cli_bad_input_exits_2(argv, capsys):
    with pytest.raises(SystemExit) if "max" in argv else _nothing():
        code = main(argv)
        assert code == 2
    assert "error" in capsys.readouterr().err


class _nothing:
    def __enter__(self):
        return self

    def __exit__(self, *a):
        return False
