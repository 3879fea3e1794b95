"""How many refinement iterations the factorisation-reuse solver needs: error and time.

``three-roller-t72`` (N = 3762), its whole 100 s (5000 steps), the reuse solver with 0 … 3
iterative-refinement iterations against the exact solver (kept interior): the largest tracer
difference (u and v, mm) over the run, and the wall time of the run (compile apart; the variants
timed in interleaved rounds, best of ``--rounds``; set ``OPENBLAS_NUM_THREADS=1``). With the shift
transport the step matrix changes only through the roller tilts' lever arms, so the frozen factors
are nearly exact and each refinement multiplies the error by ‖I − F₀⁻¹A‖. Writes
``results/refinement.json``.
"""

import argparse
import time

import jax
import numpy as np

import jaxbelt as jb
from _common import write


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--steps", type=int, default=5000)
    a = ap.parse_args()
    scene = jb.load_scene("three-roller-t72")
    model, dt = jb.build_model(scene), jb.RunOptions.from_scene(scene).dt
    variants = {"exact": jb.DirectBackwardEuler(jb.KeptInterior())}
    for k in (0, 1, 2, 3):
        variants[f"reuse refine {k}"] = jb.DirectBackwardEuler(jb.Reuse(refine=k))
    out, best, compile_s = {}, {}, {}
    for name, integ in variants.items():
        t0 = time.perf_counter()
        out[name] = jax.block_until_ready(jb.simulate(model, integ, n_steps=a.steps, dt=dt)[1])
        compile_s[name] = time.perf_counter() - t0
    for _ in range(a.rounds):
        for name, integ in variants.items():
            t0 = time.perf_counter()
            jax.block_until_ready(jb.simulate(model, integ, n_steps=a.steps, dt=dt)[1].tracer_u)
            best[name] = min(best.get(name, np.inf), time.perf_counter() - t0)
    ref = out["exact"]
    rows = []
    for name in variants:
        tr = out[name]
        err = max(np.abs(np.asarray(tr.tracer_u) - np.asarray(ref.tracer_u)).max(),
                  np.abs(np.asarray(tr.tracer_v) - np.asarray(ref.tracer_v)).max()) * 1e6
        rows.append({"solver": name, "max_tracer_error_um": float(err), "run_s": best[name],
                     "ms_per_step": best[name] / a.steps * 1e3, "first_call_s": compile_s[name]})
        print(f"{name:16s}  error {err:.2e} µm  run {best[name]:.2f} s ({best[name] / a.steps * 1e3:.3f} ms/step)",
              flush=True)
    write("refinement", {"scene": "three-roller-t72", "steps": a.steps, "rounds": a.rounds, "rows": rows})


if __name__ == "__main__":
    main()
