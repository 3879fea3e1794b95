"""Monte-Carlo yield with and without the reduced-model surrogate (``run_sweep(rom="off"|"auto")``)
on the 2D default scene ``three-roller-t72`` at full size (18 × 104, N = 3762).

Study: metric ``lateral_max`` at t_eval = 2 s (100 steps), five varied components (roller 2 and
roller 3 rotations about x and y, roller 3 z translation), independent normal laws σ = 0.1 mrad /
0.01 mm around the scene's own misalignment, limit 60 µm (the scene's own metric is 39 µm),
1000 configurations, seed 0. Full runs use direct Backward Euler with the factorisation-reuse
solver (the fastest full model, ``benchmarks/solver_2d.py``) in every sweep, vmapped in the
sweep's batches (``CHUNK``), so the surrogate is trained on and validated against exactly the
model the full-only sweep runs.

Sides, each sweep in a fresh process (each pays its own compilation; the study's aligned
reference run is timed apart, it is the same for all): ``off`` and ``off16`` (full only, in
batches of 64 — the sweep's default — and of 16, the fastest batch in
``results/sweep_throughput.json``; the faster is the reference), ``auto`` (``--rom
auto``, the default surrogate, ``method="response"``) and ``pod`` (``--rom auto`` with the fully
reduced POD step, ``fit_surrogate(method="pod")``). They run interleaved, ``REPEAT`` rounds, and
the best wall time of each side is reported (a shared, loaded machine: ``uptime`` before and
after is recorded). In every ``auto``/``pod`` process the surrogate is then fitted again with the
sweep's seed (deterministic) and evaluated on every configuration, and its metric and per-sample
bound are compared with the full-only sweep's metric sample by sample.

Writes ``results/yield_rom.json`` and ``results/yield_rom.png``. ``--quick``: 200 configurations,
one round. Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/yield_rom.py``; ~10 min on 2 cores.
"""

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from _common import RESULTS, load, write

SCENE = "three-roller-t72"
METRIC = "lateral_max"
T_EVAL = 2.0
COMPONENTS = "roller 2:rotation,roller 3:dz,roller 3:rotation"
SIGMA = {"roller 2:ax": 0.1, "roller 2:ay": 0.1, "roller 3:dz": 0.01, "roller 3:ax": 0.1, "roller 3:ay": 0.1}
LIMIT = 60.0
SEED = 0
QUICK = "--quick" in sys.argv
N = 200 if QUICK else 1000
REPEAT = 1 if QUICK else 2
# side: (rom, surrogate method, chunk); the full-only sweep at the sweep's default batch (64) and at
# 16, the fastest batch in results/sweep_throughput.json: the faster of the two is the reference
SIDES = {"off": ("off", None, 64), "off16": ("off", None, 16), "auto": ("auto", "response", 64),
         "pod": ("auto", "pod", 64)}


def setup():
    import jaxbelt as jb
    from jaxbelt import design

    model, opts = load(SCENE)
    t0 = time.perf_counter()
    study = design.make_study(model, METRIC, opts.replace(solver=jb.DirectBackwardEuler(jb.Reuse())), t_eval=T_EVAL,
                              components=COMPONENTS)
    t_study = time.perf_counter() - t0
    labels = study.space.labels()
    dist = design.Distribution(tuple(labels), ("normal",) * len(labels), tuple(SIGMA[lab] for lab in labels))
    return model, study, dist, t_study


def part(which, out_path):
    """One sweep in this (fresh) process; results to ``out_path`` (npz + json)."""
    from jaxbelt import design

    rom, method, chunk = SIDES[which]
    model, study, dist, t_study = setup()
    res = design.run_sweep(study, dist, N, LIMIT, seed=SEED, chunk=chunk, rom=rom, rom_method=method or "response",
                           with_form=False)
    yield_at = time.time()  # the yield is known: the process's time to it ends here (the check below apart)
    info = res.to_dict()
    info.update(chunk=chunk, yield_at=yield_at, study_s=t_study, n_unknowns=int(model.n_unknowns),
                n_steps=int(study.options.n_steps), labels=study.space.labels())
    arrays = {"metric": np.asarray(res.metric_values)}
    if method is not None:
        from jaxbelt.design.sampling import sample_configurations
        from jaxbelt.design.surrogate import fit_surrogate

        sur = fit_surrogate(study, dist, LIMIT, seed=SEED + 7919, method=method)  # the sweep's own validation seed
        thetas = sample_configurations(dist, N, SEED)
        sur.evaluate(thetas)
        t0 = time.perf_counter()
        pred = sur.evaluate(thetas)
        info["online_s_all"] = time.perf_counter() - t0
        arrays.update(rom_metric=pred["metric"], rom_bound=pred["bound"], rho=sur.distance(thetas))
    np.savez(out_path.with_suffix(".npz"), **arrays)
    out_path.with_suffix(".json").write_text(json.dumps(info, default=float))


def load_average():
    return [float(x) for x in os.getloadavg()]


def run_part(which, tmp):
    path = Path(tmp) / which
    load = load_average()
    started = time.time()
    t0 = time.perf_counter()
    subprocess.run([sys.executable, __file__, "--part", which, "--out", str(path)] + (["--quick"] if QUICK else []),
                   check=True)
    wall = time.perf_counter() - t0
    info = json.loads(path.with_suffix(".json").read_text())
    info.update(process_wall_s=wall, process_to_yield_s=info["yield_at"] - started, load_before=load,
                load_after=load_average())
    return info, dict(np.load(path.with_suffix(".npz")))


def side_summary(runs, off_best, full, which):
    """The best (lowest wall time) of a side's rounds, with the sample-by-sample check against
    the full-only metric ``full``."""
    info, arr = min(runs, key=lambda r: r[0]["wall_s"])
    summary = {"wall_s": info["wall_s"], "wall_s_all": [r[0]["wall_s"] for r in runs],
               "process_to_yield_s": info["process_to_yield_s"],
               "process_to_yield_s_all": [r[0]["process_to_yield_s"] for r in runs],
               "process_wall_s_all": [r[0]["process_wall_s"] for r in runs],
               "load_average_1_5_15": [r[0]["load_before"] for r in runs],
               "full_runs": info["full_runs"], "reduced_runs": info["reduced_runs"], "yield": info["yield"],
               "ci95": info["ci95"], "study_setup_s": info["study_s"]}
    if which == "off":
        return summary
    rom = info["rom"]
    err_sweep = np.abs(arr["metric"] - full)
    err_rom = np.abs(arr["rom_metric"] - full)
    bound = arr["rom_bound"]
    reruns = info["full_runs"] - rom["validation_runs"]
    per_full = off_best["wall_s"] / N
    summary.update(
        near_limit_reruns=reruns, offline_s=rom["offline_s"], online_s=info["online_s_all"],
        online_per_config_s=info["online_s_all"] / N, validation=rom,
        speedup=off_best["wall_s"] / info["wall_s"],
        speedup_process=off_best["process_to_yield_s"] / info["process_to_yield_s"],
        # fixed cost of the surrogate over the per-configuration saving: the sample count from which it pays
        break_even_samples=(info["wall_s"] - info["online_s_all"] - reruns * per_full)
        / max(per_full - info["online_s_all"] / N, 1e-12),
        yield_in_full_ci95=bool(off_best["ci95"][0] <= info["yield"] <= off_best["ci95"][1]),
        per_sample_check={
            "max_error_um": float(err_rom.max()), "median_error_um": float(np.median(err_rom)),
            "min_error_um": float(err_rom.min()), "metric_range_um": [float(full.min()), float(full.max())],
            "max_bound_um": float(bound.max()), "median_bound_um": float(np.median(bound)),
            "bound_violations": int(np.sum(err_rom > bound)),
            "min_effectivity": float(np.min(bound[err_rom > 0] / err_rom[err_rom > 0])),
            "beyond_validated_range": int(np.sum(bound > rom["max_bound_um"] * (1 + 1e-9))),
            "max_error_in_sweep_um": float(err_sweep.max()),
            "discordant_pass_fail": int(np.sum((arr["metric"] <= LIMIT) != (full <= LIMIT))),
            "samples_within_bound_of_limit": int(np.sum(np.abs(arr["rom_metric"] - LIMIT) <= bound)),
        })
    return summary


def main():
    runs = {side: [] for side in SIDES}
    with tempfile.TemporaryDirectory() as tmp:
        for rnd in range(REPEAT):  # interleaved rounds: every side sees the machine's load alike
            for side in SIDES:
                info, arr = run_part(side, tmp)
                runs[side].append((info, arr))
                print(f"round {rnd + 1} {side}:", {k: info[k] for k in ("yield", "ci95", "full_runs", "reduced_runs",
                                                                         "wall_s", "process_to_yield_s", "load_before")},
                      flush=True)
    full_runs = runs["off"] + runs["off16"]
    off_info, off_arr = min(full_runs, key=lambda r: r[0]["wall_s"])
    full = off_arr["metric"]
    for info, arr in full_runs:  # deterministic: every round and batch the same metric (to round-off)
        np.testing.assert_allclose(arr["metric"], full, rtol=1e-9)
    first = runs["off"][0][0]
    out = {
        "scene": SCENE, "n_unknowns": first["n_unknowns"], "metric": METRIC, "t_eval_s": T_EVAL,
        "n_steps": first["n_steps"], "integrator": "direct, linear_solver = reuse",
        "chunks": {side: c for side, (_, _, c) in SIDES.items()},
        "components": first["labels"], "sigma": SIGMA, "limit_um": LIMIT, "samples": N, "seed": SEED,
        "rounds": REPEAT, "timing": "best of the interleaved rounds per side; each sweep in a fresh process; "
                                    "wall_s = run_sweep's wall time (the study's aligned reference run apart), "
                                    "process_to_yield_s = from the process's start to the sweep's result (imports, "
                                    "scene, study set-up, sweep; the benchmark's own re-fit for the sample-by-sample "
                                    "check after it is left out)",
    }
    off = side_summary(full_runs, off_info, full, "off")
    off.update(per_config_s=off["wall_s"] / N, chunk=off_info["chunk"],
               by_chunk={str(SIDES[s][2]): side_summary(runs[s], off_info, full, "off") for s in ("off", "off16")})
    out["full_only"] = off
    out["rom_auto"] = side_summary(runs["auto"], off_info, full, "auto")
    out["rom_pod"] = side_summary(runs["pod"], off_info, full, "pod")
    out["speedup"] = out["rom_auto"]["speedup"]
    out["speedup_pod"] = out["rom_pod"]["speedup"]
    out["per_sample_check"] = out["rom_auto"]["per_sample_check"]
    out["auto_yield_in_full_ci95"] = out["rom_auto"]["yield_in_full_ci95"]
    print(json.dumps({k: v for k, v in out.items() if k not in ("rom_auto", "rom_pod")}, indent=1, default=float))
    for side in ("rom_auto", "rom_pod"):
        print(side, json.dumps({k: v for k, v in out[side].items() if k != "validation"}, default=float))
    name = "yield_rom_quick" if QUICK else "yield_rom"
    write(name, out)
    best_auto = min(runs["auto"], key=lambda r: r[0]["wall_s"])[1]
    plot(out, full, np.abs(best_auto["rom_metric"] - full), best_auto["rom_bound"], best_auto["rho"], name)


def plot(out, full, err, bound, rho, name):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(1, 3, figsize=(15, 4.8), constrained_layout=True)
    fo = out["full_only"]
    ax = axs[0]
    ax.barh(["full only"], [fo["wall_s"]], color="tab:gray")
    labels = {"rom_auto": "rom auto\n(response)", "rom_pod": "rom auto\n(POD)"}
    colors = ("tab:blue", "tab:orange", "tab:green")
    for i, side in enumerate(("rom_auto", "rom_pod")):
        ra = out[side]
        v = ra["validation"]
        parts = {"training runs": v["training_s"], "fit (SVD + projection)": v["fit_s"],
                 "validation runs": v["validation_s"]}
        left = 0.0
        for (lab, val), col in zip(parts.items(), colors):
            ax.barh([labels[side]], [val], left=left, color=col, label=lab if i == 1 else None)
            left += val
        ax.barh([labels[side]], [ra["wall_s"] - v["offline_s"]], left=left, color="tab:red",
                label="reduced runs + re-runs" if i == 1 else None)
        ax.text(ra["wall_s"], i + 1, f" {ra['wall_s']:.1f} s, ×{ra['speedup']:.1f}", va="center")
    ax.text(fo["wall_s"], 0, f" {fo['wall_s']:.0f} s, {out['samples']} full runs", va="center", ha="right",
            color="w")
    ax.set(xlabel="wall time (s), best of the rounds",
           title=f"{out['samples']} configurations, {out['scene']} (N = {out['n_unknowns']})")
    ax.set_xlim(0, 1.3 * max(fo["wall_s"], *(out[side]["wall_s"] for side in labels)))
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=2)
    ax = axs[1]
    v = out["rom_auto"]["validation"]
    ok = err > 0
    ax.semilogy(rho[ok], err[ok], ".", ms=3, label="|surrogate − full| metric, sweep samples")
    order = np.argsort(rho)
    ax.semilogy(rho[order], bound[order], "k-", lw=1, label="per-sample bound")
    ax.axvline(v["rho_max"], color="gray", ls=":", lw=0.8, label="validated range")
    ax.set(xlabel="ρ = ‖θ / w‖ (training widths)", ylabel="µm",
           title=f"response surface; bound = {v['safety']:.0f} × largest of {v['n_validation']} validation errors")
    ax.legend(fontsize=8)
    ax = axs[2]
    ax.hist(full, bins=40, color="tab:gray")
    ax.axvline(out["limit_um"], color="k", ls="--")
    title = "\n".join(f"{lab}: yield {res['yield']:.3f} [{res['ci95'][0]:.3f}, {res['ci95'][1]:.3f}]"
                      for lab, res in (("full only", fo), ("rom auto", out["rom_auto"]), ("rom POD", out["rom_pod"])))
    ax.set(xlabel=f"{out['metric']} (µm), full model; limit dashed", ylabel="configurations")
    ax.set_title(title, fontsize=10)
    fig.savefig(RESULTS / f"{name}.png", dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    if "--part" in sys.argv:
        part(sys.argv[sys.argv.index("--part") + 1], Path(sys.argv[sys.argv.index("--out") + 1]))
    else:
        main()
