"""Where the main job's time goes: ``jaxbelt tolerance`` on the default design scene, stage by
stage, with an empty compilation cache and with a warm one, and the whole command as a user
runs it (``--command-only``: only the whole command with error bars, empty and warm cache).

Each measurement is its own process (the CLI's persistent compilation cache in a fresh
directory: the first process fills it, the second reads it). Stages: imports and start-up, the
model build (mesh, static solve), the aligned steady state and its Jacobian as one
forward-mode program with the actuator jitter's run (first call: compile and run; second call:
run alone), the linear response with the limits read from it, one batch of eight verification
steady solves at the corners of a small box (first and second call: one compiled solve per corner,
:func:`jaxbelt.design.configurations.at_configurations`; in the warm-cache process also the same
batch as one ``vmap``),
the whole box (optimisation and verification), then the error bars: the scene one level finer
built, and its aligned reference and the box's worst corners run as one batch. ``command``: the
wall time of ``jaxbelt tolerance --json`` (error bars on, the default) and of ``--no-error-bars``,
each with an empty cache and again with the cache it filled, and of the default once more with
XLA:CPU's MLIR fusion emitters on (the command line switches them off: :data:`jaxbelt.cli.CLI_XLA_FLAGS`).
``other_commands``: ``jaxbelt steering`` and a 1000-sample ``jaxbelt sweep`` (the distribution
``data/three-roller-steered-dist.toml``; with and without its error bar) on the same scene,
each with an empty cache and again with the cache it filled. ``--stages-only`` measures the stages
again, into the existing results. ``--tolerance-again N`` measures the
tolerance command again, once cold and ``N`` times warm (the median kept, every run listed).
The stages run with the command line's process settings (:func:`jaxbelt.cli.configure_process`). Run:
``OPENBLAS_NUM_THREADS=1 python benchmarks/tolerance_latency.py``. Writes
``results/tolerance_latency.json``.
"""

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from _common import write

CHILD = r"""
import json, os, time
T0 = time.perf_counter()
marks = {}
def mark(name, t=[T0]):
    now = time.perf_counter(); marks[name] = now - t[0]; t[0] = now
import jax, jax.numpy as jnp, numpy as np
import jaxbelt as jb
from jaxbelt.cli import configure_process, enable_compilation_cache
from jaxbelt.cli._common import load_run
from jaxbelt.design import make_study
from jaxbelt.design import tolerance as tol
from jaxbelt.design.study import with_limits
from jaxbelt.design.sensitivity import response_jacobian
from jaxbelt.cli._design import DESIGN_SCENE
from jaxbelt.accuracy import refine
from jaxbelt.cli._common import rebuild
configure_process(); enable_compilation_cache()  # the command line's process settings
mark("imports_s")
scene, mesh, model, opts = load_run(DESIGN_SCENE)
jax.block_until_ready(model.chi_static); mark("model_build_s")
study, linear = make_study(model, "lateral_max", opts, jacobian=True, steady=True)
jax.block_until_ready(linear); mark("aligned_steady_jacobian_and_jitter_s")
study, linear = make_study(model, "lateral_max", opts, jacobian=True, steady=True)
jax.block_until_ready(linear); mark("aligned_steady_jacobian_and_jitter_again_s")
limits = {"longitudinal_max": 20.0, "steering_max": 3.0}
work = with_limits(study, (("lateral_max", 20.0),) + tuple(limits.items()))
response_jacobian(work, linear=linear); mark("linear_response_s")
# eight corners of a small box (every component ±0.005 mm or mrad): real solves, each from its linear start
th = jnp.asarray(np.random.default_rng(0).choice([-1.0, 1.0], (8, study.space.size)) * 0.005)
np.asarray(tol._limit_values_batch(work, th)); mark("verification_batch_first_s")
np.asarray(tol._limit_values_batch(work, th)); mark("verification_batch_again_s")
if os.environ.get("VMAP_BATCH") == "1":  # the same batch as one vmap (compiled by the first child's run)
    import equinox as eqx
    from jaxbelt.design.study import limit_values
    vmapped = eqx.filter_jit(lambda st, t: jax.vmap(lambda x: limit_values(st, x))(t))
    np.asarray(vmapped(work, th)); mark("verification_batch_vmap_first_s")
    np.asarray(vmapped(work, th)); mark("verification_batch_vmap_again_s")
res = tol.tolerance_box(study, 20.0, limits=limits, linear=linear); mark("tolerance_box_s")
_, _, fine, fine_opts = rebuild(refine(scene, n_xi=2.0, n_eta=2.0, dt=2.0))
jax.block_until_ready(fine.chi_static); mark("finer_model_build_s")
bars = tol.box_discretisation(res, study, fine, fine_opts); mark("error_bars_s")
marks["total_s"] = time.perf_counter() - T0
print(json.dumps(dict(scene=DESIGN_SCENE, n_unknowns=int(model.n_unknowns), steady=True,
                      parameters=int(study.space.size), iterations=int(res.iterations), stages=marks)))
"""


DIST = Path(__file__).parent / "data" / "three-roller-steered-dist.toml"
OTHER_COMMANDS = (  # the other design commands on the default scene, as a user runs them
    ("steering", ["steering"]),
    ("sweep_1000", ["sweep", "--dist", str(DIST), "--samples", "1000"]),
    ("sweep_1000_no_error_bars", ["sweep", "--dist", str(DIST), "--samples", "1000", "--no-error-bars"]),
)


def _command(argv, env, command="tolerance"):
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "jaxbelt.cli", command, "--json", *argv], env=env, check=True,
                   capture_output=True)
    return time.perf_counter() - t0


def _remeasure():
    """For measuring one command again into the existing results: ``(results, cache, env)``, the
    results file's contents, a fresh compilation-cache directory (a context manager) and the
    command line's environment with it."""
    path = Path(__file__).parent / "results" / "tolerance_latency.json"
    out = {k: v for k, v in json.loads(path.read_text()).items() if k != "machine"}
    cache = tempfile.TemporaryDirectory()
    env = {**os.environ, "JAXBELT_COMPILATION_CACHE": "1", "OPENBLAS_NUM_THREADS": "1", "JAXBELT_CACHE_DIR": cache.name}
    return out, cache, env


def _stages(out, env):
    """The stages with an empty cache and again with the cache that run filled, into ``out``."""
    for label in ("empty_cache", "warm_cache"):
        vmap = {"VMAP_BATCH": "1" if label == "warm_cache" else "0"}
        r = subprocess.run([sys.executable, "-c", CHILD], env={**env, **vmap}, capture_output=True, text=True,
                           check=True)
        out[label] = json.loads(r.stdout.strip().splitlines()[-1])
        print(label, json.dumps(out[label]["stages"]), flush=True)


def main():
    import argparse

    ap = argparse.ArgumentParser()
    ap.add_argument("--command-only", action="store_true",
                    help="only the whole command with error bars, empty and warm cache (no stages, no variants)")
    ap.add_argument("--only", choices=[name for name, _ in OTHER_COMMANDS], default=None,
                    help="measure one of the other commands again, into the existing results")
    ap.add_argument("--stages-only", action="store_true",
                    help="only the stages (empty and warm cache), into the existing results")
    ap.add_argument("--tolerance-again", type=int, default=0, metavar="N",
                    help="measure the tolerance command with error bars again: once with an empty cache, then N "
                         "times warm (median and spread), into the existing results")
    args = ap.parse_args()
    if args.tolerance_again:
        out, cache, env = _remeasure()
        with cache:
            cold = _command([], env)
            warm = [_command([], env) for _ in range(args.tolerance_again)]
        out["command"]["error_bars"] = {"empty_cache_s": cold, "warm_cache_s": float(np.median(warm)),
                                        "warm_cache_runs_s": warm}
        print("error_bars", out["command"]["error_bars"], flush=True)
        write("tolerance_latency", out)
        return
    if args.only:
        out, cache, env = _remeasure()
        command, *argv = dict(OTHER_COMMANDS)[args.only]
        with cache:
            out["other_commands"][args.only].update(empty_cache_s=_command(argv, env, command),
                                                     warm_cache_s=_command(argv, env, command))
        print(args.only, out["other_commands"][args.only], flush=True)
        write("tolerance_latency", out)
        return
    base = {**os.environ, "JAXBELT_COMPILATION_CACHE": "1", "OPENBLAS_NUM_THREADS": "1"}
    if args.stages_only:
        out, cache, env = _remeasure()
        with cache:
            _stages(out, env)
        write("tolerance_latency", out)
        return
    out = {"command_only": args.command_only}
    base = {**os.environ, "JAXBELT_COMPILATION_CACHE": "1", "OPENBLAS_NUM_THREADS": "1"}
    if not args.command_only:
        with tempfile.TemporaryDirectory() as cache:
            _stages(out, {**base, "JAXBELT_CACHE_DIR": cache})
    out["command"] = {}
    # the last pair: the command with XLA:CPU's MLIR fusion emitters, which it otherwise switches off
    # (the user's XLA_FLAGS win), to measure what that switch saves
    variants = (("error_bars", [], None), ("no_error_bars", ["--no-error-bars"], None),
                ("error_bars_mlir_fusion_emitters", [], "--xla_cpu_use_fusion_emitters=true"))
    for name, argv, xla in variants[:1] if args.command_only else variants:
        with tempfile.TemporaryDirectory() as cache:
            env = {**base, "JAXBELT_CACHE_DIR": cache, **({"XLA_FLAGS": xla} if xla else {})}
            out["command"][name] = {"empty_cache_s": _command(argv, env), "warm_cache_s": _command(argv, env)}
        print(name, out["command"][name], flush=True)
    out["other_commands"] = {}
    for name, (command, *argv) in OTHER_COMMANDS:
        with tempfile.TemporaryDirectory() as cache:
            env = {**base, "JAXBELT_CACHE_DIR": cache}
            out["other_commands"][name] = {"argv": [command, *argv[:1]] + (["FILE.toml"] if argv else []) + argv[2:],
                                           "empty_cache_s": _command(argv, env, command),
                                           "warm_cache_s": _command(argv, env, command)}
        print(name, out["other_commands"][name], flush=True)
    write("tolerance_latency", out)


if __name__ == "__main__":
    main()
