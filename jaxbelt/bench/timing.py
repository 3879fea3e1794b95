"""Timing and output helpers of the benchmarks (:mod:`jaxbelt.bench` and the scripts in
``benchmarks/``): the machine, best-of timings in interleaved rounds, JSON output, and runs
compiled ahead of time with their compile time and memory (:func:`compile_run`) or with the
solver's once-per-run data computed beforehand (:func:`compile_steps`)."""

from __future__ import annotations

import json
import os
import platform
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp

from ..state import initial_state
from ..timeloop import SaveAt, run, simulate


def machine() -> dict:
    """What the figures ran on (written into every result file)."""
    return {"platform": platform.platform(), "python": platform.python_version(), "jax": jax.__version__,
            "device": str(jax.devices()[0]), "cpu_count": os.cpu_count(),
            "openblas_num_threads": os.environ.get("OPENBLAS_NUM_THREADS"),
            "x64": bool(jax.config.jax_enable_x64)}


def clock(fn, *args):
    """``(seconds, result)`` of one call, waiting for JAX's asynchronous dispatch."""
    t0 = time.perf_counter()
    out = jax.block_until_ready(fn(*args))
    return time.perf_counter() - t0, out


def interleaved_best(candidates: dict, rounds: int, inner: int | dict = 1, progress=None) -> dict:
    """Best-of-``rounds`` seconds per call for each of ``candidates`` (name → zero-argument
    callable), timed in interleaved rounds (A, B, C, A, B, C, …) so that a change of the machine's
    load hits every candidate alike; within a round a candidate is called ``inner`` times
    (an int, or a dict by name) and its fastest call kept."""
    best = {k: float("inf") for k in candidates}
    for r in range(rounds):
        for name, fn in candidates.items():
            k = inner.get(name, 1) if isinstance(inner, dict) else inner
            for _ in range(k):
                t, _ = clock(fn)
                best[name] = min(best[name], t)
        if progress:
            progress(r + 1, rounds)
    return best


def write_json(out_dir: Path, name: str, payload: dict) -> Path:
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{name}.json"
    path.write_text(json.dumps({"machine": machine(), **payload}, indent=2))
    return path


def compiled_bytes(compiled) -> int | None:
    """Arguments + outputs + temporaries of a compiled XLA program (its memory analysis), or None
    where the backend does not report it."""
    compiled = getattr(compiled, "compiled", compiled)  # equinox's filter_jit wraps jax's Compiled
    try:
        ma = compiled.memory_analysis()
        return int(ma.argument_size_in_bytes + ma.output_size_in_bytes + ma.temp_size_in_bytes
                   - ma.alias_size_in_bytes)
    except Exception:  # pragma: no cover - backend without memory analysis
        return None


@eqx.filter_jit
def _simulated(model, solver, dt, n_steps, saveat):
    return simulate(model, solver, n_steps=n_steps, dt=dt, saveat=saveat, check=False)


def compile_run(model, solver, *, n_steps: int, dt, saveat: SaveAt = SaveAt()):
    """:func:`jaxbelt.simulate`'s program, compiled ahead of time with its memory figure.

    The same program as :func:`jaxbelt.timeloop.compile_simulation`, kept as XLA's compiled
    object so that its memory analysis can be read.

    **Returns:** ``(run, compile_s, nbytes)``: ``run(model, dt) -> (final_state, Trajectory)``
    (no finiteness check), the seconds to trace and compile, :func:`compiled_bytes`."""
    dt = jnp.asarray(dt, dtype=model.ell.dtype)
    t0 = time.perf_counter()
    compiled = _simulated.lower(model, solver, dt, int(n_steps), saveat).compile()
    compile_s = time.perf_counter() - t0

    def run(m, t):
        return compiled(m, solver, jnp.asarray(t, dtype=dt.dtype), int(n_steps), saveat)

    return run, compile_s, compiled_bytes(compiled)


@eqx.filter_jit
def _init(model, solver, state, dt):
    return solver.init(model, state, dt)


@eqx.filter_jit
def _stepped(model, solver, state, dt, run_data, n_steps, saveat):
    return run(model, solver, state, dt, n_steps, saveat, None, run_data)


def compile_steps(model, solver, *, n_steps: int, dt, state=None, saveat: SaveAt = SaveAt()):
    """The steps of a run apart from what the run prepares once: ``solver.init``'s data (the kept
    interior factors, the frozen first-step factors) computed beforehand, then ``n_steps`` steps
    of ``dt`` from ``state`` (default the initial state) compiled ahead of time — the per-step
    cost of a solver.

    **Returns:** ``(steps, init_s)``: ``steps() -> (final_state, Trajectory)`` and the seconds of
    one ``solver.init`` (compiled; the best of two calls after the first)."""
    state = initial_state(model) if state is None else state
    dt = jnp.asarray(dt, dtype=model.ell.dtype)
    run_data = jax.block_until_ready(_init(model, solver, state, dt))
    init_s = min(clock(_init, model, solver, state, dt)[0] for _ in range(2))
    compiled = _stepped.lower(model, solver, state, dt, run_data, int(n_steps), saveat).compile()

    def steps():
        return compiled(model, solver, state, dt, run_data, int(n_steps), saveat)

    return steps, init_s


def warm_best(f, *, repeat: int = 5, budget_s: float = 0.5):
    """``(result, seconds, first seconds)`` of ``f()`` with its outputs ready: the first call
    timed apart (compilation included), then the fastest of up to ``repeat`` calls, fewer once
    ``budget_s`` is spent (a long run is timed once; short ones are not at the mercy of one
    scheduler hiccup). ``repeat=0``: the first call alone (work done once, such as an error
    estimate), its seconds returned as both."""
    first, out = clock(f)
    if repeat < 1:
        return out, first, first
    times = []
    while len(times) < repeat and sum(times) < budget_s:
        t, out = clock(f)
        times.append(t)
    return out, min(times), first
