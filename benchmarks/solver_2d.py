"""2D full-order model on the default scene: jaxbelt's exact and reuse modes against a
numpy + scipy.sparse reference (SuperLU every step), side by side in one run.

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
from jaxbelt.timeloop import _run_jit
from _common import RESULTS, bar_plot, write
from scipy_reference import ScipyBelt


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="three-roller-t72")
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--scipy-steps", type=int, default=60)
    args = ap.parse_args()
    model = jb.load_model(args.scene)
    s0 = jax.block_until_ready(jb.initial_state(model))
    rows, trajs = {}, {}
    for name, integ in [("jaxbelt exact (structured)", jb.make_integrator("direct", model, "structured")),
                        ("jaxbelt exact, cyclic reduction", jb.DirectBackwardEuler("structured", "cyclic-reduction")),
                        ("jaxbelt reuse (refine=2)", jb.make_integrator("direct", model, "reuse")),
                        ("jaxbelt reuse (refine=1)", jb.ReusedFactorisationBackwardEuler.for_model(model, refine=1))]:
        t0 = time.perf_counter()
        c = _run_jit.lower(model, integ, s0, args.steps).compile()
        comp = time.perf_counter() - t0
        t0 = time.perf_counter()
        _, tr = jax.block_until_ready(c(model, integ, s0, args.steps))
        run = time.perf_counter() - t0
        trajs[name] = tr
        rows[name] = {"compile_s": comp, "per_step_ms": run / args.steps * 1e3}
    ref = trajs["jaxbelt exact (structured)"]
    for name, tr in trajs.items():
        rows[name]["tracer_rmse_vs_exact_mm"] = float(jnp.sqrt(jnp.mean(jnp.concatenate(
            [(tr.tracer_u - ref.tracer_u) ** 2, (tr.tracer_v - ref.tracer_v) ** 2])))) * 1e3

    sc = ScipyBelt(model)
    state = [np.asarray(s0.u), np.asarray(s0.u_dot), np.asarray(s0.chi), np.asarray(s0.chi_dot), np.asarray(s0.m_e)]
    us = []
    t0 = time.perf_counter()
    for _ in range(args.scipy_steps):
        state = list(sc.step(*state))
        us.append(state[0])
    run = time.perf_counter() - t0
    tu, tv = jax.vmap(lambda u: jb.timeloop.tracer_values(model, u))(jnp.asarray(np.stack(us)))
    diff = max(float(jnp.max(jnp.abs(tu - ref.tracer_u[: args.scipy_steps]))),
               float(jnp.max(jnp.abs(tv - ref.tracer_v[: args.scipy_steps]))))
    rows["numpy + scipy SuperLU"] = {"per_step_ms": run / args.scipy_steps * 1e3,
                                     "max_tracer_diff_vs_exact_mm": diff * 1e3}
    base = rows["numpy + scipy SuperLU"]["per_step_ms"]
    for r in rows.values():
        r["speedup_vs_scipy"] = base / r["per_step_ms"]
    for k, r in rows.items():
        print(f"{k:28s} {r['per_step_ms']:8.2f} ms/step  ×{r['speedup_vs_scipy']:.2f} vs scipy", 
              {kk: v for kk, v in r.items() if "rmse" in kk or "diff" in kk})
    reuse = rows["jaxbelt reuse (refine=2)"]["per_step_ms"]
    write("solver_2d", {"scene": args.scene, "n_unknowns": model.n_unknowns, "steps": args.steps,
                        "projected_100s_reuse_s": reuse * 5000 / 1e3, "rows": rows})

    bar_plot(rows, "per_step_ms", "speedup_vs_scipy", "×{:.1f}", "ms per step (assembly + solve + transport), 2-core CPU",
             f"{args.scene}: N = {model.n_unknowns}", RESULTS / "solver_2d.png")


if __name__ == "__main__":
    main()
