"""What the steering loop costs: a closed-loop run against the open-loop run of the same machine
(the same model with its ``[[control]]`` removed, lateral transport on, the same solver and step
count), compile timed apart, best of several runs, side by side in one process.

Run: ``python benchmarks/closed_loop.py [--scene three-roller-steered] [--t-end 100] [--solver reuse]``.
Writes ``results/closed_loop.json``.
"""

import argparse
import time

import jax

import jaxbelt as jb
from _common import load, write
from jaxbelt.integrators import solver_name
from jaxbelt.registry import LINEAR_SOLVERS
from jaxbelt.timeloop import compile_simulation


def best_run(model, solver, n_steps, dt, repeat):
    compiled = compile_simulation(model, solver, n_steps=n_steps, dt=dt)
    times, tr = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        _, tr = jax.block_until_ready(compiled(model, dt))
        times.append(time.perf_counter() - t0)
    return min(times), tr


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="three-roller-steered")
    ap.add_argument("--t-end", type=float, default=100.0)
    ap.add_argument("--solver", default=None, choices=LINEAR_SOLVERS, help="default: the scene's")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    model, opts = load(args.scene)
    if model.control is None:
        raise SystemExit(f"{args.scene}: no [[control]] table")
    solver = opts.solver if args.solver is None else jb.make_solver("direct", args.solver)
    n_steps = int(round(args.t_end / opts.dt))
    rows = {}
    for name, m in (("open loop", model.replace(control=None)), ("closed loop", model)):
        run_s, tr = best_run(m, solver, n_steps, opts.dt, args.repeat)
        jb.check_finite(tr, opts.dt)
        rows[name] = {"run_s": run_s, "per_step_ms": run_s / n_steps * 1e3}
        print(f"{name:12s} {run_s:7.3f} s  ({rows[name]['per_step_ms']:.3f} ms/step)")
    ratio = rows["closed loop"]["run_s"] / rows["open loop"]["run_s"]
    print(f"closed / open loop: {ratio:.3f}")
    write("closed_loop", {"scene": args.scene, "solver": solver_name(solver), "n_steps": n_steps,
                          "t_end_s": n_steps * opts.dt, "n_unknowns": model.n_unknowns, "rows": rows,
                          "closed_over_open": ratio, "repeat": args.repeat})


if __name__ == "__main__":
    main()
