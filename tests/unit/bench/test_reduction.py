"""What ``jaxbelt reduce`` reports a reduced model costs (:mod:`jaxbelt.bench.reduction`), with the
full runs and the comparison replaced by hand-made ones and a scripted clock: the reuse mode is
taken for the training runs only where it is faster and reproduces the given solver's tracers to
1e-3 µm (both tracer fields), a reuse solver is timed once, a diverged full run is refused; the
speedups against hand arithmetic (online, total, per step, the source's step-count formula eq. 7.5);
the JSON form; the programs compiled ahead for the timed runs."""

from types import SimpleNamespace

import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.bench import reduction
from jaxbelt.bench.reduction import FullModeTime, ReductionTimings, TimedReduction, full_runs, reduce_and_time
from jaxbelt.integrators import solver_name
from jaxbelt.rom import DMD, ReduceConfig
from jaxbelt.rom.comparison import FullRunDivergedError, ReductionCost

EXACT = jb.DirectBackwardEuler(jb.KeptInterior())
REUSE = jb.DirectBackwardEuler(jb.Reuse())


def _config(solver, n_steps=100, every=2):
    return ReduceConfig(DMD(), jb.RunOptions(solver, n_steps, 0.01, jb.SaveAt(every=every)))


class FakeRuns:
    """Full runs by solver name: their tracers offset by ``offset_um[name]`` (``u``) and
    ``solved_um[name]`` (the pre-transport ``u``), timed at ``seconds[name]`` by the clock."""

    def __init__(self, seconds, offset_um=None, solved_um=None, nan=False):
        self.seconds, self.offset_um, self.solved_um, self.nan = seconds, offset_um or {}, solved_um or {}, nan
        self.runs = []

    def full_run(self, model, solver, config):
        name = solver_name(solver)
        self.runs.append((name, solver.transport, config))
        base = np.linspace(0.0, 1e-4, 12).reshape(4, 3)
        u = base + 1e-6 * self.offset_um.get(name, 0.0)
        if self.nan:
            u[2, 1] = np.nan
        return SimpleNamespace(tracer_u=u, tracer_u_solved=base + 1e-6 * self.solved_um.get(name, 0.0), name=name)

    def warm_best(self, f, repeat=5, budget_s=0.5):
        traj = f()
        return traj, self.seconds[traj.name], 10 * self.seconds[traj.name]


@pytest.fixture
def fake(monkeypatch):
    def install(**kw):
        runs = FakeRuns(**kw)
        monkeypatch.setattr(reduction, "full_run", runs.full_run)
        monkeypatch.setattr(reduction, "warm_best", runs.warm_best)
        return runs
    return install


def test_the_reuse_mode_is_taken_where_it_is_faster_and_reproduces_the_tracers(fake):
    runs = fake(seconds={"direct/kept-interior": 2.0, "direct/reuse": 1.5}, offset_um={"direct/reuse": 0.9e-3})
    config = _config(EXACT)
    traj, times, reuse = full_runs("model", EXACT, config)
    assert traj.name == "direct/kept-interior" and reuse is True
    assert times == (FullModeTime("direct/kept-interior", 2.0), FullModeTime("direct/reuse", 1.5))
    assert [(name, transport) for name, transport, _ in runs.runs] == [("direct/kept-interior", "shift"),
                                                                       ("direct/reuse", "shift")]
    assert all(c is config for *_, c in runs.runs)


@pytest.mark.parametrize("seconds,offset_um,solved_um", [
    ({"direct/kept-interior": 2.0, "direct/reuse": 1.5}, {"direct/reuse": 2e-3}, {}),  # off by 2e-3 µm
    ({"direct/kept-interior": 2.0, "direct/reuse": 1.5}, {}, {"direct/reuse": -2e-3}),  # off before transport
    ({"direct/kept-interior": 2.0, "direct/reuse": 2.0}, {}, {}),  # exact but not faster
])
def test_the_reuse_mode_is_not_taken_where_it_differs_or_is_not_faster(fake, seconds, offset_um, solved_um):
    fake(seconds=seconds, offset_um=offset_um, solved_um=solved_um)
    _, times, reuse = full_runs("model", EXACT, _config(EXACT))
    assert reuse is False and len(times) == 2


def test_the_reuse_mode_keeps_the_transport_rule(fake):
    runs = fake(seconds={"direct/structured": 3.0, "direct/reuse": 1.0})
    solver = jb.DirectBackwardEuler(jb.Structured(), transport="source")
    _, times, reuse = full_runs("model", solver, _config(solver))
    assert reuse is True and [t for _, t, _ in runs.runs] == ["source", "source"]


def test_a_reuse_solver_is_timed_once(fake):
    runs = fake(seconds={"direct/reuse": 1.0})
    _, times, reuse = full_runs("model", REUSE, _config(REUSE))
    assert times == (FullModeTime("direct/reuse", 1.0),) and reuse is False and len(runs.runs) == 1


def test_a_diverged_full_run_is_refused(fake):
    runs = fake(seconds={"direct/kept-interior": 1.0}, nan=True)
    with pytest.raises(FullRunDivergedError, match="^the full simulation diverged; nothing to compare with$"):
        full_runs("model", EXACT, _config(EXACT))
    assert len(runs.runs) == 1  # the reuse mode is not run


def _result(cost):
    return SimpleNamespace(n_steps=100, predict_from_step=20, train_steps=20, n_train_runs=2, cost=cost,
                           to_dict=lambda: {"method": "dmd", "rmse_um": 0.5})


@pytest.mark.parametrize("reuse_faster", [True, False])
def test_speedups_against_the_fastest_full_mode(fake, monkeypatch, reuse_faster):
    fake(seconds={"direct/kept-interior": 3.0, "direct/reuse": 2.0 if reuse_faster else 4.0})
    cost = ReductionCost(offline_s=0.5, offline_first_call_s=4.0, online_s=0.1, estimate_s=0.25, calibration_s=0.5)
    seen = {}

    def compare(model, train, config, train_solvers, trained, *, full_trajectory, reuse_factors, clock):
        seen.update(full=full_trajectory.name, reuse=reuse_factors, clock=clock, train=train)
        return _result(cost)

    monkeypatch.setattr(reduction, "reduce_and_compare", compare)
    timed = reduce_and_time("model", ["train"], _config(EXACT))
    assert seen["full"] == "direct/kept-interior" and seen["reuse"] is reuse_faster and seen["train"] == ["train"]
    assert seen["clock"] == reduction.warm_best  # the training runs timed by the same clock
    t = timed.timings
    fastest = 2.0 if reuse_faster else 3.0
    assert t.full_run_s == fastest and t.full_mode == ("direct/reuse" if reuse_faster else "direct/kept-interior")
    assert t.scene_mode_run_s == 3.0
    assert t.speedup_online == pytest.approx(fastest / 0.1)
    assert t.speedup_total == pytest.approx(fastest / 0.6)
    assert t.speedup_total_vs_scene_mode == pytest.approx(3.0 / 0.6)
    per_step = (fastest / 100) / (0.1 / 80)  # 80 predicted steps in 0.1 s
    assert t.speedup_per_step_online == pytest.approx(per_step)
    assert t.speedup_eq_7_5 == pytest.approx(100 / (20 * 2 + 80 / per_step))  # n / (n_train + n_pred / s)
    assert (t.offline_s, t.offline_first_call_s, t.online_s) == (0.5, 4.0, 0.1)
    assert (t.error_estimate_s, t.error_estimate_total_s) == (0.25, 0.75)


def test_without_an_estimate_its_times_are_none(fake, monkeypatch):
    fake(seconds={"direct/reuse": 1.0})
    cost = ReductionCost(offline_s=0.5, offline_first_call_s=1.0, online_s=0.25)
    monkeypatch.setattr(reduction, "reduce_and_compare", lambda *a, **k: _result(cost))
    t = reduce_and_time("model", ["train"], _config(REUSE)).timings
    assert (t.error_estimate_s, t.error_estimate_total_s) == (None, None)
    assert t.full_runs == (FullModeTime("direct/reuse", 1.0),) and t.speedup_online == pytest.approx(4.0)


def test_json_form_is_the_comparison_with_its_timings():
    timings = ReductionTimings(full_run_s=2.0, full_mode="direct/reuse", full_runs=(FullModeTime("direct/reuse", 2.0),),
                               scene_mode_run_s=2.0, offline_s=0.5, offline_first_call_s=1.0, online_s=0.1,
                               speedup_online=20.0, speedup_total=float("inf"), speedup_total_vs_scene_mode=3.0,
                               speedup_per_step_online=16.0, speedup_eq_7_5=2.2)
    d = TimedReduction(result=_result(None), timings=timings).to_dict()
    assert d["method"] == "dmd" and d["rmse_um"] == 0.5
    assert d["timings"]["full_runs"] == [{"mode": "direct/reuse", "run_s": 2.0}]
    assert d["timings"]["speedup_total"] is None  # not finite: null in JSON
    assert d["timings"]["error_estimate_s"] is None and d["timings"]["note"].startswith("compilation excluded")


@pytest.mark.parametrize("solver,expected", [(EXACT, ["direct/kept-interior", "direct/reuse"]),
                                             (REUSE, ["direct/reuse"])])
def test_warm_full_runs_compiles_each_timed_mode_once(monkeypatch, solver, expected):
    compiled = []
    monkeypatch.setattr(reduction, "compile_simulate",
                        lambda model, s, *, n_steps, dt, saveat: compiled.append((solver_name(s), n_steps, dt, saveat)))
    reduction.warm_full_runs("model", solver, _config(solver, n_steps=40, every=4))
    assert compiled == [(name, 40, 0.01, jb.SaveAt(every=4)) for name in expected]
