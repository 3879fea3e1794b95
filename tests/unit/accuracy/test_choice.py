"""The choice of the cheapest run that meets an accuracy (:mod:`jaxbelt.accuracy.choice`), with the
error estimate and the tracer runs replaced by hand-made ones on the two-roller machine (220
elements, Δt = 5 ms, CFL number 0.64, so a finer mesh needs a finer step): the refinement picked
against a hand search of the error model ``F_s Σ_d e_d f_d^(−p_d)``, a second round where the
first prediction misses, the refusals (no grid reaches it, over the budget, the estimate grew) with
their figures; the reuse solver, float32 and the 1D counterpart taken or not by the measured
difference and speed; and the small pieces: the precision scope, the asked value, the window
difference, the 1D counterpart's conditions, the predicted cost and the JSON form."""

import math

import jax.numpy as jnp
import numpy as np
import pytest

from helpers import scene_with
from jaxbelt.accuracy import (AccuracyError, DirectionError, DiscretisationError, Grid, GridChoice, ModelCheck,
                              TracerRun, asked_value, choose_grid, one_d_counterpart, precision_scope, scene_grid,
                              window_difference_um)
from jaxbelt.accuracy import choice
from jaxbelt.accuracy.choice import verification_cost_s

BASE = Grid(220, 1, 0.005)  # the two-roller machine's own grid


def _short(d):
    d["time"].update(t_end_s=0.05)  # 10 steps: light hand-made histories


def _scene(mutate=None):
    return scene_with(lambda d: (_short(d), mutate and mutate(d)))


def _estimate(e_xi, e_dt, p_xi=1.0, p_dt=1.0, grid=BASE, lateral=None, run_s=0.01, cost_runs=3.0):
    dirs = (DirectionError("n_xi", (0.5, 1.0, 2.0), grid.dt, p_xi, False, e_xi, lateral),
            DirectionError("dt", (0.5, 1.0, 2.0), grid.dt, p_dt, False, e_dt, lateral))
    return DiscretisationError(longitudinal_um=1.25 * (e_xi + e_dt), lateral_um=lateral, dominant="n_xi",
                               directions=dirs, grid=grid, safety_factor=1.25, run_s=run_s, estimate_s=1.0,
                               runs_s=run_s * cost_runs, cost_runs=cost_runs, run_bytes=1e3)


class FakeEstimate:
    """An error estimate whose truth is ``A / f_ξ^q + B / f_Δt`` µm (before the safety factor) on a
    grid refined by ``(f_ξ, f_Δt)`` from the two-roller machine's, reporting the order ``p_xi``
    along the belt (the true one, ``q``, unless told otherwise)."""

    def __init__(self, A=4.0, B=1.0, q=1.0, p_xi=None, grows=False, run_s=0.01):
        self.A, self.B, self.q, self.p_xi, self.grows, self.run_s = A, B, q, q if p_xi is None else p_xi, grows, run_s
        self.grids = []

    def __call__(self, scene, solver=None, *, t_from=0.0, progress=None, runs=None):
        g = scene_grid(scene)
        self.grids.append(g)
        fx, ft = g.n_xi / BASE.n_xi, BASE.dt / g.dt
        e_xi, e_dt = self.A / fx**self.q, self.B / ft
        if self.grows and (fx, ft) != (1.0, 1.0):
            e_xi *= 10.0
        return _estimate(e_xi, e_dt, p_xi=self.p_xi, grid=g, run_s=self.run_s)


class FakeRuns:
    """Tracer runs: zero histories offset by ``offset_um`` for the reuse solver, the 1D model and
    float32 (added up), timed at ``seconds`` (the scene's solver and model in float64: 1 s) times
    each substitution's factor."""

    def __init__(self, offset_um=None, speed=None):
        self.offset_um = {"reuse": 0.1, "float32": 0.2, "one_d": 0.3, **(offset_um or {})}
        self.speed = {"reuse": 0.5, "float32": 0.5, "one_d": 0.2, **(speed or {})}
        self.calls = []

    def __call__(self, scene, solver=None):
        parts = [k for k, on in (("reuse", scene.solver.linear_solver == "reuse"),
                                 ("float32", jnp.zeros(()).dtype == jnp.float32),
                                 ("one_d", scene.name.endswith("(1D counterpart)"))) if on]
        self.calls.append(tuple(parts))
        k = scene.time.n_steps
        u = np.full((k, 3), 1e-6 * sum(self.offset_um[p] for p in parts))
        return TracerRun(np.arange(1, k + 1) * scene.time.dt, u, None, math.prod(self.speed[p] for p in parts), 1e3)


@pytest.fixture
def fakes(monkeypatch):
    def install(estimate=None, runs=None):
        estimate, runs = estimate or FakeEstimate(), runs or FakeRuns()
        monkeypatch.setattr(choice, "estimate_error", estimate)
        monkeypatch.setattr(choice, "tracer_run", runs)
        return estimate, runs
    return install


def test_the_cheapest_admissible_refinement_predicted_to_meet_the_accuracy(fakes):
    """Base estimate 1.25 (4 + 1) = 6.25 µm; 2.6 µm asked: ``4/f_ξ + 1/f_Δt ≤ 2.08``. Cheaper grids
    that meet it ((4, 1), (4, 2), (8, 1)) break the CFL limit (0.64 f_ξ / f_Δt < 1); of the cost-16
    ones, (2, 8) misses (2.125) and (4, 4) is the first that meets it."""
    estimate, runs = fakes()
    got = choose_grid(_scene(), 2.6, allow_reuse=False)
    assert got.factors == {"n_xi": 4.0, "n_eta": 1.0, "dt": 4.0}
    assert got.grid == Grid(880, 1, 0.00125) and scene_grid(got.scene) == got.grid
    assert got.predicted_um == pytest.approx(1.25 * (1.0 + 0.25))
    assert got.estimate_um == pytest.approx(1.5625) and got.rounds == 1
    assert estimate.grids == [BASE, Grid(880, 1, 0.00125)]  # the base estimate and the verification
    assert runs.calls == []  # no substitution tried
    assert (got.model, got.precision, got.solver, got.quantities) == ("1d", "float64", "direct/kept-interior",
                                                                      ("longitudinal",))
    assert got.automatic == ("solver direct/kept-interior (the scene's): the answer runs in batches, which share the "
                             "exact solver's kept factors", "precision float64 (float32 is not considered for this "
                             "answer)")
    assert got.cost_s == 0.01 and got.checks == ()


def test_a_missed_prediction_is_chosen_again_from_the_verified_grid(fakes):
    """The estimate reports order 2 along the belt where the truth is order 1: the first pick
    (2, 2), predicted 1.25 (1 + 0.5) = 1.875 µm, reads 1.25 (2 + 0.5) = 3.125; refitted there
    (e_ξ = 2, e_Δt = 0.5), (2, 2) again is predicted 0.9375 and reads 1.5625 µm."""
    estimate, _ = fakes(FakeEstimate(q=1.0, p_xi=2.0))
    progress = []
    got = choose_grid(_scene(), 2.6, allow_reuse=False, progress=progress.append)
    assert got.rounds == 2 and got.factors == {"n_xi": 4.0, "n_eta": 1.0, "dt": 4.0}
    assert got.predicted_um == pytest.approx(0.9375) and got.estimate_um == pytest.approx(1.5625)
    assert estimate.grids == [BASE, Grid(440, 1, 0.0025), Grid(880, 1, 0.00125)]
    assert progress == ["the grid predicted at 1.88 µm reads 3.12 µm: the error model is fitted again on it"]


def test_no_grid_reaches_an_estimate_that_does_not_converge(fakes):
    fakes(FakeEstimate(p_xi=0.0))  # no order along the belt: its 4 µm stay whatever the mesh
    with pytest.raises(AccuracyError) as e:
        choose_grid(_scene(), 2.0, allow_reuse=False)
    # the best reachable: 1.25 (4 + 1/256) at the finest step, on the coarsest mesh the ladder saw
    assert str(e.value) == ("accuracy_um = 2: no grid within half the machine's memory reaches it: the error model of "
                            "the last grid estimated (its own 6.25 µm) predicts 5 µm at best (refined n_xi ×0.5, "
                            "dt /256)")


def test_a_grid_over_the_budget_is_refused_before_it_runs(fakes):
    estimate, _ = fakes(FakeEstimate(run_s=0.5))
    with pytest.raises(AccuracyError) as e:
        choose_grid(_scene(), 2.6, allow_reuse=False, max_cost_s=20.0)
    # its run and its ladder's three: 16 × 0.5 s × (1 + 3) = 32 s
    assert str(e.value).startswith("accuracy_um = 2.6: the cheapest grid predicted to reach 1.56 µm (refined "
                                   "n_xi ×4, dt /4 against the grid estimated last) would take about 32 s to run "
                                   "and verify, ")
    assert str(e.value).endswith("s spent already, over the budget of 20 s (max_cost_s)")
    assert estimate.grids == [BASE]  # refused before the grid ran


def test_an_estimate_that_grows_on_refinement_is_named_in_the_refusal(fakes):
    fakes(FakeEstimate(grows=True))
    with pytest.raises(AccuracyError) as e:
        choose_grid(_scene(), 2.6, allow_reuse=False, rounds=1)
    # the picked (4, 4) reads 1.25 (10 + 0.25) = 12.8 µm, more than the coarser 6.25
    assert str(e.value).startswith("accuracy_um = 2.6: the chosen grid's estimate is still 12.8 µm after 1 rounds "
                                   "(each fitting the error model again on the grid before) (the estimate grew on "
                                   "refinement, 6.25 → 12.8 µm:")


def test_the_reuse_solver_and_float32_are_taken_where_they_fit_and_are_faster(fakes):
    _, runs = fakes()
    got = choose_grid(_scene(), 2.6, allow_float32=True)
    assert got.solver == "direct/reuse" and got.scene.solver.linear_solver == "reuse" and got.precision == "float32"
    assert got.estimate_um == pytest.approx(1.5625 + 0.1 + 0.2)  # the estimate plus both measured differences
    reuse, f32 = got.checks
    assert (reuse.name, reuse.used, reuse.run_s, reuse.reference_run_s) == ("reuse", True, 0.5, 1.0)
    assert (f32.name, f32.used, f32.run_s, f32.reference_run_s) == ("float32", True, 0.25, 0.5)
    assert reuse.difference_um == pytest.approx(0.1) and f32.difference_um == pytest.approx(0.2)
    assert got.cost_s == 0.25
    assert runs.calls == [(), ("reuse",), ("reuse", "float32")]  # float32 measured against the reuse run
    assert got.automatic[0] == "solver direct/reuse: it reproduces the kept-interior solver to 0.1 µm and is faster"
    assert got.automatic[1] == ("precision float32: its rounding (0.2 µm, measured) leaves the answer within the "
                                "accuracy")


def test_substitutions_beyond_the_accuracy_or_not_faster_are_declined(fakes):
    fakes(runs=FakeRuns(offset_um=dict(reuse=1.5, float32=0.2), speed=dict(float32=1.2)))
    got = choose_grid(_scene(), 2.6, allow_float32=True)
    reuse, f32 = got.checks
    assert not reuse.used and reuse.why == "it differs by 1.5 µm, beyond the accuracy"  # 1.5625 + 1.5 > 2.6
    assert not f32.used and f32.why == "not faster here (1.2 s against 1 s)"
    assert (got.solver, got.precision, got.estimate_um) == ("direct/kept-interior", "float64", pytest.approx(1.5625))
    fakes(runs=FakeRuns(offset_um=dict(float32=1.1)))
    f32 = choose_grid(_scene(), 2.6, allow_float32=True).checks[1]
    assert not f32.used and f32.why == "its rounding (1.1 µm) on top of the estimate exceeds the accuracy"


def test_the_1d_counterpart_is_taken_with_the_model_difference_added(fakes):
    """2.6 µm asked, the models 0.3 µm apart: the 1D grid is chosen for 2.3 µm (``4/f_ξ + 1/f_Δt ≤
    1.84``: (4, 4) again) and its answer carries the difference."""
    estimate, runs = fakes()
    scene = _scene(lambda d: d.update(model={"kind": "2d"}, mesh=dict(d["mesh"], n_eta=3)))
    got = choose_grid(scene, 2.6, allow_1d=True, allow_reuse=False)
    assert got.model == "1d" and got.scene.kind == "1d" and got.scene.name.endswith("(1D counterpart)")
    assert got.factors == {"n_xi": 4.0, "n_eta": 1.0, "dt": 4.0}
    assert got.estimate_um == pytest.approx(1.5625 + 0.3) and got.predicted_um == pytest.approx(1.5625 + 0.3)
    (check,) = got.checks
    assert (check.name, check.used, check.run_s, check.reference_run_s) == ("1d", True, 0.2, 1.0)
    assert runs.calls == [(), ("one_d",)]
    assert got.automatic[1].startswith("model 1d: nothing pushes the belt sideways") and "0.3 µm (measured)" in \
        got.automatic[1]
    assert got.quantities == ("longitudinal", "lateral")


def test_a_1d_counterpart_beyond_the_accuracy_leaves_the_2d_model(fakes):
    fakes(runs=FakeRuns(offset_um=dict(one_d=3.0)))
    scene = _scene(lambda d: d.update(model={"kind": "2d"}, mesh=dict(d["mesh"], n_eta=3)))
    got = choose_grid(scene, 2.6, allow_1d=True, allow_reuse=False)
    assert got.model == "2d" and got.scene.mesh.n_eta == 3
    assert got.automatic[1] == "model 2d: the 1D and 2D models differ by 3 µm, not within the accuracy"


@pytest.mark.parametrize("accuracy", [0, -1.0, float("nan"), float("inf"), "2"])
def test_an_accuracy_that_is_not_a_positive_number_is_refused(accuracy):
    with pytest.raises(ValueError, match=rf"^accuracy_um = {accuracy}: must be a positive number of µm$"):
        choose_grid(_scene(), accuracy)


def test_unknown_quantities_are_refused():
    with pytest.raises(ValueError, match=r"^quantities \['vertical'\]: unknown \(one of longitudinal, lateral\)$"):
        choose_grid(_scene(), 1.0, quantities=("longitudinal", "vertical"))


def test_precision_scope_sets_the_default_precision_within_it():
    with precision_scope("float32"):
        assert jnp.zeros(1).dtype == jnp.float32
    assert jnp.zeros(1).dtype == jnp.float64
    with precision_scope("float64"):
        assert jnp.zeros(1).dtype == jnp.float64
    with pytest.raises(ValueError, match=r"^precision = 'bfloat16': one of float64, float32$"):
        precision_scope("bfloat16")


def test_asked_value_is_the_largest_of_the_quantities_asked():
    est = DiscretisationError(3.75, 5.0, "n_xi", (), BASE, 1.25, 1.0, 1.0, 1.0, 1.0, 1.0)
    assert asked_value(est, ("longitudinal",)) == 3.75
    assert asked_value(est, ("longitudinal", "lateral")) == 5.0
    assert asked_value(est, ("lateral",)) == 5.0
    one_d = DiscretisationError(3.75, None, "n_xi", (), BASE, 1.25, 1.0, 1.0, 1.0, 1.0, 1.0)
    assert asked_value(one_d, ("lateral",)) == 0.0  # nothing lateral in 1D
    assert asked_value(one_d, ("longitudinal", "lateral")) == 3.75


def test_window_difference_over_the_times_from_t_from():
    scene = _scene(lambda d: d["time"].update(dt_s=0.01))  # 5 output times, 0.01 … 0.05 s
    t = np.arange(1, 6) * 0.01
    ua = np.zeros((5, 2))
    ub = np.array([[9.0, 0], [0, 0], [0, -2.0], [0, 0], [1.0, 0]]) * 1e-6
    vb = np.array([[0, 0], [0, 7.0], [0, 0], [3.0, 0], [0, 0]]) * 1e-6
    a, b = TracerRun(t, ua, None, 1.0, 0.0), TracerRun(t, ub, vb, 1.0, 0.0)
    assert window_difference_um(a, b, scene, ("longitudinal",), 0.0) == pytest.approx(9.0)
    assert window_difference_um(a, b, scene, ("longitudinal",), 0.025) == pytest.approx(2.0)  # from 0.03 s on
    assert window_difference_um(a, b, scene, ("longitudinal",), 0.04) == pytest.approx(1.0)
    assert window_difference_um(a, b, scene, ("longitudinal", "lateral"), 0.025) == pytest.approx(3.0)  # v_a = 0
    assert window_difference_um(a, b, scene, ("lateral",), 0.0) == pytest.approx(7.0)
    assert window_difference_um(a, a, scene, ("lateral",), 0.0) == 0.0  # neither run has v


def _two_d(mutate=None):
    def go(d):
        d.update(model={"kind": "2d"})
        if mutate:
            mutate(d)
    return scene_with(go)


def test_the_1d_counterpart_of_a_symmetric_2d_scene():
    scene = _two_d(lambda d: (d["roller"][0].update(translation_mm=[0.5, 0.0, 0.0]),
                              d["roller"][1].update(role="tension", force_n=[3.0, 0.0, 0.0]),
                              d["mesh"].update(n_eta=5)))
    s1, why = one_d_counterpart(scene)
    assert why == "nothing pushes the belt sideways: no lateral displacement by symmetry"
    assert (s1.kind, s1.mesh.n_eta, s1.name) == ("1d", 1, f"{scene.name} (1D counterpart)")
    assert s1.rollers == scene.rollers and s1.mesh.roller_elements == scene.mesh.roller_elements
    assert s1.belt == scene.belt and s1.time == scene.time
    assert one_d_counterpart(scene_with(lambda d: None)) == (None, "the scene is 1D")


@pytest.mark.parametrize("mutate,why", [
    (lambda d: d["roller"][1].update(translation_mm=[0.0, 0.2, 0.0]), "roller 'idle' translated off x"),
    (lambda d: d["roller"][0].update(translation_mm=[0.0, 0.0, -0.1]), "roller 'drive' translated off x"),
    (lambda d: d["roller"][1].update(rotation_mrad=[0.0, 0.5, 0.0]), "roller 'idle' tilted"),
    (lambda d: d["roller"][1].update(role="tension", force_n=[2.0, 1.0, 0.0]), "roller 'idle' loaded off x"),
    (lambda d: d["roller"][1].update(role="tension", torque_nm=[0.1, 0.0, 0.0]), "roller 'idle' loaded off x"),
    (lambda d: d.update(solver={"lateral_transport": True}), "lateral transport is on"),
    (lambda d: (d["roller"][0].update(rotation_mrad=[1.0, 0.0, 0.0]), d["roller"][1].update(translation_mm=[0, 1, 0])),
     "roller 'drive' tilted; roller 'idle' translated off x"),
])
def test_lateral_physics_keeps_the_2d_model(mutate, why):
    assert one_d_counterpart(_two_d(mutate)) == (None, "lateral physics: " + why)


def test_a_steering_loop_keeps_the_2d_model():
    assert one_d_counterpart(scene_with(lambda d: None, "three-roller-steered")) == (
        None, "lateral physics: a steering loop tilts a roller; lateral transport is on")


def test_verification_cost_is_the_run_and_its_ladder_scaled():
    est = _estimate(1.0, 1.0, run_s=0.25, cost_runs=5.0)
    assert verification_cost_s(est, 8.0) == pytest.approx(8.0 * 0.25 * 6.0)
    assert verification_cost_s(est, 0.25) == pytest.approx(0.25 * 0.25 * 6.0)


def test_json_form_of_a_choice():
    est = _estimate(2.0, 1.0, grid=Grid(440, 1, 0.0025))
    check = ModelCheck("float32", 0.2, 0.5, 1.0, True, "fits")
    gc = GridChoice(scene=None, grid=est.grid, factors={"n_xi": 2.0, "n_eta": 1.0, "dt": 2.0}, solver="direct/reuse",
                    precision="float32", estimate=est, estimate_um=3.95, predicted_um=float("inf"), cost_s=0.5,
                    accuracy_um=4.0, quantities=("longitudinal",), rounds=2, automatic=("a", "b"), model="1d",
                    checks=(check,))
    d = gc.to_dict()
    assert {k: d[k] for k in ("n_xi", "n_eta", "dt_s", "solver", "model", "precision", "rounds")} == dict(
        n_xi=440, n_eta=1, dt_s=0.0025, solver="direct/reuse", model="1d", precision="float32", rounds=2)
    assert d["predicted_um"] is None  # not finite: null in JSON
    assert d["quantities"] == ["longitudinal"] and d["automatic"] == ["a", "b"]
    assert d["checks"] == [dict(name="float32", difference_um=0.2, run_s=0.5, reference_run_s=1.0, used=True,
                                why="fits")]
    assert d["discretisation_error_um"] == est.to_dict()
    assert d["discretisation_error_um"]["longitudinal"] == pytest.approx(3.75)
