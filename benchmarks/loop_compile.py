"""Compile time and per-step cost of the time loop's layout (``jaxbelt.timeloop.loop_plan``)
against the layout it replaced, side by side in one process.

The replaced layout (kept here as ``_run_remainder_and_tail``) ran a remainder chunk and a
tail loop as scans of their own and, with ``every > 1``, a separate recording step: up to four
copies of the step in one program. The plan's layout traces the step once and pads the last
chunk with slots that branch around it. Measured on the coarse three-roller scene (n_eta = 3,
exact solver: compile) and on ``three-roller-t72`` (reuse solver: per step, best of 5, the two
layouts interleaved), XLA's default flags, ``OPENBLAS_NUM_THREADS=1``.
Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/loop_compile.py`` (~2 min); writes
``results/loop_compile.json``.
"""

import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
from jax import lax

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from _common import write  # noqa: E402

jax.config.update("jax_enable_x64", True)
import jaxbelt as jb  # noqa: E402
from jaxbelt import timeloop  # noqa: E402


def _checkpointed_scan(body, carry, length, chunk):
    if length <= chunk:
        return lax.scan(body, carry, None, length=length)

    def part(k, in_scan):
        return jax.checkpoint(lambda c: lax.scan(body, c, None, length=k), prevent_cse=not in_scan)

    n_chunks, rem = divmod(length, chunk)
    carry, ys = lax.scan(lambda c, _: part(chunk, True)(c), carry, None, length=n_chunks)
    ys = jax.tree.map(lambda a: a.reshape(n_chunks * chunk, *a.shape[2:]), ys)
    if rem:
        carry, ys_rem = part(rem, False)(carry)
        ys = jax.tree.map(lambda a, b: jnp.concatenate([a, b]), ys, ys_rem)
    return carry, ys


def _run_remainder_and_tail(model, integrator, state, n_steps):
    """The layout before ``loop_plan`` (jaxbelt 598e671): remainder chunk, tail loop, advance steps."""
    step = timeloop.make_step(model, integrator)
    every = model.every
    n_out, tail = divmod(n_steps, every)
    chunk = timeloop.default_checkpoint_chunk(n_steps)
    advance = lambda s, _: (step(s)[0], None)

    def record(s, _):
        s = _checkpointed_scan(advance, s, every - 1, chunk)[0] if every > 1 else s
        return step(s)

    state, rec = _checkpointed_scan(record, state, n_out, max(1, chunk // every))
    if tail:
        state = _checkpointed_scan(advance, state, tail, chunk)[0]
    return state, rec


def compile_s(run, model, integ, state, n):
    f = jax.jit(lambda m, s: run(m, integ, s, n))
    t = time.perf_counter()
    f.lower(model, state).compile()
    return time.perf_counter() - t


def main():
    from helpers import scene_with

    coarse = jb.compile_scene(scene_with(lambda d: d["mesh"].update(n_eta=3), "three-roller"))
    integ = jb.make_integrator("direct", coarse)
    s0 = jb.initial_state(coarse)
    compile_rows = []
    for every, n in [(1, 56), (1, 57), (1, 1001), (5, 503)]:
        m = coarse.replace(every=every)
        old = min(compile_s(_run_remainder_and_tail, m, integ, s0, n) for _ in range(2))
        new = min(compile_s(timeloop.run, m, integ, s0, n) for _ in range(2))
        plan = timeloop.loop_plan(n, every)
        compile_rows.append({"every": every, "n_steps": n, "padded": plan.active is not None,
                             "compile_s_remainder_and_tail": round(old, 3), "compile_s_plan": round(new, 3)})
        print(compile_rows[-1])

    t72 = jb.load_model("three-roller-t72")
    integ = jb.make_integrator("direct", t72, "reuse")
    s0 = jb.initial_state(t72)
    step_rows = []
    for n in (1000, 1001):
        fns = {k: jax.jit(lambda m, s, r=r: r(m, integ, s, n)).lower(t72, s0).compile()
               for k, r in (("remainder_and_tail", _run_remainder_and_tail), ("plan", timeloop.run))}
        best = dict.fromkeys(fns, float("inf"))
        for _ in range(5):
            for k, c in fns.items():
                t = time.perf_counter()
                jax.block_until_ready(c(t72, s0))
                best[k] = min(best[k], time.perf_counter() - t)
        step_rows.append({"n_steps": n, "padded": timeloop.loop_plan(n, 1).active is not None,
                          **{f"ms_per_step_{k}": round(v * 1e3 / n, 4) for k, v in best.items()}})
        print(step_rows[-1])
    write("loop_compile", {"compile_coarse_three_roller": compile_rows, "per_step_three_roller_t72_reuse": step_rows})


if __name__ == "__main__":
    main()
