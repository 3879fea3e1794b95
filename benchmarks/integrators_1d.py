"""Per-step cost of the three 1D integrators and of the structured (kept interior) vs dense solves,
side by side.

Run: ``python benchmarks/integrators_1d.py [--steps 400]``. Writes
``benchmarks/results/integrators_1d.json`` and ``.png``; also the largest tracer difference of
each integrator against the default (direct, kept interior) over the same run.
"""

import argparse

import jax
import jax.numpy as jnp

import jaxbelt as jb
from _common import RESULTS, bar_plot, timed, write


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="two-roller-1d-train1")
    ap.add_argument("--steps", type=int, default=400)
    args = ap.parse_args()
    scene = jb.load_scene(args.scene)
    model, dt = jb.build_model(scene), jb.RunOptions.from_scene(scene).dt
    state = jb.initial_state(model)
    variants = {
        "direct (kept interior)": jb.DirectBackwardEuler(jb.KeptInterior()),
        "direct (dense)": jb.DirectBackwardEuler(jb.Dense()),
        "eliminated (dense ODE)": jb.EliminatedBackwardEuler(),
        "naive 3N (dense)": jb.NaiveBackwardEuler(),
    }
    rows, ref = {}, None
    for name, integ in variants.items():
        fn = jax.jit(lambda s, integ=integ: jb.simulate(model, integ, n_steps=args.steps, dt=dt, y0=s)[1].tracer_u)
        comp, run, tu = timed(fn, state)
        ref = tu if ref is None else ref
        rows[name] = {"compile_s": comp, "run_s": run, "per_step_ms": run / args.steps * 1e3,
                      "max_tracer_diff_vs_direct_m": float(jnp.max(jnp.abs(tu - ref)))}
        print(f"{name:26s} {rows[name]['per_step_ms']:8.3f} ms/step  compile {comp:5.2f} s  "
              f"max diff {rows[name]['max_tracer_diff_vs_direct_m']:.2e} m")
    base = rows["direct (kept interior)"]["per_step_ms"]
    for r in rows.values():
        r["ratio_to_direct"] = r["per_step_ms"] / base
    write("integrators_1d", {"scene": args.scene, "n_unknowns": model.n_unknowns, "steps": args.steps, "rows": rows})

    bar_plot(rows, "per_step_ms", "ratio_to_direct", "{:.1f}×", "ms per step (solve + transport), CPU",
             f"{args.scene}: N = {model.n_unknowns}, {args.steps} steps", RESULTS / "integrators_1d.png")


if __name__ == "__main__":
    main()
