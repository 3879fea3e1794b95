"""The two per-step figures of ``jaxbelt bench --only baselines`` alone, in about a minute: the
per-step comparison against SciPy SuperLU (interleaved rounds, best of 6:
:func:`jaxbelt.bench.baselines.per_step`) and the whole 100 s reuse run
(:func:`jaxbelt.bench.baselines.whole_run`, best of 3) on ``three-roller-t72``. For tracking the
machine's state between full bench runs. Writes ``results/step_vs_superlu[_TAG].json``.
Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/step_vs_superlu.py [TAG]``.
"""

import sys
import time

import jaxbelt as jb
from _common import write
from jaxbelt.bench.baselines import SCENE, per_step, whole_run


def main():
    tag = sys.argv[1] if len(sys.argv) > 1 else ""
    model = jb.load_model(SCENE)
    t0 = time.perf_counter()
    out = dict(scene=SCENE, n_unknowns=int(model.n_unknowns), per_step=per_step(model, rounds=6),
               whole_run=whole_run(model, repeat=3))
    out["wall_s"] = time.perf_counter() - t0
    for k, v in out["per_step"]["ms_per_step"].items():
        print(f"{k:50s} {v:8.3f} ms")
    print("reuse step in SuperLU kept-factor solves", round(out["per_step"]["ratios"]["reuse step in SuperLU kept-factor solves"], 2))
    print("whole 100 s run", round(out["whole_run"]["run_s"], 2), "s")
    write("step_vs_superlu" + (f"_{tag}" if tag else ""), out)


if __name__ == "__main__":
    main()
