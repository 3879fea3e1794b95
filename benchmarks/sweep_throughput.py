"""Sweep throughput: configurations × steps per second against the batch size.

The design scene ``three-roller-tolerance`` (N = 3762) evaluated through the sweep's own path
(:func:`jaxbelt.design.evaluate_configs`: ``vmap`` over configurations, sharded over the local
devices) for batch sizes 1–256, with the exact solver (kept interior) and the factorisation-reuse
solver. Compilation is timed apart; each batch is the best of ``--repeat`` runs. Writes
``results/sweep_throughput[_quick].json`` and ``.png``.
"""

import argparse
import time

import numpy as np

import jaxbelt as jb
from _common import RESULTS, load, write
from jaxbelt import design

SOLVERS = {"exact": jb.DirectBackwardEuler(jb.KeptInterior()), "reuse": jb.DirectBackwardEuler(jb.Reuse())}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="n_eta = 6, 20 steps, batches up to 64")
    ap.add_argument("--steps", type=int, default=None)
    ap.add_argument("--repeat", type=int, default=2)
    a = ap.parse_args()
    scene = jb.load_scene("three-roller-tolerance")
    if a.quick:
        scene = scene.replace(mesh=scene.mesh.__class__(n_eta=6, n_xi=104))
    steps = a.steps or (20 if a.quick else 50)
    batches = [1, 4, 16, 64] if a.quick else [1, 4, 16, 64, 256]
    model, opts = load(scene)
    rows = {}
    for solver, integ in SOLVERS.items():
        study = design.make_study(model, "lateral_max", opts.replace(solver=integ, n_steps=steps))
        rng = np.random.default_rng(0)
        for b in batches:
            thetas = 0.01 * rng.standard_normal((b, study.space.size))
            t0 = time.perf_counter()
            design.evaluate_configs(study, thetas, chunk=b)
            first = time.perf_counter() - t0
            best = np.inf
            for _ in range(a.repeat):
                t0 = time.perf_counter()
                design.evaluate_configs(study, thetas, chunk=b)
                best = min(best, time.perf_counter() - t0)
            rows[f"{solver}/{b}"] = {"solver": solver, "batch": b, "compile_s": max(first - best, 0.0),
                                     "run_s": best, "config_steps_per_s": b * steps / best,
                                     "ms_per_config_step": 1e3 * best / (b * steps)}
            print(f"{solver:10s} batch {b:4d}: {1e3 * best / (b * steps):7.3f} ms per configuration-step, "
                  f"compile {max(first - best, 0.0):.1f} s")
    name = "sweep_throughput" + ("_quick" if a.quick else "")
    write(name, {"scene": "three-roller-tolerance", "n_unknowns": int(model.n_unknowns),
                 "steps": steps, "rows": rows})

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 4), constrained_layout=True)
    for solver in SOLVERS:
        r = [rows[f"{solver}/{b}"] for b in batches]
        ax.loglog(batches, [x["config_steps_per_s"] for x in r], "o-", label=solver)
    ax.set_xlabel("configurations per batch")
    ax.set_ylabel("configuration-steps per second")
    ax.set_title(f"sweep throughput, N = {model.n_unknowns}, CPU")
    ax.grid(alpha=0.3, which="both")
    ax.legend()
    fig.savefig(RESULTS / f"{name}.png", dpi=120)


if __name__ == "__main__":
    main()
