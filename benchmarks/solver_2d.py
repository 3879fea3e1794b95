"""2D full-order model on the default scene: jaxbelt's linear solvers (exact: kept interior, full
factorisation with a Thomas or cyclic-reduction interior; reuse with 0 and 1 refinement iterations)
against a numpy + scipy.sparse reference (SuperLU every step,
:class:`jaxbelt.bench.scipy_reference.ScipyBelt`), side by side in one run.

Run: ``python benchmarks/solver_2d.py [--scene three-roller-t72] [--steps 200]``. Checks that
the scipy reference gives the same trajectory (max tracer difference) and writes
``results/solver_2d.json`` and ``.png``.
"""

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

import jaxbelt as jb
from _common import RESULTS, bar_plot, write
from jaxbelt.bench.scipy_reference import ScipyBelt
from jaxbelt.timeloop import compile_simulation, tracer_values


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="three-roller-t72")
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--scipy-steps", type=int, default=60)
    args = ap.parse_args()
    scene = jb.load_scene(args.scene)
    model, dt = jb.build_model(scene), jb.RunOptions.from_scene(scene).dt
    s0 = jax.block_until_ready(jb.initial_state(model))
    rows, trajs = {}, {}
    for name, integ in [("jaxbelt exact (kept interior)", jb.DirectBackwardEuler(jb.KeptInterior())),
                        ("jaxbelt exact, full factorisation", jb.DirectBackwardEuler(jb.Structured())),
                        ("jaxbelt exact, cyclic reduction", jb.DirectBackwardEuler(jb.CyclicReduction())),
                        ("jaxbelt reuse (refine=0)", jb.DirectBackwardEuler(jb.Reuse(refine=0))),
                        ("jaxbelt reuse (refine=1)", jb.DirectBackwardEuler(jb.Reuse(refine=1)))]:
        t0 = time.perf_counter()
        c = compile_simulation(model, integ, n_steps=args.steps, dt=dt)
        comp = time.perf_counter() - t0
        t0 = time.perf_counter()
        _, tr = jax.block_until_ready(c(model, dt))
        run = time.perf_counter() - t0
        trajs[name] = tr
        rows[name] = {"compile_s": comp, "per_step_ms": run / args.steps * 1e3}
    ref = trajs["jaxbelt exact (kept interior)"]
    for name, tr in trajs.items():
        rows[name]["tracer_rmse_vs_exact_mm"] = float(jnp.sqrt(jnp.mean(jnp.concatenate(
            [(tr.tracer_u - ref.tracer_u) ** 2, (tr.tracer_v - ref.tracer_v) ** 2])))) * 1e3

    sc = ScipyBelt(model, dt)
    state = [np.asarray(s0.u), np.asarray(s0.u_dot), np.asarray(s0.chi), np.asarray(s0.chi_dot), np.asarray(s0.m_e)]
    us = []
    t0 = time.perf_counter()
    for _ in range(args.scipy_steps):
        state = list(sc.step(*state))
        us.append(state[0])
    run = time.perf_counter() - t0
    tu, tv = jax.vmap(lambda u: tracer_values(model, u))(jnp.asarray(np.stack(us)))
    diff = max(float(jnp.max(jnp.abs(tu - ref.tracer_u[: args.scipy_steps]))),
               float(jnp.max(jnp.abs(tv - ref.tracer_v[: args.scipy_steps]))))
    rows["numpy + scipy SuperLU"] = {"per_step_ms": run / args.scipy_steps * 1e3,
                                     "max_tracer_diff_vs_exact_mm": diff * 1e3}
    base = rows["numpy + scipy SuperLU"]["per_step_ms"]
    for r in rows.values():
        r["speedup_vs_scipy"] = base / r["per_step_ms"]
    for k, r in rows.items():
        print(f"{k:34s} {r['per_step_ms']:8.2f} ms/step  ×{r['speedup_vs_scipy']:.2f} vs scipy",
              {kk: v for kk, v in r.items() if "rmse" in kk or "diff" in kk})
    reuse = rows["jaxbelt reuse (refine=0)"]["per_step_ms"]
    write("solver_2d", {"scene": args.scene, "n_unknowns": model.n_unknowns, "steps": args.steps,
                        "projected_100s_reuse_s": reuse * 5000 / 1e3, "rows": rows})

    bar_plot(rows, "per_step_ms", "speedup_vs_scipy", "×{:.1f}", "ms per step (assembly + solve + transport), 2-core CPU",
             f"{args.scene}: N = {model.n_unknowns}", RESULTS / "solver_2d.png")


if __name__ == "__main__":
    main()
