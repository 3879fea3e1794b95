"""The two per-step figures of ``jaxbelt bench --only baselines`` alone, in about a minute: the
per-step comparison against SciPy SuperLU (interleaved rounds, best of 6:
:func:`jaxbelt.bench.baselines.per_step`) and the whole 100 s reuse run
(:func:`jaxbelt.bench.baselines.whole_run`, best of 3) on ``three-roller-t72``. For tracking the
machine's state between full bench runs; with the command line's process settings
(:func:`jaxbelt.cli.configure_process`), as ``jaxbelt bench`` has them. Writes
``results/step_vs_superlu.json``.
Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/step_vs_superlu.py [--rounds 6]``.
"""

import argparse
import time

import jaxbelt as jb
from _common import write
from jaxbelt.bench.baselines import SCENE, per_step, whole_run
from jaxbelt.cli import configure_process


def main():
    configure_process()  # before the first computation: the XLA flags take effect when the backend starts
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=6)
    a = ap.parse_args()
    scene = jb.load_scene(SCENE)
    model, opts = jb.build_model(scene), jb.RunOptions.from_scene(scene)
    t0 = time.perf_counter()
    out = dict(scene=SCENE, n_unknowns=int(model.n_unknowns), per_step=per_step(model, opts.dt, rounds=a.rounds),
               whole_run=whole_run(model, opts.n_steps, opts.dt, repeat=3))
    out["wall_s"] = time.perf_counter() - t0
    for k, v in out["per_step"]["ms_per_step"].items():
        print(f"{k:50s} {v:8.3f} ms")
    for k, v in out["per_step"]["ratios"].items():
        print(f"{k:90s} {v:6.2f}")
    print(f"whole {out['whole_run']['t_end_s']:g} s run (reuse): {out['whole_run']['run_s']:.2f} s")
    write("step_vs_superlu", out)


if __name__ == "__main__":
    main()
