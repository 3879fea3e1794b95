"""Accelerator figures for the 2D default scene: exact (full factorisation every step, Thomas or
cyclic-reduction interior; kept interior) and reuse per-step times, and a vmap batch of
misalignment configurations. Run on the GPU machine: ``python benchmarks/gpu_2d.py --batch 256``.
Writes ``results/gpu_2d_<tag>.json`` (tag ``gpu`` by default)."""

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

import jaxbelt as jb
from _common import write
from jaxbelt.timeloop import compile_simulation, run

VMAP_SOLVERS = {"reuse": jb.DirectBackwardEuler(jb.Reuse()),
                "exact": jb.DirectBackwardEuler(jb.CyclicReduction()),
                "kept-interior": jb.DirectBackwardEuler(jb.KeptInterior())}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="three-roller-t72")
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--batch", type=int, default=256)
    ap.add_argument("--tag", default="gpu")
    ap.add_argument("--vmap-integrator", choices=tuple(VMAP_SOLVERS), default="exact")
    ap.add_argument("--skip-single", action="store_true")
    args = ap.parse_args()
    scene = jb.load_scene(args.scene)
    model, dt = jb.build_model(scene), jb.RunOptions.from_scene(scene).dt
    rows = {}
    single = [("exact thomas", jb.DirectBackwardEuler(jb.Structured("thomas"))),
              ("exact cyclic-reduction", jb.DirectBackwardEuler(jb.CyclicReduction())),
              ("exact kept interior", jb.DirectBackwardEuler(jb.KeptInterior())),
              ("reuse", jb.DirectBackwardEuler(jb.Reuse()))]
    for name, solver in [] if args.skip_single else single:
        t0 = time.perf_counter()
        c = compile_simulation(model, solver, n_steps=args.steps, dt=dt)
        comp = time.perf_counter() - t0
        t0 = time.perf_counter()
        jax.block_until_ready(c(model, dt))
        rows[name] = {"compile_s": comp, "per_step_ms": (time.perf_counter() - t0) / args.steps * 1e3}
        print(name, rows[name], flush=True)

    rng = np.random.default_rng(0)
    chis = np.tile(np.asarray(model.chi_static), (args.batch, 1))
    chis[:, 1] = rng.uniform(-5e-3, 5e-3, args.batch)  # roller 1 y translation
    chis[:, 9] = rng.uniform(-5e-4, 5e-4, args.batch)  # roller 2 x rotation
    chis[:, 15] = rng.uniform(-5e-4, 5e-4, args.batch)  # roller 3 x rotation
    solver = VMAP_SOLVERS[args.vmap_integrator]

    def one(chi):
        m = model.replace(chi_static=chi)
        return run(m, solver, jb.initial_state(m), dt, args.steps)[1].tracer_v

    f = jax.jit(jax.vmap(one))
    t0 = time.perf_counter()
    f = f.lower(jnp.asarray(chis)).compile()
    comp = time.perf_counter() - t0
    t0 = time.perf_counter()
    tv = jax.block_until_ready(f(jnp.asarray(chis)))
    wall = time.perf_counter() - t0
    rows[f"vmap {args.batch} configs ({args.vmap_integrator})"] = {
        "compile_s": comp, "wall_s": wall, "per_config_step_ms": wall / args.batch / args.steps * 1e3,
        "max_tracer_v_um": float(jnp.max(jnp.abs(tv))) * 1e6}
    print(rows, flush=True)
    write(f"gpu_2d_{args.tag}", {"device": str(jax.devices()[0]), "scene": args.scene, "steps": args.steps, "rows": rows})


if __name__ == "__main__":
    main()
