"""Why the Thomas sweeps' pace is set by the blocks they stream, not by the chain's latency.

A sweep ``y_t = g_t - P_t y_{t-1}`` over ``steps`` dependent steps of ``chains`` independent
(36 × 36) block products (the chained sweeps of ``three-roller-t72``: 3 chains of up to 37
steps), each variant jit-compiled in a ``lax.scan`` and timed best of 3 × 15 calls of 500
sweeps:

- the blocks streamed (every step its own blocks, as a solve reads its factors);
- the same block at every step (it stays in cache): the same arithmetic and dependencies;
- the chains split in two and swept from both ends (twice the chains, half the steps: a
  twisted factorisation's shape) — the same blocks streamed;
- twice the dependent steps with the same chains;
- an elementwise update instead of the block product (the scan's own overhead).

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/sweep_streaming.py``. Writes
``results/sweep_streaming.json``.
"""

import time

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from _common import write

jax.config.update("jax_enable_x64", True)


def per_sweep_us(body, xs, y0, inner=500, repeat=15, rounds=3):
    def sweep(c):
        _, ys = lax.scan(body, c, xs)
        return c + 1e-30 * jnp.sum(ys)

    f = jax.jit(lambda c: lax.scan(lambda c, _: (sweep(c), None), c, None, length=inner)[0])
    jax.block_until_ready(f(y0))
    best = float("inf")
    for _ in range(rounds * repeat):
        t0 = time.perf_counter()
        jax.block_until_ready(f(y0))
        best = min(best, time.perf_counter() - t0)
    return best / inner * 1e6


def main():
    rng = np.random.default_rng(0)
    b = 36

    def streamed(steps, chains):
        P = jnp.asarray(rng.normal(size=(steps, chains, b, b)) * 0.01)
        g = jnp.asarray(rng.normal(size=(steps, chains, b, 1)))
        return per_sweep_us(lambda y, blk: (blk[1] - blk[0] @ y,) * 2, (P, g), jnp.zeros((chains, b, 1)))

    P0 = jnp.asarray(rng.normal(size=(3, b, b)) * 0.01)
    g = jnp.asarray(rng.normal(size=(37, 3, b, 1)))
    rows = {
        "37 steps x 3 chains, blocks streamed": streamed(37, 3),
        "37 steps x 3 chains, one block in cache": per_sweep_us(lambda y, gg: (gg - P0 @ y,) * 2, g, jnp.zeros((3, b, 1))),
        "18 steps x 6 chains (two-ended), blocks streamed": streamed(18, 6),
        "74 steps x 3 chains, blocks streamed": streamed(74, 3),
        "37 steps x 3 chains, elementwise update only": per_sweep_us(lambda y, gg: (gg - 0.5 * y,) * 2, g,
                                                                     jnp.zeros((3, b, 1))),
    }
    for k, v in rows.items():
        print(f"{k:55s} {v:7.1f} µs per sweep")
    write("sweep_streaming", {"block": b, "us_per_sweep": rows})


if __name__ == "__main__":
    main()
