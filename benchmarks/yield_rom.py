"""Monte-Carlo yield with and without the reduced-model surrogate (``run_sweep(rom="off"|"auto")``)
on the 2D default scene ``three-roller-t72`` at full size (18 × 104, N = 3762).

Study: metric ``lateral_max`` at t_eval = 2 s (100 steps), five varied components (roller 2 and
roller 3 rotations about x and y, roller 3 z translation), independent normal laws σ = 0.1 mrad /
0.01 mm around the scene's own misalignment, limit 60 µm (the scene's own metric is 39 µm),
1000 configurations, seed 0. Full runs use direct Backward Euler with the factorisation-reuse
solver (the fastest full model, ``benchmarks/solver_2d.py``) in both sweeps, so the surrogate is
trained on and validated against exactly the model the full-only sweep runs.

Each sweep runs in a fresh process, so each pays its own compilation (the study's aligned
reference run is timed apart, it is the same for both). Afterwards the surrogate is fitted
again with the sweep's seed (deterministic) and evaluated on every configuration, and its metric
and per-sample bound are compared with the full-only sweep's metric sample by sample.

Writes ``results/yield_rom.json`` and ``results/yield_rom.png``. ``--quick``: 200 configurations.
Takes ~6 min on 2 cores.
"""

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from _common import RESULTS, write

SCENE = "three-roller-t72"
METRIC = "lateral_max"
T_EVAL = 2.0
COMPONENTS = "roller 2:rotation,roller 3:dz,roller 3:rotation"
SIGMA = {"roller 2:ax": 0.1, "roller 2:ay": 0.1, "roller 3:dz": 0.01, "roller 3:ax": 0.1, "roller 3:ay": 0.1}
LIMIT = 60.0
SEED = 0
QUICK = "--quick" in sys.argv
N = 200 if QUICK else 1000


def setup():
    import jax

    jax.config.update("jax_enable_x64", True)
    import jaxbelt as jb
    from jaxbelt import design
    from jaxbelt.integrators import make_integrator

    model = jb.load_model(SCENE)
    t0 = time.perf_counter()
    study = design.make_study(model, METRIC, t_eval=T_EVAL, components=COMPONENTS,
                              integrator=make_integrator("direct", model, linear_solver="reuse"))
    t_study = time.perf_counter() - t0
    labels = study.space.labels()
    dist = design.Distribution(tuple(labels), ("normal",) * len(labels), tuple(SIGMA[lab] for lab in labels))
    return model, study, dist, t_study


def part(which, out_path):
    """One sweep in this (fresh) process; results to ``out_path`` (npz + json)."""
    from jaxbelt import design

    model, study, dist, t_study = setup()
    res = design.run_sweep(study, dist, N, LIMIT, seed=SEED, rom=which, with_form=False)
    info = {k: v for k, v in res.items() if k != "metric_values"}
    info.update(study_s=t_study, n_unknowns=int(model.n_unknowns), n_steps=int(study.n_steps),
                labels=study.space.labels())
    arrays = {"metric": np.asarray(res["metric_values"])}
    if which == "auto":
        import jax.numpy as jnp

        from jaxbelt.design.sampling import standard_normal_samples
        from jaxbelt.design.surrogate import fit_surrogate

        sur = fit_surrogate(study, dist, LIMIT, seed=SEED + 7919)  # the sweep's own validation seed
        thetas = np.asarray(dist.transform(jnp.asarray(standard_normal_samples(N, study.space.size, SEED))))
        sur.evaluate(thetas)
        t0 = time.perf_counter()
        pred = sur.evaluate(thetas)
        info["online_s_all"] = time.perf_counter() - t0
        arrays.update(rom_metric=pred["metric"], rom_bound=pred["bound"], rho=sur.distance(thetas))
    np.savez(out_path.with_suffix(".npz"), **arrays)
    out_path.with_suffix(".json").write_text(json.dumps(info, default=float))


def run_part(which, tmp):
    path = Path(tmp) / which
    t0 = time.perf_counter()
    subprocess.run([sys.executable, __file__, "--part", which, "--out", str(path)] + (["--quick"] if QUICK else []),
                   check=True)
    wall = time.perf_counter() - t0
    info = json.loads(path.with_suffix(".json").read_text())
    info["process_wall_s"] = wall
    return info, dict(np.load(path.with_suffix(".npz")))


def main():
    with tempfile.TemporaryDirectory() as tmp:
        off, a_off = run_part("off", tmp)
        print("off:", {k: off[k] for k in ("yield", "ci95", "full_runs", "wall_s")})
        auto, a_auto = run_part("auto", tmp)
        print("auto:", {k: auto[k] for k in ("yield", "ci95", "full_runs", "reduced_runs", "wall_s")})
    full = a_off["metric"]
    err_sweep = np.abs(a_auto["metric"] - full)
    err_rom = np.abs(a_auto["rom_metric"] - full)
    bound = a_auto["rom_bound"]
    rom = auto["rom"]
    reruns = auto["full_runs"] - rom["validation_runs"]
    per_full = off["wall_s"] / N
    out = {
        "scene": SCENE, "n_unknowns": off["n_unknowns"], "metric": METRIC, "t_eval_s": T_EVAL,
        "n_steps": off["n_steps"], "integrator": "direct, linear_solver = reuse", "components": off["labels"],
        "sigma": SIGMA, "limit_um": LIMIT, "samples": N, "seed": SEED,
        "study_setup_s": off["study_s"],
        "full_only": {"wall_s": off["wall_s"], "full_runs": off["full_runs"], "yield": off["yield"],
                      "ci95": off["ci95"], "per_config_s": per_full},
        "rom_auto": {"wall_s": auto["wall_s"], "full_runs": auto["full_runs"], "reduced_runs": auto["reduced_runs"],
                     "near_limit_reruns": reruns, "yield": auto["yield"], "ci95": auto["ci95"],
                     "offline_s": rom["offline_s"], "online_s": auto["online_s_all"],
                     "online_per_config_s": auto["online_s_all"] / N, "validation": rom},
        "speedup": off["wall_s"] / auto["wall_s"],
        # fixed cost of the surrogate over the per-configuration saving: the sample count from which it pays
        "break_even_samples": (auto["wall_s"] - auto["online_s_all"] - reruns * per_full)
        / max(per_full - auto["online_s_all"] / N, 1e-12),
        "per_sample_check": {
            "max_error_um": float(err_rom.max()), "median_error_um": float(np.median(err_rom)),
            "min_error_um": float(err_rom.min()), "metric_range_um": [float(full.min()), float(full.max())],
            "max_bound_um": float(bound.max()), "median_bound_um": float(np.median(bound)),
            "bound_violations": int(np.sum(err_rom > bound)),
            "min_effectivity": float(np.min(bound[err_rom > 0] / err_rom[err_rom > 0])),
            "beyond_validated_range": int(np.sum(bound > rom["max_bound_um"] * (1 + 1e-9))),
            "max_error_in_sweep_um": float(err_sweep.max()),
            "discordant_pass_fail": int(np.sum((a_auto["metric"] <= LIMIT) != (full <= LIMIT))),
            "samples_within_bound_of_limit": int(np.sum(np.abs(a_auto["rom_metric"] - LIMIT) <= bound)),
        },
        "auto_yield_in_full_ci95": bool(off["ci95"][0] <= auto["yield"] <= off["ci95"][1]),
    }
    print(json.dumps({k: v for k, v in out.items() if k not in ("rom_auto",)}, indent=1, default=float))
    name = "yield_rom_quick" if QUICK else "yield_rom"
    write(name, out)
    plot(out, full, err_rom, bound, a_auto["rho"], name)


def plot(out, full, err, bound, rho, name):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(1, 3, figsize=(15, 4.8), constrained_layout=True)
    fo, ra = out["full_only"], out["rom_auto"]
    v = ra["validation"]
    parts = {"training runs": v["training_s"], "POD + projection": v["fit_s"], "validation runs": v["validation_s"]}
    rest = ra["wall_s"] - v["offline_s"]
    ax = axs[0]
    ax.barh(["full only"], [fo["wall_s"]], color="tab:gray")
    left = 0.0
    for (lab, val), col in zip(parts.items(), ("tab:blue", "tab:orange", "tab:green")):
        ax.barh(["rom auto"], [val], left=left, color=col, label=lab)
        left += val
    ax.barh(["rom auto"], [rest], left=left, color="tab:red", label=f"reduced runs + {ra['near_limit_reruns']} re-runs")
    ax.text(fo["wall_s"], 0, f" {out['samples']} full runs", va="center")
    ax.text(ra["wall_s"], 1, f" ×{out['speedup']:.1f}", va="center")
    ax.set(xlabel="wall time (s)", title=f"{out['samples']} configurations, {out['scene']} (N = {out['n_unknowns']})")
    ax.set_xlim(0, 1.15 * max(fo["wall_s"], ra["wall_s"]))
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=2)
    ax = axs[1]
    ok = err > 0
    ax.semilogy(rho[ok], err[ok], ".", ms=3, label="|reduced − full| metric, sweep samples")
    order = np.argsort(rho)
    ax.semilogy(rho[order], bound[order], "k-", lw=1, label="per-sample bound")
    ax.axvline(v["rho_max"], color="gray", ls=":", lw=0.8, label="validated range")
    ax.set(xlabel="ρ = ‖θ / w‖ (training widths)", ylabel="µm",
           title=f"{v['n_modes']} modes; bound = {v['safety']:.0f} × largest of {v['n_validation']} validation errors")
    ax.legend(fontsize=8)
    ax = axs[2]
    ax.hist(full, bins=40, color="tab:gray")
    ax.axvline(out["limit_um"], color="k", ls="--")
    title = "\n".join(f"{lab}: yield {res['yield']:.3f} [{res['ci95'][0]:.3f}, {res['ci95'][1]:.3f}]"
                      for lab, res in (("full only", fo), ("rom auto", ra)))
    ax.set(xlabel=f"{out['metric']} (µm), full model; limit dashed", ylabel="configurations")
    ax.set_title(title, fontsize=10)
    fig.savefig(RESULTS / f"{name}.png", dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    if "--part" in sys.argv:
        part(sys.argv[sys.argv.index("--part") + 1], Path(sys.argv[sys.argv.index("--out") + 1]))
    else:
        main()
