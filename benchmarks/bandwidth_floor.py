"""The floor of a batched full-model step: the bytes it must stream against the memory bandwidth.

With the reuse solver and the shift transport (no lateral transport), a step's linear solve is
one forward and back substitution with the first step's factors, which are per configuration
(each configuration's own misalignment), so in a batch of configurations nothing is shared and
every step streams every configuration's factors once. The floor counts those bytes
(the linear solver's run data from the integrator's ``init``) plus the step's state (read and
written; the free belt's stiffness stencil carries no misalignment, so the batch shares it and it
is left out), and divides by the read bandwidth measured in the same process (the sum of a 512 MiB
array, best of five) — the time a step cannot beat on this machine. Against it: the measured
time per configuration-step of :func:`jaxbelt.design.evaluate_configs` (the sweep's path) on the
design scene ``three-roller-tolerance`` (N = 3762) for batches of 1, 8 and 32 configurations over
200 steps (the first step's factorisation amortised over them; compilation apart; best of
three). The substitution alone (``factor_solve``, ``vmap`` over a
batch of factor sets) is timed against its own bytes likewise, and so is the recurrence of one
of its sweeps on its own (synthetic blocks of the design scene's shape). A compute floor is given beside it: the multiply-adds a substitution does (two per factor
entry) at the rate of a large ``matmul``, measured likewise.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/bandwidth_floor.py``. Writes
``results/bandwidth_floor.json``.
"""

import time

import jax
import jax.numpy as jnp
import numpy as np
from _common import write

import jaxbelt as jb
from jaxbelt import design
from jaxbelt.linalg.bordered import factor_solve
from jaxbelt.state import initial_state

SCENE, STEPS, BATCHES = "three-roller-tolerance", 200, (1, 8, 32)


def best_of(f, repeat=5):
    jax.block_until_ready(f())
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        jax.block_until_ready(f())
        best = min(best, time.perf_counter() - t0)
    return best


rng0 = np.random.default_rng(1)


@jax.jit
def sweep(P, g):
    """``y_i = g_i - P_i y_{i-1}`` along the steps (the chained Thomas sweep's recurrence)."""
    def body(y, blk):
        Pi, gi = blk
        y = gi - jnp.einsum("...ij,...j->...i", Pi, y)
        return y, y

    return jax.lax.scan(body, jnp.zeros(g.shape[1:], g.dtype), (P, g))[1]


def nbytes(tree):
    return int(sum(x.size * x.dtype.itemsize for x in jax.tree.leaves(tree) if hasattr(x, "dtype")))


def main():
    jb.enable_x64()
    x = jnp.ones(64 * 2**20)  # 512 MiB of float64
    total = jax.jit(jnp.sum)
    read_gb_s = x.nbytes / best_of(lambda: total(x)) / 1e9
    a = jnp.ones((2048, 2048))
    mm = jax.jit(lambda a: a @ a)
    gflop_s = 2 * 2048**3 / best_of(lambda: mm(a)) / 1e9
    x = None  # free the 512 MiB

    sc = jb.load_scene(SCENE)
    model, opts = jb.build_model(sc), jb.RunOptions.from_scene(sc)
    solver = jb.DirectBackwardEuler(jb.Reuse())
    state = initial_state(model)
    dt = jnp.asarray(opts.dt)
    run_data = solver.init(model, state, dt)
    factor_bytes, state_bytes = nbytes(run_data.linear), nbytes(state)
    stencil_bytes = nbytes(run_data.stencil)  # the free belt's stiffness: shared by the batch (no misalignment in it)
    step_bytes = factor_bytes + 2 * state_bytes
    floor_ms = 1e3 * step_bytes / (read_gb_s * 1e9)
    compute_ms = 1e3 * (2 * factor_bytes / 8) / (gflop_s * 1e9)
    # the substitution alone, one and a batch of factor sets, against its own bytes
    F = run_data.linear.F
    rb = jnp.ones((model.n_xi, model.block))
    rr = jnp.ones(model.n_roller_dofs)
    solve_rows = []
    for b in BATCHES:
        Fb = jax.tree.map(lambda a: jnp.stack([a] * b) if hasattr(a, "dtype") else a, F)
        go = jax.jit(jax.vmap(lambda F, r, q: factor_solve(F, r, q)))
        rbb, rrb = jnp.stack([rb] * b), jnp.stack([rr] * b)
        ms = 1e3 * best_of(lambda: go(Fb, rbb, rrb)) / b
        solve_floor = 1e3 * nbytes(F) / (read_gb_s * 1e9)
        solve_rows.append(dict(batch=b, solve_ms=ms, solve_floor_ms=solve_floor, over_floor=ms / solve_floor))
        print(solve_rows[-1], flush=True)
    # one forward sweep's dependent chain alone (synthetic: 37 steps of 3 chains of 36 x 36 blocks,
    # the interior sweep's shape on the design scene), a batched matrix-vector product per step
    sweep_rows = []
    for b in BATCHES:
        P = jnp.asarray(rng0.random((37, b, 3, 36, 36)))
        g = jnp.asarray(rng0.random((37, b, 3, 36)))
        ms = 1e3 * best_of(lambda: sweep(P, g)) / b
        floor = 1e3 * P.nbytes / b / (read_gb_s * 1e9)
        sweep_rows.append(dict(batch=b, sweep_ms=ms, sweep_floor_ms=floor, over_floor=ms / floor))
        print(sweep_rows[-1], flush=True)
    study = design.make_study(model, "lateral_max", opts.replace(solver=solver, n_steps=STEPS))
    rng = np.random.default_rng(0)
    rows = []
    for b in BATCHES:
        thetas = 0.01 * rng.standard_normal((b, study.space.size))
        t = best_of(lambda: design.evaluate_configs(study, thetas, chunk=b), repeat=3)
        ms = 1e3 * t / (b * STEPS)
        rows.append(dict(batch=b, ms_per_config_step=ms, over_bandwidth_floor=ms / floor_ms,
                         over_compute_floor=ms / compute_ms))
        print(rows[-1], flush=True)
    write("bandwidth_floor", dict(
        scene=SCENE, n_unknowns=int(model.n_unknowns), steps=STEPS, solver="direct/reuse",
        refinement=int(jb.Reuse().iterations(model, "shift")), read_bandwidth_gb_s=read_gb_s, matmul_gflop_s=gflop_s,
        factor_bytes=factor_bytes, state_bytes=state_bytes, stencil_bytes_shared=stencil_bytes,
        bytes_per_config_step=step_bytes,
        bandwidth_floor_ms=floor_ms, compute_floor_ms=compute_ms, rows=rows, solve_rows=solve_rows, sweep_rows=sweep_rows))
    print(f"floor: {step_bytes / 2**20:.2f} MiB a configuration-step at {read_gb_s:.1f} GB/s = {floor_ms:.3f} ms; "
          f"compute {compute_ms:.3f} ms at {gflop_s:.1f} GFLOP/s", flush=True)


if __name__ == "__main__":
    main()
