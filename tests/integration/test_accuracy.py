"""The discretisation-error estimate against runs refined 4× in every direction, the grid chosen
for an accuracy (verified by its own estimate), and the command-line options with their errors."""

import json
import math

import numpy as np
import pytest
from helpers import scene_with

import jaxbelt as jb
from jaxbelt.accuracy import AccuracyError, at_times, tracer_run, choose_grid, estimate_error, refine
from jaxbelt.cli import main


def _short_1d(d):
    d["time"] = {"dt_s": 0.005, "t_end_s": 0.05}


def _walking_2d(d):
    d.update(model={"kind": "2d"}, mesh={"n_eta": 3, "roller_elements": [6, 6], "free_elements": [8, 8]},
             time={"dt_s": 0.02, "t_end_s": 0.4}, solver={"lateral_transport": True})
    d["belt"]["length_mm"] = 863.0
    d["roller"][1]["rotation_mrad"] = [0.0, 0.3, 0.0]  # the idle roller skewed: the belt walks


@pytest.fixture(scope="module")
def scene_1d():
    return scene_with(_short_1d)


@pytest.fixture(scope="module")
def estimate_1d(scene_1d):
    return estimate_error(scene_1d)


def _true_error_um(scene):
    """Largest |u − u_truth|, |v − v_truth| (µm) against the run refined 4× in every direction."""
    own, fine_scene = tracer_run(scene), refine(scene, n_xi=4.0, n_eta=4.0, dt=4.0)
    fine = tracer_run(fine_scene)
    k = len(own.t)
    fu, fv = at_times(fine, fine_scene.time.dt, scene.time.dt, k)
    tv = None if fv is None else float(np.max(np.abs(own.v - fv)) * 1e6)
    return float(np.max(np.abs(own.u - fu)) * 1e6), tv


def test_estimate_1d_bounds_the_error_within_a_factor_of_three(scene_1d, estimate_1d):
    est = estimate_1d
    assert est.lateral_um is None and {d.direction for d in est.directions} == {"n_xi", "dt"}
    true_u, true_v = _true_error_um(scene_1d)
    assert true_v is None
    assert 1.0 <= est.longitudinal_um / true_u <= 3.0
    # the impulsive start of the drive dominates: the time step is the direction to refine
    assert est.dominant == "dt" and est.direction("dt").longitudinal_um > 10 * est.direction("n_xi").longitudinal_um
    assert est.cost_runs > 1 and est.run_s > 0 and est.estimate_s > est.run_s
    d = est.as_dict()
    assert set(d) >= {"longitudinal", "lateral", "dominant", "orders"} and d["orders"]["dt"] is not None


@pytest.mark.slow  # ~25 s: seven 2D grids and the 4× refined one (benchmarks/error_estimate.py runs eleven such cases)
def test_estimate_2d_with_a_walking_belt():
    scene = scene_with(_walking_2d)
    est = estimate_error(scene)
    true_u, true_v = _true_error_um(scene)
    assert {d.direction for d in est.directions} == {"n_xi", "n_eta", "dt"}
    assert 1.0 <= est.longitudinal_um / true_u <= 3.0
    assert 1.0 <= est.lateral_um / true_v <= 3.0


def test_chosen_grid_meets_the_accuracy_and_is_verified(scene_1d, estimate_1d):
    target = 0.5 * estimate_1d.longitudinal_um
    c = choose_grid(scene_1d, target)
    assert c.estimate_um <= target and c.estimate.longitudinal_um == c.estimate_um
    assert c.factors["dt"] > 1 and c.grid.dt < scene_1d.time.dt  # the dominant direction refined
    assert c.quantities == ("longitudinal",) and c.precision == "float64"
    d = c.as_dict()
    assert set(d) >= {"n_xi", "n_eta", "dt_s", "solver", "precision", "estimate_um", "cost_s"}


def test_unreachable_accuracy_names_the_best_reachable(scene_1d):
    with pytest.raises(AccuracyError, match="best reachable is about"):
        choose_grid(scene_1d, 1e-9)
    for bad in (0.0, -1.0, math.nan):
        with pytest.raises(ValueError, match="positive"):
            choose_grid(scene_1d, bad)


def test_cli_error_estimate_and_accuracy(tmp_path, capsys):
    path = tmp_path / "short.toml"
    path.write_text('extends = "two-roller-1d"\n[time]\ndt_s = 0.005\nt_end_s = 0.05\n')
    assert main(["simulate", str(path), "--error-estimate", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)["discretisation_error_um"]
    assert d["dominant"] == "dt" and d["lateral"] is None and d["longitudinal"] > 0
    for bad in ("0", "-3", "nan"):
        assert main(["simulate", str(path), "--accuracy-um", bad]) == 2
        err = capsys.readouterr().err
        assert "--accuracy-um" in err and len(err.strip().splitlines()) == 1
    assert main(["simulate", str(path), "--accuracy-um", "1e-9"]) == 2
    assert "best reachable" in capsys.readouterr().err


def test_scene_accuracy_key():
    scene = scene_with(lambda d: d.setdefault("solver", {}).update(accuracy_um=5.0))
    assert scene.solver.accuracy_um == 5.0
    for bad in (0.0, -2.0, "x"):
        with pytest.raises(jb.SceneError, match="solver.accuracy_um"):
            scene_with(lambda d, b=bad: d.setdefault("solver", {}).update(accuracy_um=b))


def test_info_says_what_the_program_decides(tmp_path, capsys):
    path = tmp_path / "acc.toml"
    path.write_text('extends = "two-roller-1d"\n[solver]\naccuracy_um = 50.0\nlinear_solver = "reuse"\n')
    assert main(["info", str(path), "--json"]) == 0
    auto = json.loads(capsys.readouterr().out)["automatic"]
    assert any(a.startswith("grid: chosen for 50 µm") for a in auto)
    assert any(a.startswith("reuse solver: no refinement") for a in auto)
    assert any(a.startswith("precision: float64") for a in auto)
