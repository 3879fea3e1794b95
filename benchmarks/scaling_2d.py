"""Per-step cost against grid size (n_eta 6 → 36, n_xi 104 → 416) on the default geometry,
exact (kept interior) and reuse modes, with the fitted log-log slope against N. (n_xi = 52 puts fewer than
5 elements on roller 2's arc, which jaxbelt rejects; Δt follows the CFL condition at 0.75.)
Run: ``python benchmarks/scaling_2d.py``; writes ``results/scaling_2d[_tag].json`` and ``.png``."""

import argparse
import copy
import time
import tomllib
from importlib import resources

import jax
import numpy as np

import jaxbelt as jb
from _common import RESULTS, write
from jaxbelt.timeloop import compile_simulation

SOLVERS = {"exact": jb.DirectBackwardEuler(jb.KeptInterior()), "reuse": jb.DirectBackwardEuler(jb.Reuse())}


def model_for(n_eta, n_xi):
    d = tomllib.loads((resources.files("jaxbelt") / "scenes" / "three-roller.toml").read_text())
    d = copy.deepcopy(d)
    d["mesh"] = {"n_eta": n_eta, "n_xi": n_xi}
    L = 2.8316
    d["time"]["dt_s"] = 0.75 * (L / n_xi) * 0.9  # below the CFL limit of the shortest element
    scene = jb.scene_from_dict(d)
    return jb.build_model(scene), jb.RunOptions.from_scene(scene).dt


def per_step(model, dt, solver, steps):
    c = compile_simulation(model, SOLVERS[solver], n_steps=steps, dt=dt)
    t0 = time.perf_counter()
    jax.block_until_ready(c(model, dt))
    return (time.perf_counter() - t0) / steps * 1e3


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--tag", default="")
    ap.add_argument("--max-n", type=int, default=40000)
    args = ap.parse_args()
    grid = [(6, 104), (12, 104), (18, 104), (36, 104), (18, 208), (18, 416), (36, 208)]
    rows = []
    for n_eta, n_xi in grid:
        m, dt = model_for(n_eta, n_xi)
        if m.n_unknowns > args.max_n:
            continue
        row = {"n_eta": n_eta, "n_xi": n_xi, "N": m.n_unknowns}
        for solver in ("exact", "reuse"):
            row[f"{solver}_ms"] = per_step(m, dt, solver, args.steps)
        print(row, flush=True)
        rows.append(row)
    N = np.array([r["N"] for r in rows], float)
    fits = {s: float(np.polyfit(np.log(N), np.log([r[f"{s}_ms"] for r in rows]), 1)[0]) for s in ("exact", "reuse")}
    print("log-log slopes vs N:", fits)
    name = "scaling_2d" + (f"_{args.tag}" if args.tag else "")
    write(name, {"device": str(jax.devices()[0]), "rows": rows, "slope_vs_N": fits})

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4), constrained_layout=True)
    for s, mk in (("exact", "o-"), ("reuse", "s-")):
        order = np.argsort(N)
        ax.loglog(N[order], np.array([r[f"{s}_ms"] for r in rows])[order], mk, label=f"{s} (slope {fits[s]:.2f})")
    ax.set_xlabel("unknowns N")
    ax.set_ylabel("ms per step")
    ax.set_title(f"per-step cost vs grid size ({jax.devices()[0].platform})")
    ax.legend()
    ax.grid(alpha=0.3, which="both")
    fig.savefig(RESULTS / f"{name}.png", dpi=120)


if __name__ == "__main__":
    main()
