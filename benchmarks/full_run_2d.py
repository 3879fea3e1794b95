"""The whole default run (100 s, 5000 steps) in the fast mode, compile timed apart, with the
process's peak memory. Run: ``python benchmarks/full_run_2d.py [--solver reuse] [--scene ...]``.
Writes ``results/full_run_2d[_<device>].json``."""

import argparse
import resource
import time

import jax
import numpy as np

import jaxbelt as jb
from jaxbelt.timeloop import _run_jit
from _common import write


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="three-roller-t72")
    ap.add_argument("--solver", default="reuse")
    ap.add_argument("--tag", default="")
    args = ap.parse_args()
    model = jb.load_model(args.scene)
    t0 = time.perf_counter()
    s0 = jax.block_until_ready(jb.initial_state(model))
    integ = jb.make_integrator("direct", model, args.solver)
    c = _run_jit.lower(model, integ, s0, model.n_steps).compile()
    compile_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    _, tr = jax.block_until_ready(c(model, integ, s0, model.n_steps))
    run_s = time.perf_counter() - t0
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    out = {"scene": args.scene, "solver": args.solver, "device": str(jax.devices()[0]), "n_steps": model.n_steps,
           "t_end_s": float(tr.t[-1]), "compile_s": compile_s, "run_s": run_s, "per_step_ms": run_s / model.n_steps * 1e3,
           "peak_rss_mb": peak_mb, "tracer_u_max_abs_mm": float(np.max(np.abs(np.asarray(tr.tracer_u)))) * 1e3,
           "tracer_v_max_abs_mm": float(np.max(np.abs(np.asarray(tr.tracer_v)))) * 1e3}
    print(out)
    write("full_run_2d" + (f"_{args.tag}" if args.tag else ""), out)


if __name__ == "__main__":
    main()
