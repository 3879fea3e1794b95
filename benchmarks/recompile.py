"""Does another time step or misalignment compile again? First call vs. later calls of ``simulate``.

``jb.simulate`` traces ``dt`` and the model's arrays, so a second call on the same model with
another ``dt``, or on a model with another misalignment, should run the program compiled by the
first call. Measured per scene: the first call (trace + compile + run), then a call with ``dt``
scaled by 0.9, then one with a roller tilted (2D) or translated (1D), each the best of three,
and the number of XLA compilations each made (JAX's monitoring events). The contract: each
later call takes at most 15 % of the first and compiles nothing.

    OPENBLAS_NUM_THREADS=1 python benchmarks/recompile.py     # -> results/recompile.json
"""

import time

import jax
import jax.numpy as jnp

import jaxbelt as jb
from _common import write

jb.enable_x64()

COMPILES = []
jax.monitoring.register_event_duration_secs_listener(
    lambda name, secs, **kw: COMPILES.append(name) if name == "/jax/core/compile/backend_compile_duration" else None)


def timed_call(model, opts):
    n0 = len(COMPILES)
    t0 = time.perf_counter()
    state, _ = jb.simulate(model, **opts)
    jax.block_until_ready(state.u)
    return time.perf_counter() - t0, len(COMPILES) - n0


def case(name, n_steps):
    scene = jb.load_scene(name)
    model = jb.build_model(scene)
    opts = jb.RunOptions.from_scene(scene).replace(n_steps=n_steps)
    first, first_compiles = timed_call(model, opts)
    other_dt = [timed_call(model, opts.replace(dt=0.9 * opts.dt)) for _ in range(3)]
    if model.kind == "2d":
        tilted = jb.with_misalignment(model, rotation=jnp.zeros((model.n_rollers, 3)).at[1, 1].set(1e-4))
    else:
        tilted = jb.with_misalignment(model, translation=jnp.zeros(model.n_rollers).at[1].set(1e-4))
    other_mis = [timed_call(tilted, opts) for _ in range(3)]
    row = dict(n_steps=n_steps, first_s=first, first_compiles=first_compiles,
               other_dt_s=min(t for t, _ in other_dt), other_dt_compiles=max(c for _, c in other_dt),
               other_misalignment_s=min(t for t, _ in other_mis),
               other_misalignment_compiles=max(c for _, c in other_mis))
    row["other_dt_ratio"] = row["other_dt_s"] / first
    row["other_misalignment_ratio"] = row["other_misalignment_s"] / first
    row["contract_met"] = bool(row["other_dt_ratio"] <= 0.15 and row["other_misalignment_ratio"] <= 0.15
                               and row["other_dt_compiles"] == 0 and row["other_misalignment_compiles"] == 0)
    print(name, row)
    return row


if __name__ == "__main__":
    rows = {"two-roller-1d": case("two-roller-1d", 1000), "three-roller": case("three-roller", 500)}
    write("recompile", {"cases": rows, "contract_met": all(r["contract_met"] for r in rows.values())})
