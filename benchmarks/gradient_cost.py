"""Cost of the gradient of a tracer metric w.r.t. the roller misalignments, through a whole run.

Metric: RMS of the final lateral tracer displacement ``tracer_v[-1]``; parameters:
``model.chi_static`` (all roller misalignment components). For 50, 500 (and with ``--long``
5000) steps on ``three-roller-t72``, exact (kept interior) and reuse solver: the wall time of the
forward run and of ``jax.grad`` of it (both jit-compiled, static equilibrium included; compile
timed apart; best of several runs, forward and gradient interleaved in one process, so that a
shared machine's load hits both alike) and their ratio, and the memory: each case also runs
alone in its own subprocess, which reports its peak resident set (``ru_maxrss``) and XLA's
temporary buffer size (``compiled.memory_analysis()``). Two controls: the forward run without the
checkpointed scan (``adjoint=Checkpointed(steps=0)``: ``jax.checkpoint`` costs nothing without
differentiation) and, up to 500 steps, the gradient without it (memory then grows with every
step's stored residuals).

Run: ``python benchmarks/gradient_cost.py [--long] [--steps 50 500]``. Writes
``results/gradient_cost.json`` and ``.png`` (``--tag`` changes the name).
"""

import argparse
import json
import subprocess
import sys
import time

import jaxbelt as jb

RESULTS_NAME = "gradient_cost"
REPEAT = {50: 7, 500: 3}  # best of; 1 for longer runs
MODES = ("forward", "gradient", "forward_no_checkpoint", "gradient_no_checkpoint")
NO_CHECKPOINT_GRAD_MAX_STEPS = 500

SOLVERS = {"exact": jb.DirectBackwardEuler(jb.KeptInterior()), "reuse": jb.DirectBackwardEuler(jb.Reuse())}


def run_case(scene, steps, solver, modes, repeat):
    """Cases in this process: compile each mode, then time them interleaved (best of ``repeat``;
    one untimed warm-up call each when ``repeat > 1``); one JSON line on stdout with the process's
    peak RSS (meaningful for a single mode)."""
    import resource

    import jax
    import jax.numpy as jnp

    jb.enable_x64()
    sc = jb.load_scene(scene)
    model, dt = jb.build_model(sc), jb.RunOptions.from_scene(sc).dt
    chi = model.chi_static
    integ = SOLVERS[solver]

    def metric(chi, checkpoint):
        m = model.replace(chi_static=chi)
        _, tr = jb.simulate(m, integ, n_steps=steps, dt=dt, adjoint=jb.Checkpointed(checkpoint))
        return jnp.sqrt(jnp.mean(tr.tracer_v[-1] ** 2))

    out = {"steps": steps, "solver": solver, "modes": {},
           "maxrss_before_compile_bytes": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024}
    compiled = {}
    for mode in modes:
        f = lambda c, ck=(0 if mode.endswith("no_checkpoint") else None): metric(c, ck)
        t0 = time.perf_counter()
        compiled[mode] = jax.jit(jax.grad(f) if mode.startswith("gradient") else f).lower(chi).compile()
        r = out["modes"][mode] = {"compile_s": time.perf_counter() - t0, "runs_s": []}
        try:
            r["xla_temp_bytes"] = int(compiled[mode].memory_analysis().temp_size_in_bytes)
        except Exception:  # not every backend reports it
            r["xla_temp_bytes"] = None
        if repeat > 1:
            jax.block_until_ready(compiled[mode](chi))
    for _ in range(repeat):
        for mode in modes:
            t0 = time.perf_counter()
            jax.block_until_ready(compiled[mode](chi))
            out["modes"][mode]["runs_s"].append(time.perf_counter() - t0)
    for r in out["modes"].values():
        r["run_s"] = min(r["runs_s"])
    out["maxrss_bytes"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print(json.dumps(out))


def in_subprocess(scene, steps, solver, modes, repeat):
    cmd = [sys.executable, __file__, "--case", scene, str(steps), solver, ",".join(modes), str(repeat)]
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd[2:])} failed:\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def plot(rows, ratios, path, title):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    def ratio_points(ratios, solver):
        pts = [(int(n), r["gradient_over_forward"]) for n, r in ratios.get(solver, {}).items() if "gradient_over_forward" in r]
        return zip(*sorted(pts)) if pts else ((), ())

    fig, (a1, a2, a3) = plt.subplots(1, 3, figsize=(15, 4.2), constrained_layout=True)
    for solver, marker, color in (("exact", "o", "tab:blue"), ("reuse", "s", "tab:orange")):
        a1.plot(*ratio_points(ratios, solver), marker=marker, color=color, label=solver)
        for mode, ls in (("forward", ":"), ("gradient", "-"), ("gradient_no_checkpoint", "--")):
            pts = [(r["steps"], r["maxrss_bytes"] / 2**20) for r in rows if r["solver"] == solver and r["mode"] == mode]
            if pts:
                a2.plot(*zip(*sorted(pts)), ls=ls, marker=marker, color=color, label=f"{solver}, {mode.replace('_', ' ')}")
            pts = [(r["steps"], r["xla_temp_bytes"] / 2**20) for r in rows
                   if r["solver"] == solver and r["mode"] == mode and r["xla_temp_bytes"] is not None]
            if pts:
                a3.plot(*zip(*sorted(pts)), ls=ls, marker=marker, color=color, label=f"{solver}, {mode.replace('_', ' ')}")
    a1.axhline(3.0, color="grey", ls="--", lw=1, label="target 3×")
    a1.set(xscale="log", xlabel="time steps", ylabel="gradient time / forward time", ylim=(0, None), title=title)
    a1.legend(fontsize=7)
    a2.set(xscale="log", yscale="log", xlabel="time steps", ylabel="peak RSS of the process (MiB)",
           title="memory (one subprocess per case)")
    a2.legend(fontsize=7)
    a3.set(xscale="log", yscale="log", xlabel="time steps", ylabel="XLA temporary buffers (MiB)",
           title="compiled.memory_analysis()")
    a3.legend(fontsize=7)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="three-roller-t72")
    ap.add_argument("--steps", type=int, nargs="+", default=[50, 500])
    ap.add_argument("--long", action="store_true", help="also 5000 steps (the gradient takes minutes)")
    ap.add_argument("--solvers", nargs="+", default=list(SOLVERS), choices=tuple(SOLVERS))
    ap.add_argument("--modes", nargs="+", default=list(MODES), choices=MODES)
    ap.add_argument("--tag", default=RESULTS_NAME, help="results file name")
    ap.add_argument("--case", nargs=5, help=argparse.SUPPRESS)  # SCENE STEPS SOLVER MODE[,MODE..] REPEAT
    args = ap.parse_args()
    if args.case:
        scene, steps, solver, modes, repeat = args.case
        return run_case(scene, int(steps), solver, modes.split(","), int(repeat))

    from _common import RESULTS, write

    steps = sorted(set(args.steps) | ({5000} if args.long else set()))
    rows, ratios = [], {}
    for solver in args.solvers:
        for n in steps:
            modes = [m for m in args.modes if not (m == "gradient_no_checkpoint" and n > NO_CHECKPOINT_GRAD_MAX_STEPS)]
            repeat = REPEAT.get(n, 1)
            for mode in modes:  # memory: one process per mode, one run (also the timing where repeat == 1)
                r = in_subprocess(args.scene, n, solver, [mode], 1)
                m = r["modes"][mode]
                rows.append({"steps": n, "solver": solver, "mode": mode, "compile_s": m["compile_s"],
                             "run_s": m["run_s"], "xla_temp_bytes": m["xla_temp_bytes"],
                             "maxrss_bytes": r["maxrss_bytes"], "maxrss_before_compile_bytes": r["maxrss_before_compile_bytes"]})
            if repeat > 1:  # timing: all modes in one process, interleaved, best of `repeat`
                timed = in_subprocess(args.scene, n, solver, modes, repeat)["modes"]
                for row in rows[-len(modes):]:
                    row.update(run_s=timed[row["mode"]]["run_s"], runs_s=timed[row["mode"]]["runs_s"],
                               compile_s=timed[row["mode"]]["compile_s"])
            for row in rows[-len(modes):]:
                temp = "-" if row["xla_temp_bytes"] is None else f"{row['xla_temp_bytes'] / 2**20:8.1f}"
                print(f"{solver:10s} {n:5d} steps {row['mode']:24s} run {row['run_s']:8.3f} s  compile "
                      f"{row['compile_s']:6.1f} s  peak RSS {row['maxrss_bytes'] / 2**20:7.0f} MiB  XLA temp {temp} MiB",
                      flush=True)
            t = {r["mode"]: r["run_s"] for r in rows[-len(modes):]}
            ratio = ratios.setdefault(solver, {})[str(n)] = {
                f"{mode}_ms_per_step": t[mode] / n * 1e3 for mode in modes}
            ratio["timing"] = (f"best of {repeat}, modes interleaved in one process" if repeat > 1
                               else "one run per mode, each in its own process")
            if "gradient" in t:
                ratio["gradient_over_forward"] = t["gradient"] / t["forward"]
                print(f"{solver:10s} {n:5d} steps  gradient / forward = {ratio['gradient_over_forward']:.2f}", flush=True)
            if "forward_no_checkpoint" in t:
                ratio["forward_no_checkpoint_over_forward"] = t["forward_no_checkpoint"] / t["forward"]
    model = jb.load_model(args.scene)
    write(args.tag, {"scene": args.scene, "n_unknowns": model.n_unknowns, "n_parameters": int(model.chi_static.size),
                     "metric": "sqrt(mean(tracer_v[-1]**2)), gradient w.r.t. model.chi_static",
                     "target_gradient_over_forward": 3.0, "ratios": ratios, "cases": rows})
    plot(rows, ratios, RESULTS / f"{args.tag}.png", f"{args.scene} (N = {model.n_unknowns}), d metric / d chi_static")


if __name__ == "__main__":
    main()
