"""A reduced model over a 15-component box, trained only as much as the tolerance needs: the time
of the command, and its error estimate against the truth on fresh configurations from the box.

Box: every free component of ``three-roller``'s three rollers (dx, dy, dz, ax, ay), ±3 mm /
±0.5 mrad (``benchmarks/rom_box_2d.py``'s box). Command: ``jaxbelt reduce three-roller --method
dmdc --train-ranges BOX.toml --steps 1500 --json`` (tolerance 20 µm: the sizing loop stops where
the error estimate on 10 held-out configurations is below 2 µm), timed as its own process with an
empty compilation cache and again with the cache the first call left.

Truth: ``N_FRESH`` configurations drawn uniformly from the box with another seed than the
command's held-out ones (all 15 components at once), each predicted by the sized model over the
1500 steps and run with the full model (reuse solver); the calibrated estimate of each
prediction's tracer RMSE against the true one (effectivity = estimate / truth), and the largest
error over time likewise (tracer RMSEs in µm). Writes ``results/rom_box_sized.json`` and ``.png``.
Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/rom_box_sized.py``.
"""

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import jax.numpy as jnp
import numpy as np

import jaxbelt as jb
from _common import RESULTS, load, machine, write
from jaxbelt.misalignment import aligned, apply, parameter_space
from jaxbelt.rom import belt_inputs, error_rom, parameters, rmse, state_to_z, tracer_operator, train_over_box
from jaxbelt.rom.sizing import held_out_configurations
from jaxbelt.rom.dmdc import prediction_trajectory

SCENE, STEPS, N_FRESH, FRESH_SEED = "three-roller", 1500, 12, 1
TRANSLATION_MM, ROTATION_MRAD = 3.0, 0.5


def box_toml(labels) -> str:
    rollers = list(dict.fromkeys(lab.split(":")[0] for lab in labels))
    out = []
    for r in rollers:
        out += [f'[roller."{r}"]', f'translation_mm = {{dist = "uniform", half_width = [{TRANSLATION_MM}, '
                f'{TRANSLATION_MM}, {TRANSLATION_MM}]}}',
                f'rotation_mrad = {{dist = "uniform", half_width = [{ROTATION_MRAD}, {ROTATION_MRAD}, 0.0]}}']
    return "\n".join(out) + "\n"


def command(box_path, cache):
    """The command in its own process: ``(wall seconds, report)``."""
    env = {**os.environ, "JAXBELT_CACHE_DIR": cache, "JAXBELT_COMPILATION_CACHE": "1", "OPENBLAS_NUM_THREADS": "1"}
    argv = [sys.executable, "-m", "jaxbelt.cli", "reduce", SCENE, "--method", "dmdc", "--train-ranges", str(box_path),
            "--steps", str(STEPS), "--json"]
    t0 = time.perf_counter()
    out = subprocess.run(argv, env=env, capture_output=True, text=True, check=True)
    return time.perf_counter() - t0, json.loads(out.stdout)


def main():
    nominal, opts = load(SCENE)
    space = parameter_space(nominal)
    labels = space.labels()
    h = np.array([TRANSLATION_MM if c.startswith("d") else ROTATION_MRAD for _, c in space.entries])
    runs = {}
    with tempfile.TemporaryDirectory() as d:
        box_path = Path(d) / "box.toml"
        box_path.write_text(box_toml(labels))
        cache = str(Path(d) / "xla")
        for label in ("empty_cache", "warm_cache"):
            wall, report = command(box_path, cache)
            runs[label] = dict(wall_s=wall, sizing=report["sizing"], rmse_um=report["rmse_um"],
                               error_estimate_um=report["error_estimate_um"], effectivity=report["effectivity"],
                               modes=report["modes"], train_steps=report["train_steps"],
                               offline_s=report["timings"]["offline_s"])
            print(f"{label}: {wall:.1f} s, {report['train_steps']} steps, {report['modes']} modes", flush=True)

    # the same sizing in this process, then fresh configurations against the full model
    solver = jb.DirectBackwardEuler(jb.Reuse(), transport=opts.solver.transport)
    trained = train_over_box(nominal, labels, h, jb.RunOptions(solver, STEPS, opts.dt))
    kappa = trained.calibration.safety_factor
    base = aligned(nominal)
    C = tracer_operator(nominal)
    Cz = jnp.concatenate([C, jnp.zeros_like(C)], axis=1)
    rows = []
    for i, theta in enumerate(held_out_configurations(h, N_FRESH, FRESH_SEED)):
        m = apply(base, space, theta, base=base.chi_static)
        _, ref = jb.simulate(m, solver, n_steps=STEPS, dt=opts.dt)
        steps = np.rint(np.asarray(ref.t) / opts.dt).astype(int)
        keep = (steps >= 1) & (steps <= STEPS)
        z0 = state_to_z(m, jb.initial_state(m), opts.dt)
        u = belt_inputs(parameters(m), 1)[:, 0]
        pred = np.asarray(trained.fit.predict(z0, u, STEPS, observe=Cz))[steps[keep] - 1]
        truth = np.asarray(ref.tracer_u)[keep]
        err_t = np.sqrt(np.mean((truth - pred) ** 2, axis=1)) * 1e6
        traj = prediction_trajectory(trained.fit, z0, u, STEPS)
        est = error_rom(m, traj.basis, traj.coords, opts.dt, traj.z_true0, stride=10, order="post",
                        solver=solver)
        est_t = kappa * np.asarray(est.error_um)[steps[keep] - 1]
        true_um = float(rmse(truth, pred)) * 1e6
        row = dict(theta=theta.tolist(), rmse_um=true_um, estimate_um=float(np.sqrt(np.mean(est_t**2))),
                   max_um=float(err_t.max()), estimate_max_um=float(est_t.max()))
        row["effectivity"] = row["estimate_um"] / true_um
        row["effectivity_max"] = row["estimate_max_um"] / row["max_um"]
        rows.append(row)
        print(f"fresh {i + 1}: RMSE {true_um:.3f} µm, estimate {row['estimate_um']:.3f} µm, "
              f"effectivity {row['effectivity']:.2f} (max over time {row['effectivity_max']:.2f})", flush=True)
    eff = np.array([r["effectivity"] for r in rows])
    eff_max = np.array([r["effectivity_max"] for r in rows])
    payload = dict(
        machine=machine(), scene=SCENE, steps=STEPS, components=list(labels), half_widths=h.tolist(),
        tol_um=20.0, command=runs,
        sized=dict(train_steps=trained.train_steps, modes=trained.modes, stop=trained.stop, safety_factor=kappa,
                   levels=[dict(train_steps=lv.train_steps, modes=lv.modes, worst_estimate_um=max(lv.estimate_um),
                                evaluated=len(lv.estimate_um), passed=lv.passed) for lv in trained.levels]),
        fresh=rows,
        summary=dict(n_fresh=len(rows), largest_rmse_um=max(r["rmse_um"] for r in rows),
                     effectivity_min=float(eff.min()), effectivity_max=float(eff.max()),
                     effectivity_of_max_min=float(eff_max.min()), effectivity_of_max_max=float(eff_max.max()),
                     within_1_to_3=int(np.sum((eff >= 1) & (eff <= 3)))))
    write("rom_box_sized", payload)
    plot(rows, RESULTS / "rom_box_sized.png")


def plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.2, 4.2))
    t = np.array([r["rmse_um"] for r in rows])
    e = np.array([r["estimate_um"] for r in rows])
    lo, hi = min(t.min(), e.min()) / 2, max(t.max(), e.max()) * 2
    x = np.array([lo, hi])
    ax.fill_between(x, x, 3 * x, color="tab:green", alpha=0.15, label="effectivity 1–3")
    ax.loglog(t, e, "o", label="fresh configurations")
    ax.set_xlim(lo, hi)
    ax.set_ylim(lo, hi)
    ax.set_xlabel("true tracer RMSE (µm)")
    ax.set_ylabel("calibrated estimate (µm)")
    ax.set_title("DMDc over a 15-component box, sized to 0.02 mm")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    main()
