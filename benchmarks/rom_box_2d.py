"""One reduced model over every misalignment direction of the default 2D scene, tested on
held-out configurations with all rollers misaligned.

Box: every free component of the three rollers of ``three-roller`` (15: dx, dy, dz, ax, ay of
each; α_z is structurally zero), ±3 mm / ±0.5 mrad — it contains Table 7.2's configuration
(``three-roller-t72``: roller 1 y 3 mm, roller 2 ax 0.4 mrad, roller 3 x −1 mm) and the Table 7.3
tests' roller-3 x translations that no Table 7.4 run varied. Training: the axial design
(:func:`jaxbelt.rom.axial_design`: aligned + each component at ±h, 31 runs of ``TRAIN`` steps,
reuse solver), every ``STRIDE``-th snapshot; models: the fully reduced POD step (the
misalignments enter through the model's own input map ``B μ``, projected from the full step's
Jacobian) at several ranks, and DMD with control. Tests: ``three-roller-t72`` and ``N_RANDOM``
configurations drawn uniformly in the box (all 15 components at once), ``STEPS`` steps each,
tracer RMSE (longitudinal and lateral) against the full model. Writes ``results/rom_box_2d.json``.
Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/rom_box_2d.py [--quick]``.
"""

import sys
import time

import jax.numpy as jnp
import numpy as np

import jaxbelt as jb
from _common import load, write
from jaxbelt.misalignment import apply, parameter_space
from jaxbelt.rom import (axial_design, belt_inputs, collect_first_order, fit_dmdc, fit_reduced_pod_ranks, parameters,
                         rmse, stack_controlled, state_to_z, tracer_operator)

QUICK = "--quick" in sys.argv
TRAIN, STRIDE, STEPS, N_RANDOM = (100, 4, 300, 1) if QUICK else (400, 4, 1500, 4)
RANKS = (20, 40, 80)
REUSE = jb.DirectBackwardEuler(jb.Reuse())


def main():
    nominal, opts = load("three-roller")
    dt = opts.dt
    space = parameter_space(nominal)
    h = np.array([3.0 if c.startswith("d") else 0.5 for _, c in space.entries])
    models, thetas, space = axial_design(nominal, space.labels(), h)
    t0 = time.perf_counter()
    post, both, mus = [], [], []
    for m in models:
        _, Zp, Zq = collect_first_order(m, jb.RunOptions(REUSE, TRAIN, dt))
        post.append(Zq[:, ::STRIDE])
        both.append(jnp.concatenate([Zp[:, ::STRIDE], Zq[:, ::STRIDE]], axis=1))
        mus.append(parameters(m))
    t_runs = time.perf_counter() - t0
    print(f"{len(models)} training runs of {TRAIN} steps: {t_runs:.1f} s", flush=True)
    t0 = time.perf_counter()
    pods = fit_reduced_pod_ranks(models[0], jnp.concatenate(both, axis=1), RANKS, dt)
    t_pod = time.perf_counter() - t0
    t0 = time.perf_counter()
    X, Y, U = stack_controlled(post, [belt_inputs(mu, z.shape[1] - 1) for mu, z in zip(mus, post)])
    dmdc = fit_dmdc(X, Y, U, rank=40)
    t_dmdc = time.perf_counter() - t0
    print(f"fits: POD (ranks {RANKS}, one projection) {t_pod:.1f} s, DMDc {t_dmdc:.1f} s", flush=True)
    # DMDc was fitted on every STRIDE-th post-transport state: it steps STRIDE steps at a time
    C, Cz = tracer_operator(nominal), tracer_operator(nominal, "z")
    obs = jnp.concatenate([jnp.concatenate([C, jnp.zeros_like(C)], 1), jnp.concatenate([Cz, jnp.zeros_like(C)], 1)])

    rng = np.random.default_rng(1)
    tests = {"three-roller-t72": load("three-roller-t72")[0]}
    for i in range(N_RANDOM):
        th = rng.uniform(-h, h)
        tests[f"random {i + 1} (all 15 components)"] = apply(models[0], space, th, base=models[0].chi_static)
    rows = {}
    for name, mt in tests.items():
        _, ref = jb.simulate(mt, REUSE, n_steps=STEPS, dt=dt)
        mu, st = parameters(mt), jb.initial_state(mt)
        row = {}
        for r, rom in pods.items():
            out = rom.run(rom.project(mt, st), mu, STEPS)
            row[f"POD r={r}"] = {"rmse_u_um": float(rmse(ref.tracer_u, out.tracer_u)) * 1e6,
                                 "rmse_v_um": float(rmse(ref.tracer_v, out.tracer_v)) * 1e6}
        pred = dmdc.predict(state_to_z(mt, st, dt), belt_inputs(mu, 1)[:, 0], STEPS // STRIDE, observe=obs)
        ntr = C.shape[0]
        sel = slice(STRIDE - 1, STEPS, STRIDE)
        row["DMDc r=40 (every 4th step)"] = {
            "rmse_u_um": float(rmse(ref.tracer_u[sel], pred[:, :ntr])) * 1e6,
            "rmse_v_um": float(rmse(ref.tracer_v[sel], pred[:, ntr:])) * 1e6}
        row["max_tracer_v_um"] = float(jnp.max(jnp.abs(ref.tracer_v))) * 1e6
        rows[name] = row
        print(name, {k: (round(v["rmse_u_um"], 3), round(v["rmse_v_um"], 3)) if isinstance(v, dict) else round(v, 1)
                     for k, v in row.items()}, flush=True)
    write("rom_box_2d" + ("_quick" if QUICK else ""),
          {"box_half_widths": dict(zip(space.labels(), h.tolist())), "training_runs": len(models), "train_steps": TRAIN,
           "stride": STRIDE, "test_steps": STEPS, "training_runs_s": t_runs, "pod_fit_s": t_pod, "dmdc_fit_s": t_dmdc,
           "rows": rows})


if __name__ == "__main__":
    main()
