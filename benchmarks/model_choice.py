"""The cheaper runs ``--accuracy-um`` considers, measured: the 1D counterpart of a symmetric 2D
scene and float32.

* ``three-roller`` (2D, no misalignment) over 2 s on its own grid against its 1D counterpart
  (:func:`jaxbelt.accuracy.one_d_counterpart`): the largest longitudinal tracer difference over
  all output times and over the last 0.4 s, the largest lateral displacement of the 2D run, and
  both run times.
* float32 against float64 (each run built and run inside
  :func:`jaxbelt.accuracy.precision_scope`): ``three-roller-t72`` over 2 s on its own grid and on
  9 × 208 at Δt 0.01 s (the grid ``--accuracy-um 40`` chooses there, ``accuracy_trade.py``), and
  ``two-roller-1d`` over 1 s: the largest tracer difference (longitudinal and lateral) and both
  run times.
* The reuse solver against the scene's kept-interior solver on ``three-roller-t72`` at
  9 × 208, Δt 0.01 s: the largest tracer difference and both run times.

Run times are the best of three runs (compilation apart). Run:
``OPENBLAS_NUM_THREADS=1 python benchmarks/model_choice.py``. Writes ``results/model_choice.json``.
"""

import dataclasses

import numpy as np
from _common import write

import jaxbelt as jb
from jaxbelt.accuracy import one_d_counterpart, precision_scope, refine, scene_grid, tracer_run, window_difference_um


def best_run(scene, precision="float64", repeat=3):
    with precision_scope(precision):
        runs = [tracer_run(scene) for _ in range(repeat)]
    return min(runs, key=lambda r: r.run_s)


def horizon(name, t_end):
    s = jb.load_scene(name)
    return s.replace(time=dataclasses.replace(s.time, t_end=t_end))


def main():
    jb.enable_x64()
    out = {}
    s2 = horizon("three-roller", 2.0)
    s1, why = one_d_counterpart(s2)
    r2, r1 = best_run(s2), best_run(s1)
    out["one_d"] = dict(
        scene="three-roller", t_end_s=2.0, grid=dataclasses.asdict(scene_grid(s2)), why=why,
        difference_um=window_difference_um(r1, r2, s2, ("longitudinal",), 0.0),
        difference_last_0_4_s_um=window_difference_um(r1, r2, s2, ("longitudinal",), 1.6),
        lateral_2d_max_um=float(np.max(np.abs(r2.v)) * 1e6), run_2d_s=r2.run_s, run_1d_s=r1.run_s,
        speedup=r2.run_s / r1.run_s)
    print(out["one_d"], flush=True)
    rows = []
    t72 = horizon("three-roller-t72", 2.0)
    cases = (("three-roller-t72", t72), ("three-roller-t72", refine(t72, n_xi=2.0, n_eta=0.5, dt=2.0)),
             ("two-roller-1d", horizon("two-roller-1d", 1.0)))
    for name, sc in cases:
        r64, r32 = best_run(sc), best_run(sc, "float32")
        qs = ("longitudinal",) if sc.kind == "1d" else ("longitudinal", "lateral")
        rows.append(dict(scene=name, grid=dataclasses.asdict(scene_grid(sc)), t_end_s=sc.time.t_end,
                         rounding_um={q: window_difference_um(r32, r64, sc, (q,), 0.0) for q in qs},
                         run_64_s=r64.run_s, run_32_s=r32.run_s, speedup=r64.run_s / r32.run_s))
        print(rows[-1], flush=True)
    out["float32"] = rows
    fine = refine(t72, n_xi=2.0, n_eta=0.5, dt=2.0)
    reuse = fine.replace(solver=dataclasses.replace(fine.solver, linear_solver="reuse"))
    r_k, r_r = best_run(fine), best_run(reuse)
    out["reuse"] = dict(scene="three-roller-t72", grid=dataclasses.asdict(scene_grid(fine)), t_end_s=2.0,
                        solver=fine.solver.linear_solver,
                        difference_um=window_difference_um(r_r, r_k, fine, ("longitudinal", "lateral"), 0.0),
                        run_solver_s=r_k.run_s, run_reuse_s=r_r.run_s, speedup=r_k.run_s / r_r.run_s)
    print(out["reuse"], flush=True)
    write("model_choice", out)


if __name__ == "__main__":
    main()
