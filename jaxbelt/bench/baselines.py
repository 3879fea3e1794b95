"""jaxbelt against the baselines a user would pick, side by side in one process, ratios in one run.

On the default 2D scene (``three-roller-t72``, N = 3762), every figure per step:

* **SciPy SuperLU on the same matrix**: the assembled, row-equilibrated step matrix of the first
  step (:class:`~jaxbelt.bench.scipy_reference.ScipyBelt`), factor + solve and solve-only with a
  kept factor, the column ordering the best of ``MMD_AT_PLUS_A`` and ``COLAMD`` (timed, not
  assumed);
* **a numpy + SuperLU implementation of the whole step** (assembly, solve, transport), factor
  every step and factor once — like for like with jaxbelt's exact and reuse modes;
* **jaxbelt exact** (structured block solver, exact to round-off: the interior factors kept for
  the run, the part of the factors the step's matrix changes refactored every step —
  ``DirectBackwardEuler(KeptInterior())``), the same with a **full factorisation every step**
  (``DirectBackwardEuler(Structured())``) and **reuse** (frozen factors, the default refinement:
  ``DirectBackwardEuler(Reuse())``), each 200 compiled steps divided by 200; what a run prepares
  once (the kept or frozen factors: the solver's ``init``) is timed apart.

All candidates are timed in interleaved rounds and the best of each kept (the machine's load
changes the SuperLU figure by ×1.5 from one minute to the next). Besides: the whole 100 s run in
the reuse mode; the compilation (cold, and a second process with the persistent cache warm; the
compile time against the number of steps); the per-configuration cost of ``vmap`` batches of
1, 8, 64, 256 configurations through the sweep's own path; the accelerator figures kept in the
results folder where they exist; the source's reported speedups as a reference row.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import jax
import numpy as np

from .. import design
from ..build import build_model
from ..integrators import DirectBackwardEuler, KeptInterior, Reuse, Structured
from ..scene import load_scene
from ..state import initial_state
from ..timeloop import RunOptions, compile_simulation, tracer_values
from .timing import clock, compile_steps, interleaved_best, write_json

SCENE = "three-roller-t72"

#: The source's reported speedups (its §7.4 and eq. 7.5; MATLAB, its own full model), for reference.
SOURCE_SPEEDUPS = {
    "DMD online, after the snapshots (source §7.4)": 7.2,
    "DMD total over 5000 steps from 400 snapshots (source eq. 7.5)": 4.8,
    "POD trained on several configurations, total (source §7.4)": 2.0,
    "POD, solving the system only (source §8)": "2–3",
}


def _log(msg):
    print(msg, file=sys.stderr, flush=True)


def per_step(model, dt, rounds: int, steps: int = 200, scipy_steps: int = 5) -> dict:
    """Per-step milliseconds of every candidate with time step ``dt`` (s), interleaved rounds,
    best of ``rounds``; the SciPy step is checked against jaxbelt's exact one over
    ``scipy_steps`` steps."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from .scipy_reference import ScipyBelt

    s0 = jax.block_until_ready(initial_state(model))
    solver = {"exact": DirectBackwardEuler(KeptInterior()),
             "exact, full factorisation": DirectBackwardEuler(Structured()),
             "reuse": DirectBackwardEuler(Reuse())}
    runs, init_s = {}, {}
    for k, v in solver.items():
        runs[k], init_s[k] = compile_steps(model, v, n_steps=steps, dt=dt, state=s0)

    sc = ScipyBelt(model, dt)
    st = [np.asarray(x) for x in (s0.u, s0.u_dot, s0.chi, s0.chi_dot, s0.m_e)]
    A = sc.matrices(st[4], sc.R(st[0]))
    scale = 1.0 / abs(A).max(axis=1).toarray().ravel()
    As = (sp.diags(scale) @ A).tocsc()
    b = np.random.default_rng(0).standard_normal(As.shape[0])
    orderings = ("MMD_AT_PLUS_A", "COLAMD")
    factor_t = interleaved_best({o: (lambda o=o: spla.splu(As, permc_spec=o)) for o in orderings}, 2, 2)
    order = min(factor_t, key=factor_t.get)
    kept_lu = spla.splu(As, permc_spec=order)
    kept = sc.kept_factor(st[0], st[4], order)
    # the reference is checked, not trusted: its trajectory against jaxbelt's exact one
    s = st
    for _ in range(scipy_steps):
        s = list(sc.step(*s, permc_spec=order))
    _, ref = runs["exact"]()
    tu, _ = tracer_values(model, jax.numpy.asarray(s[0]))
    ref_diff_um = float(np.abs(np.asarray(tu) - np.asarray(ref.tracer_u[scipy_steps - 1])).max() * 1e6)

    def scipy_steps_fn(kept_factor):
        def go():
            s = st
            for _ in range(scipy_steps):
                s = sc.step(*s, permc_spec=order, kept=kept_factor)
            return s[0]
        return go

    cands = {
        "jaxbelt exact step": lambda: runs["exact"]()[0].u,
        "jaxbelt exact step, full factorisation every step": lambda: runs["exact, full factorisation"]()[0].u,
        "jaxbelt reuse step": lambda: runs["reuse"]()[0].u,
        "SuperLU factor + solve (matrix given)": lambda: spla.splu(As, permc_spec=order).solve(b),
        "SuperLU solve, kept factor (matrix given)": lambda: kept_lu.solve(b),
        "numpy + SuperLU step, factor every step": scipy_steps_fn(None),
        "numpy + SuperLU step, factor once": scipy_steps_fn(kept),
    }
    per_call = {"jaxbelt exact step": steps, "jaxbelt reuse step": steps,
                "jaxbelt exact step, full factorisation every step": steps,
                "numpy + SuperLU step, factor every step": scipy_steps, "numpy + SuperLU step, factor once": scipy_steps}
    inner = {"SuperLU factor + solve (matrix given)": 3, "SuperLU solve, kept factor (matrix given)": 20}
    best = interleaved_best(cands, rounds, inner, lambda r, n: _log(f"  per-step round {r}/{n}"))
    ms = {k: 1e3 * t / per_call.get(k, 1) for k, t in best.items()}
    lu_fs = ms["SuperLU factor + solve (matrix given)"]
    lu_s = ms["SuperLU solve, kept factor (matrix given)"]
    ratios = {
        "exact step vs SuperLU factor + solve alone (speedup)": lu_fs / ms["jaxbelt exact step"],
        "exact step with a full factorisation every step vs SuperLU factor + solve alone (speedup)":
            lu_fs / ms["jaxbelt exact step, full factorisation every step"],
        "exact step vs numpy + SuperLU step, factor every step (speedup)":
            ms["numpy + SuperLU step, factor every step"] / ms["jaxbelt exact step"],
        "reuse step in SuperLU kept-factor solves": ms["jaxbelt reuse step"] / lu_s,
        "reuse step vs numpy + SuperLU step, factor once (speedup)":
            ms["numpy + SuperLU step, factor once"] / ms["jaxbelt reuse step"],
    }
    return {"ms_per_step": ms, "ratios": ratios, "ms_per_run_init": {k: 1e3 * t for k, t in init_s.items()},
            "superlu_ordering": order,
            "superlu_factor_s_by_ordering": factor_t, "rounds": rounds, "jaxbelt_steps_per_call": steps,
            "scipy_reference_max_tracer_diff_vs_jaxbelt_um": ref_diff_um, "scipy_reference_steps_checked": scipy_steps}


def whole_run(model, n_steps: int, dt, repeat: int) -> dict:
    """The whole run (``n_steps`` of ``dt`` s) in the reuse mode, compile apart, best of ``repeat``."""
    solver = DirectBackwardEuler(Reuse())
    t0 = time.perf_counter()
    run = compile_simulation(model, solver, n_steps=n_steps, dt=dt)
    comp = time.perf_counter() - t0
    best = min(clock(lambda: run(model, dt)[0].u)[0] for _ in range(repeat))
    return {"n_steps": int(n_steps), "t_end_s": float(n_steps * dt), "run_s": best,
            "compile_s": comp, "ms_per_step": 1e3 * best / n_steps}


_COMPILE_CHILD = r"""
import json, sys, time
t0 = time.perf_counter()
import jax, jaxbelt as jb
from jaxbelt.timeloop import compile_simulation
jb.enable_x64()
jax.config.update("jax_compilation_cache_dir", sys.argv[3])
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.5)
jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
scene = jb.load_scene(sys.argv[1])
m, opts = jb.build_model(scene), jb.RunOptions.from_scene(scene)
solver = jb.DirectBackwardEuler(jb.Reuse())
jax.block_until_ready(jb.initial_state(m))
t_ready = time.perf_counter()
out = {}
for n in map(int, sys.argv[2].split(",")):
    t1 = time.perf_counter()
    compile_simulation(m, solver, n_steps=n, dt=opts.dt)
    out[n] = {"compile_s": time.perf_counter() - t1}
print(json.dumps({"setup_s": t_ready - t0, "by_steps": out}))
"""


def compilation(steps=(50, 5000)) -> dict:
    """Compile time (trace, lower and compile) of a whole run (reuse mode) in fresh processes: cold
    (empty persistent cache) and warm (a second process, the cache the first one left), for each
    number of steps."""
    with tempfile.TemporaryDirectory(prefix="jaxbelt-bench-cache-") as d:
        out = {}
        for label in ("cold", "warm"):
            r = subprocess.run([sys.executable, "-c", _COMPILE_CHILD, SCENE, ",".join(map(str, steps)), d],
                               env=dict(os.environ), capture_output=True, text=True)
            if r.returncode:
                raise RuntimeError(f"compilation child failed: {r.stderr.strip().splitlines()[-1:]}")
            out[label] = json.loads(r.stdout.strip().splitlines()[-1])
    return out


def vmap_batches(batches, steps: int, repeat: int) -> dict:
    """Per-configuration cost of ``vmap`` batches through the sweep's path
    (:func:`jaxbelt.design.evaluate_configs`) on the design scene, exact and reuse solvers."""
    scene = load_scene("three-roller-tolerance")
    model, dt = build_model(scene), RunOptions.from_scene(scene).dt
    rows = {}
    for name, solver in (("exact", DirectBackwardEuler(KeptInterior())), ("reuse", DirectBackwardEuler(Reuse()))):
        study = design.make_study(model, "lateral_max", RunOptions(solver, steps, dt))
        rng = np.random.default_rng(0)
        for b in batches:
            thetas = 0.01 * rng.standard_normal((b, study.space.size))
            first, _ = clock(lambda: design.evaluate_configs(study, thetas, chunk=b))
            best = min(clock(lambda: design.evaluate_configs(study, thetas, chunk=b))[0] for _ in range(repeat))
            rows[f"{name}/{b}"] = {"solver": name, "batch": b, "compile_s": max(first - best, 0.0), "run_s": best,
                                     "ms_per_config_step": 1e3 * best / (b * steps)}
            _log(f"  vmap {name:10s} batch {b:4d}: {rows[f'{name}/{b}']['ms_per_config_step']:.3f} ms "
                 "per configuration-step")
    return {"scene": "three-roller-tolerance", "steps": steps, "rows": rows,
            "note": (
                "the exact mode factors the belt's interior once per run; under vmap over misalignments "
                "those factors are shared by the batch (misalignments change neither stiffness nor masses), "
                "so per configuration and step only the border (the tilt columns' sweep and the Schur "
                "complement) and the solve remain, as in the reuse mode plus the border")}


def accelerator_figures(results_dir: Path) -> dict | None:
    """Accelerator figures (``benchmarks/gpu_2d.py``, ``benchmarks/full_run_2d.py``) kept in ``results_dir``."""
    out = {}
    for name in ("gpu_2d_gpu", "full_run_2d_gpu"):
        p = Path(results_dir) / f"{name}.json"
        if p.exists():
            out[name] = json.loads(p.read_text())
    return out or None


def run(out_dir: Path, quick: bool = False, results_dir: Path | None = None) -> dict:
    """All baselines; writes ``baselines[_quick].json`` and ``.png`` into ``out_dir``."""
    t_start = time.perf_counter()
    scene = load_scene(SCENE)
    model, opts = build_model(scene), RunOptions.from_scene(scene)
    _log(f"baselines on {SCENE} (N = {model.n_unknowns}), {'quick' if quick else 'full'}")
    payload = {"scene": SCENE, "n_unknowns": int(model.n_unknowns), "quick": quick}
    payload["per_step"] = per_step(model, opts.dt, rounds=3 if quick else 6)
    _log("  whole run")
    payload["whole_run_reuse"] = whole_run(model, opts.n_steps, opts.dt, repeat=1 if quick else 3)
    _log("  compilation (two fresh processes)")
    payload["compilation"] = compilation()
    payload["vmap"] = vmap_batches((1, 8, 64) if quick else (1, 8, 64, 256), steps=10 if quick else 20,
                                   repeat=1 if quick else 2)
    payload["accelerator_runs"] = accelerator_figures(results_dir or out_dir)
    payload["source_reported_speedups"] = SOURCE_SPEEDUPS
    payload["wall_s"] = time.perf_counter() - t_start
    name = "baselines" + ("_quick" if quick else "")
    path = write_json(out_dir, name, payload)
    plot(payload, Path(out_dir) / f"{name}.png")
    _log(f"wrote {path}")
    return payload


def plot(payload: dict, path: Path) -> None:
    import matplotlib.pyplot as plt  # backend: the environment's (the CLI sets MPLBACKEND=Agg)

    ms = payload["per_step"]["ms_per_step"]
    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.2), constrained_layout=True)
    names = list(ms)
    colors = ["tab:blue" if n.startswith("jaxbelt") else "tab:gray" for n in names]
    a.barh(names, [ms[n] for n in names], color=colors)
    for i, n in enumerate(names):
        a.text(ms[n], i, f" {ms[n]:.2f} ms", va="center")
    a.set_xscale("log")
    a.set_xlabel("ms per step (log), 2-core CPU, best of interleaved rounds")
    a.set_title(f"{payload['scene']} (N = {payload['n_unknowns']}): jaxbelt (blue) vs SciPy SuperLU")
    rows = payload["vmap"]["rows"]
    for solver in ("exact", "reuse"):
        r = sorted((x for x in rows.values() if x["solver"] == solver), key=lambda x: x["batch"])
        b.loglog([x["batch"] for x in r], [x["ms_per_config_step"] for x in r], "o-", label=solver)
    b.set_xlabel("configurations per vmap batch")
    b.set_ylabel("ms per configuration-step")
    b.set_title("sweep cost per configuration against the batch size")
    b.grid(alpha=0.3, which="both")
    b.legend()
    fig.savefig(path, dpi=110)
    plt.close(fig)
