"""The whole default run (100 s, 5000 steps) with one linear solver, compile timed apart, with
the process's peak memory. Run: ``python benchmarks/full_run_2d.py [--solver reuse] [--scene ...]
[--tag gpu]``. Writes ``results/full_run_2d[_<tag>].json``."""

import argparse
import resource
import time

import jax
import numpy as np

import jaxbelt as jb
from _common import write
from jaxbelt.registry import LINEAR_SOLVERS
from jaxbelt.timeloop import compile_simulation


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="three-roller-t72")
    ap.add_argument("--solver", default="reuse", choices=LINEAR_SOLVERS)
    ap.add_argument("--steps", type=int, default=None, help="default: the scene's")
    ap.add_argument("--tag", default="")
    args = ap.parse_args()
    scene = jb.load_scene(args.scene)
    model, opts = jb.build_model(scene), jb.RunOptions.from_scene(scene)
    n_steps = args.steps or opts.n_steps
    integ = jb.make_solver("direct", args.solver)
    t0 = time.perf_counter()
    run = compile_simulation(model, integ, n_steps=n_steps, dt=opts.dt)
    compile_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    _, tr = jax.block_until_ready(run(model, opts.dt))
    run_s = time.perf_counter() - t0
    jb.check_finite(tr, opts.dt)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    out = {"scene": args.scene, "solver": args.solver, "device": str(jax.devices()[0]), "n_steps": n_steps,
           "t_end_s": float(tr.t[-1]), "compile_s": compile_s, "run_s": run_s, "per_step_ms": run_s / n_steps * 1e3,
           "peak_rss_mb": peak_mb, "tracer_u_max_abs_um": float(np.max(np.abs(np.asarray(tr.tracer_u)))) * 1e6,
           "tracer_v_max_abs_um": float(np.max(np.abs(np.asarray(tr.tracer_v)))) * 1e6}
    print(out)
    write("full_run_2d" + (f"_{args.tag}" if args.tag else ""), out)


if __name__ == "__main__":
    main()
