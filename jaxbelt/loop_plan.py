"""How the time loop lays a run out as nested scans: checkpointed chunks, record intervals, steps.

:func:`loop_plan` is pure bookkeeping on static integers (no arrays of the run): which slots of
the nested scans take a step and which records are the run's. The step appears once in the
compiled program whatever the run's length; :func:`jaxbelt.timeloop.run` follows the plan.
"""

from __future__ import annotations

import dataclasses
import math

import jax
import numpy as np
from jax import lax


def checkpointed(f, on: bool):
    """``f`` under ``jax.checkpoint`` where ``on`` (a chunk of a longer loop); inside a scan XLA
    cannot CSE the recomputation away, so ``prevent_cse`` stays off."""
    return jax.checkpoint(f, prevent_cse=False) if on else f


def default_checkpoint_chunk(n_steps: int) -> int:
    """Steps per checkpointed chunk of :func:`jaxbelt.timeloop.run`: ``⌈√n⌉``, so reverse-mode memory grows as
    ``√n`` (``√n`` carries and ``√n`` steps' residuals), at the price of one extra forward pass.
    :func:`jaxbelt.timeloop.run` takes a divisor of the run's record count near it where there is one."""
    return max(1, math.isqrt(max(n_steps - 1, 0)) + 1)


def _near_divisor(n: int, target: int) -> int:
    """The divisor of ``n`` closest to ``target`` within ``[target/2, 2 target]``, else
    ``target``: a whole number of chunks needs no masked padding steps."""
    candidates = [d for d in range(max(1, (target + 1) // 2), 2 * target + 1) if n % d == 0]
    return min(candidates, key=lambda d: (abs(d - target), d)) if candidates else target


@dataclasses.dataclass(frozen=True)
class LoopPlan:
    """How :func:`jaxbelt.timeloop.run` lays ``n_steps`` steps out as nested scans (all static).

    ``n_chunks`` checkpointed chunks × ``records_per_chunk`` record groups × ``n_sub`` sub-chunks
    (checkpointed too where ``n_sub > 1``: a record interval longer than a chunk) × ``sub_steps``
    steps; ``active`` (same nested shape, bool) marks the slots that take a step — ``None`` when
    every slot does — the others pass the state through unchanged. The first ``n_out`` groups'
    records are the run's."""

    n_chunks: int
    records_per_chunk: int
    n_sub: int
    sub_steps: int
    n_out: int
    active: np.ndarray | None

    @property
    def slots(self) -> int:
        return self.n_chunks * self.records_per_chunk * self.n_sub * self.sub_steps


def loop_plan(n_steps: int, every: int, checkpoint: int | None = None) -> LoopPlan:
    """The nested-scan layout of a run of ``n_steps`` steps recording every ``every``-th.

    The step appears **once** in the compiled program, whatever ``n_steps``: instead of a
    remainder chunk and a tail loop (each a further copy of the step to compile), the last chunk
    is padded with slots that skip the step (``lax.cond``: at run time a skipped slot costs a
    branch; under ``vmap`` too, its predicate is not batched). With the default ``checkpoint``,
    the records per chunk are a divisor of the number of record groups near ``⌈√n⌉ / every`` where
    there is one (5000 steps: chunks of 50, none padded) — then nothing is padded and no slot
    branches. An explicit ``checkpoint`` is kept as given (rounded to whole record intervals where
    it is at least one)."""
    n_steps, every = int(n_steps), max(1, int(every))
    n_out = n_steps // every
    groups = -(-n_steps // every)  # the last one partial (a tail without a record) where every ∤ n
    chunk = default_checkpoint_chunk(n_steps) if checkpoint is None else (int(checkpoint) or max(n_steps, 1))
    if every <= chunk:
        n_sub, sub_steps = 1, every
        per = max(1, groups) if checkpoint == 0 else max(1, chunk // every)
        if checkpoint is None:
            per = _near_divisor(groups, per)
    else:  # a record interval longer than a chunk: the interval itself in checkpointed sub-chunks
        per = 1
        span = every if n_out else n_steps  # a run shorter than one interval: its steps only
        sub_steps = _near_divisor(span, chunk) if checkpoint is None else chunk
        n_sub = -(-span // sub_steps)
    n_chunks = -(-groups // per) if groups else 0
    shape = (n_chunks, per, n_sub, sub_steps)
    i_local = np.arange(n_sub * sub_steps).reshape(n_sub, sub_steps)
    g = np.arange(n_chunks * per).reshape(n_chunks, per)
    k = g[:, :, None, None] * every + i_local[None, None]
    active = (i_local[None, None] < every) & (k < n_steps)
    return LoopPlan(n_chunks=n_chunks, records_per_chunk=per, n_sub=n_sub, sub_steps=sub_steps, n_out=n_out,
                    active=None if bool(np.all(active)) else np.broadcast_to(active, shape).copy())


def scan_or_inline(body, carry, xs, length: int):
    """``lax.scan(body, carry, xs, length=length)``; a loop of one iteration is the body itself
    (no while loop to compile: the plan's levels are often one iteration long)."""
    if length != 1:
        return lax.scan(body, carry, xs, length=length)
    carry, y = body(carry, None if xs is None else xs[0])
    return carry, jax.tree.map(lambda a: a[None], y)
