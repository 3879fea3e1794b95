"""The discretisation-error estimate against runs refined 4× in every direction, the grid chosen
for an accuracy (verified by its own estimate), and the command-line options with their errors."""

import json
import math

import numpy as np
import pytest
from helpers import scene_with

import jaxbelt as jb
from jaxbelt.accuracy import (AccuracyError, at_times, choose_grid, estimate_error, one_d_counterpart, precision_scope,
                              refine, tracer_run)
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
    d = est.to_dict()
    assert set(d) >= {"longitudinal", "lateral", "dominant", "orders"} and d["orders"]["dt"] is not None


def test_estimate_2d_with_a_walking_belt():
    scene = scene_with(_walking_2d)
    est = estimate_error(scene)
    true_u, true_v = _true_error_um(scene)
    assert {d.direction for d in est.directions} == {"n_xi", "n_eta", "dt"}
    assert 1.0 <= est.longitudinal_um / true_u <= 3.0
    assert 1.0 <= est.lateral_um / true_v <= 3.0


def test_chosen_grid_meets_the_accuracy_and_is_verified(scene_1d, estimate_1d):
    target = 0.5 * estimate_1d.longitudinal_um
    c = choose_grid(scene_1d, target, allow_float32=True)
    assert c.estimate_um <= target
    assert c.factors["dt"] > 1 and c.grid.dt < scene_1d.time.dt  # the dominant direction refined
    assert c.quantities == ("longitudinal",) and c.model == "1d"
    d = c.to_dict()
    assert set(d) >= {"n_xi", "n_eta", "dt_s", "solver", "precision", "estimate_um", "cost_s"}
    # float32: its rounding measured against float64 on the chosen grid, independently here
    check = next(ch for ch in c.checks if ch.name == "float32")
    r64 = jb.simulate(jb.build_model(c.scene), **jb.RunOptions.from_scene(c.scene))[1]
    with precision_scope("float32"):
        r32 = jb.simulate(jb.build_model(c.scene), **jb.RunOptions.from_scene(c.scene))[1]
    assert r32.tracer_u.dtype == np.float32 and r64.tracer_u.dtype == np.float64
    assert check.difference_um == pytest.approx(_max_diff_um(r32, r64), rel=1e-3)
    assert 0 < check.difference_um < 0.1 * target  # rounding, not discretisation
    # float32 is taken only where it is faster and its rounding fits; the choice says which
    assert check.used == (c.precision == "float32")
    extra = check.difference_um if check.used else 0.0
    assert c.estimate_um == pytest.approx(c.estimate.longitudinal_um + extra)
    with pytest.raises(ValueError, match="precision"):
        precision_scope("float16")
    # the reuse solver: exact with the shift transport, taken where it is also faster
    reuse = next(ch for ch in c.checks if ch.name == "reuse")
    assert reuse.difference_um is not None and reuse.difference_um < 1e-6
    assert reuse.used == (c.solver == "direct/reuse") == (c.scene.solver.linear_solver == "reuse")
    # an answer made of batched runs keeps the scene's solver, and says why
    b = choose_grid(scene_1d, target, allow_reuse=False)
    assert "reuse" not in {ch.name for ch in b.checks} and b.scene.solver == scene_1d.solver
    assert "batches" in b.automatic[0]


def test_unreachable_accuracy_names_the_best_reachable(scene_1d):
    with pytest.raises(AccuracyError, match="predicts .* µm at best"):
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
    assert "at best" in capsys.readouterr().err


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


def _symmetric_2d(d):
    d.update(model={"kind": "2d"}, mesh={"n_eta": 3, "roller_elements": [6, 6], "free_elements": [8, 8]},
             time={"dt_s": 0.005, "t_end_s": 0.05})


def test_one_d_counterpart_only_without_lateral_physics():
    s2 = scene_with(_symmetric_2d)
    s1, why = one_d_counterpart(s2)
    assert s1.kind == "1d" and s1.mesh.n_eta == 1 and "symmetry" in why
    assert s1.rollers == s2.rollers and s1.time == s2.time and s1.belt == s2.belt
    tilted = scene_with(lambda d: (_symmetric_2d(d), d["roller"][1].update(rotation_mrad=[0.0, 0.3, 0.0])))
    assert one_d_counterpart(tilted)[0] is None and "tilted" in one_d_counterpart(tilted)[1]
    walking = scene_with(lambda d: (_symmetric_2d(d), d.update(solver={"lateral_transport": True})))
    assert "lateral transport" in one_d_counterpart(walking)[1]
    assert one_d_counterpart(scene_with(_short_1d))[0] is None


def _max_diff_um(a, b):
    return 1e6 * float(np.max(np.abs(np.asarray(a.tracer_u, np.float64) - np.asarray(b.tracer_u, np.float64))))


def test_symmetric_2d_scene_runs_its_1d_counterpart_with_the_model_difference_measured():
    s2 = scene_with(_symmetric_2d)
    c = choose_grid(s2, 1e3, allow_1d=True)  # loose: the 1D grid is the scene's own
    assert c.model == "1d" and c.scene.kind == "1d"
    check = next(ch for ch in c.checks if ch.name == "1d")
    assert check.used and check.run_s < check.reference_run_s
    # the model difference, measured independently on the 2D scene's grid
    runs = [jb.simulate(jb.build_model(s), **jb.RunOptions.from_scene(s))[1] for s in (s2, one_d_counterpart(s2)[0])]
    assert check.difference_um == pytest.approx(_max_diff_um(*runs), rel=1e-9)
    assert c.estimate_um == pytest.approx(c.estimate.longitudinal_um + check.difference_um) and c.estimate_um <= 1e3
    assert any(a.startswith("model 1d") for a in c.automatic)


def test_a_choice_over_its_budget_is_refused_before_it_runs(scene_1d):
    """The grid that would meet the accuracy is priced before it runs (its cost multiple times
    the runs its verification needs) and refused, with that price, when it exceeds the budget."""
    import time

    t0 = time.perf_counter()
    with pytest.raises(AccuracyError, match=r"would take about .* s to run and verify.*over the budget of 0.01 s"):
        choose_grid(scene_1d, 150.0, max_cost_s=0.01)
    est = estimate_error(scene_1d)
    assert time.perf_counter() - t0 < 10 * (1 + est.cost_runs) * est.run_s + 30  # no candidate grid was run


def test_the_start_up_swing_is_named_where_it_sets_the_accuracy():
    """From rest, the idle roller's start-up swing dominates the error of a short 1D run, and the
    coarse grids' runs agree on damping it away: refining makes the estimate larger, and a refusal
    (here by the budget) says why and what to do (docs/speed.md); a running start meets the
    same accuracy on the scene's own grid."""
    scene = scene_with(lambda d: d.update(time={"dt_s": 0.005, "t_end_s": 0.3}))
    with pytest.raises(AccuracyError, match="grew on refinement.*start-up swing"):
        choose_grid(scene, 100.0, max_cost_s=8.0)
    running = scene_with(lambda d: d.update(time={"dt_s": 0.005, "t_end_s": 0.3, "start": "running"}))
    assert running.time.start == "running"
    assert choose_grid(running, 100.0, max_cost_s=120.0).estimate_um <= 100.0
    with pytest.raises(jb.SceneError, match="time.start"):
        scene_with(lambda d: d.update(time={"dt_s": 0.005, "t_end_s": 0.3, "start": "moving"}))
