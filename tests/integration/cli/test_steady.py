"""The design commands on a steered machine judge steady operation by default: the tolerance box
verified by steady solves, the steering roller's own tilt limited by the actuator range only, and
the options that ask the transient question or do not apply refused before anything runs."""

import json

import pytest

from jaxbelt.cli import main

SCENE = "two-roller-steered"  # N = 180, PI loop on the idle roller about y


def _json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_tolerance_in_steady_operation(capsys):
    # the scene's drive is skewed 0.15 mrad: 35 µm of steady deviation before any tolerance
    r = _json(capsys, ["tolerance", SCENE, "--limit-um", "60", "--components", "idle:rotation,drive:dx",
                       "--no-error-bars", "--json"])
    assert r["operation"] == "steady" and r["window_s"] is None and r["t_eval_s"] is None
    assert r["verified"]
    widths = {row["component"]: row["half_width"] for row in r["half_widths"]}
    # the loop absorbs its own roller's tilt about the actuated axis: it costs actuator range only,
    # so its half-width is most of the ±2 mrad range (less the hold angle of the skew and the jitter)
    steer = next(x for x in r["limits"] if x["metric"] == "steering_max")
    assert steer["limit"] == 2.0 and 0 < max(r["actuator_jitter_mrad"]) < 0.2
    assert 1.5 < widths["idle:ay"] < 2.0
    assert widths["drive:dx"] < 0.1  # a translation the deviation limits: tens of µm


@pytest.mark.parametrize("argv, message", [
    (["tolerance", "three-roller-tolerance", "--window", "1"], "no steering loop"),
    (["tolerance", SCENE, "--window", "0"], "--window"),
    (["tolerance", SCENE, "--window", "100"], "longer than the run"),
    (["sweep", SCENE, "--dist", "{dist}", "--rom", "pod"], "--rom"),
])
def test_transient_options_refused_before_any_run(argv, message, tmp_path, capsys):
    dist = tmp_path / "d.toml"
    dist.write_text('[roller."idle"]\nrotation_mrad = {dist = "normal", sigma = [0.05, 0.05, 0.0]}\n')
    assert main([a.replace("{dist}", str(dist)) for a in argv]) == 2
    assert message in capsys.readouterr().err


def test_a_barely_felt_component_is_left_at_the_cap_where_it_counts_as_unconstrained():
    """A component the metric barely feels (an axial roller offset of the steered machine in steady
    operation) ends at the cap, within the fraction above which ``tolerance_box`` lists it as
    unconstrained rather than as a tolerance; a felt one ends below it."""
    import numpy as np

    from jaxbelt.design.linear_box import H_MAX, LinearResponse, optimise_box
    from jaxbelt.design.tolerance import CAP_FRACTION

    J = np.array([[100.0, 1e-9], [50.0, -1e-9]])  # the second component: felt at 1e-9 µm/mm only
    h = optimise_box(LinearResponse(np.zeros(2), J, "max"), 20.0, None, H_MAX)
    assert h[1] >= CAP_FRACTION * H_MAX and h[0] < CAP_FRACTION * H_MAX


def test_a_steering_limit_on_a_machine_without_a_loop_is_refused_before_any_computation(monkeypatch, capsys):
    import jaxbelt.cli.tolerance as tolerance

    def no_study(*a, **k):
        raise AssertionError("the study was computed before the options were checked")

    monkeypatch.setattr(tolerance, "make_design_study", no_study)
    assert main(["tolerance", "three-roller-tolerance", "--steering-limit-mrad", "1"]) == 2
    assert "--steering-limit-mrad = 1.0: the scene has no steering loop" in capsys.readouterr().err
