"""``jaxbelt bench``'s pieces: the Pareto front and its table, the SuperLU
baseline checked against jaxbelt on a small scene, and the compiled programs it times giving
``simulate``'s results (timings themselves are never asserted)."""

import dataclasses

import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.bench import pareto


def test_front_keeps_only_undominated_points():
    pts = [(1.0, 5.0), (2.0, 1.0), (3.0, 2.0), (0.5, 9.0), (4.0, 0.5), (2.0, 6.0)]
    assert sorted(pareto._front(pts)) == [0, 1, 3, 4]


def test_front_table_lists_the_undominated_candidates_fastest_first():
    rows = {"a": dict(time_s=1.0, lateral_max_um=3.0, longitudinal_final_um=1.0, bytes=2**20),
            "b": dict(time_s=5.0, lateral_max_um=0.2, longitudinal_final_um=1.0, bytes=2**21),
            "c": dict(time_s=0.5, lateral_max_um=30.0, longitudinal_final_um=1.0, bytes=None),
            "d": dict(time_s=6.0, lateral_max_um=0.3, longitudinal_final_um=1.0, bytes=None)}
    assert [r["name"] for r in pareto.front_rows(rows)] == ["c", "a", "b"]  # d: slower and less accurate than b
    md = pareto.table_markdown({"scene": "s", "t_end_s": 1.0, "rows": rows})
    assert "| a | 1 | 1.0 | 3 | 1 |" in md and "| d |" not in md and "--accuracy-um" in md


def test_superlu_baseline_reproduces_jaxbelt_on_a_small_scene():
    pytest.importorskip("scipy")
    from jaxbelt.bench import baselines

    sc = jb.load_scene("three-roller-t72")
    sc = sc.replace(mesh=dataclasses.replace(sc.mesh, n_eta=3))
    m, opts = jb.build_model(sc), jb.RunOptions.from_scene(sc)
    out = baselines.per_step(m, opts.dt, rounds=1, steps=4, scipy_steps=3)
    # the numpy + SuperLU step is an independent implementation of the same discrete step
    assert out["scipy_reference_max_tracer_diff_vs_jaxbelt_um"] < 1e-6
    assert out["superlu_ordering"] in ("MMD_AT_PLUS_A", "COLAMD")
    assert all(np.isfinite(v) and v > 0 for v in out["ms_per_step"].values())


def test_timed_programs_give_the_results_of_simulate():
    from jaxbelt.bench import timing

    model, dt = jb.load_model("two-roller-1d"), 0.005
    solver = jb.DirectBackwardEuler(jb.Reuse())
    _, ref = jb.simulate(model, solver, n_steps=6, dt=dt)
    run, compile_s, _ = timing.compile_run(model, solver, n_steps=6, dt=dt)
    steps, init_s = timing.compile_steps(model, solver, n_steps=6, dt=dt)
    for traj in (run(model, dt)[1], steps()[1]):
        np.testing.assert_allclose(np.asarray(traj.tracer_u), np.asarray(ref.tracer_u), rtol=1e-12, atol=1e-15)
    assert compile_s > 0 and init_s > 0
