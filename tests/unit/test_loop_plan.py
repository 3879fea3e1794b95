"""The nested-scan bookkeeping of :mod:`jaxbelt.loop_plan` against a plain step-by-step loop: walking
the plan's slots in scan order takes steps ``1 … n`` in order and records after steps ``every, 2 every,
…``; the default chunk is ``⌈√n⌉`` (integer arithmetic), an explicit chunk is kept, and the two
helpers (``checkpointed``, ``scan_or_inline``) change neither values nor gradients."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax import lax

from jaxbelt.loop_plan import checkpointed, default_checkpoint_chunk, loop_plan, scan_or_inline


def _walk(plan):
    """Emulate the nested scans: ``(steps taken, step count at the end of each record group)``."""
    taken, at_records, k = [], [], 0
    for c in range(plan.n_chunks):
        for r in range(plan.records_per_chunk):
            for s in range(plan.n_sub):
                for j in range(plan.sub_steps):
                    if plan.active is None or plan.active[c, r, s, j]:
                        k += 1
                        taken.append(k)
            at_records.append(k)
    return taken, at_records


@pytest.mark.parametrize("n", [0, 1, 2, 3, 4, 5, 9, 10, 99, 100, 101, 4999, 5000, 5001, 10 ** 6])
def test_default_chunk_is_the_ceiling_of_the_square_root(n):
    c = default_checkpoint_chunk(n)
    assert c == max(1, math.ceil(math.sqrt(n)))
    assert c * c >= n and (c - 1) ** 2 < max(n, 1)


@pytest.mark.parametrize("checkpoint", [None, 0, 1, 2, 5, 7])
def test_walking_the_plan_equals_a_plain_loop_with_records_every_interval(checkpoint):
    """Every ``(n, every)`` with ``n ≤ 40``, ``every ≤ 9``: steps taken once each in order, the
    first ``n_out`` record groups end right after steps ``every, 2·every, …``."""
    for n in range(0, 41):
        for every in range(1, 10):
            p = loop_plan(n, every, checkpoint)
            taken, at_records = _walk(p)
            assert taken == list(range(1, n + 1)), (n, every, checkpoint)
            assert p.n_out == n // every
            assert at_records[:p.n_out] == [every * (g + 1) for g in range(p.n_out)], (n, every, checkpoint)


def test_active_mask_has_the_nested_shape_and_is_none_only_without_padding():
    for n, every, checkpoint in [(17, 3, None), (17, 3, 2), (10, 50, None), (57, 1, None), (100, 1, None)]:
        p = loop_plan(n, every, checkpoint)
        if p.active is None:
            assert p.slots == n
        else:
            assert p.active.shape == (p.n_chunks, p.records_per_chunk, p.n_sub, p.sub_steps)
            assert p.active.dtype == bool and int(p.active.sum()) == n < p.slots


@pytest.mark.parametrize("n,every,checkpoint", [(100, 1, 7), (100, 2, 7), (90, 3, 10), (90, 5, 5)])
def test_explicit_chunk_is_kept_in_whole_record_intervals(n, every, checkpoint):
    p = loop_plan(n, every, checkpoint)
    assert p.n_sub == 1 and p.sub_steps == every
    assert p.records_per_chunk == checkpoint // every
    assert p.n_chunks == -(-(-(-n // every)) // (checkpoint // every))


def test_record_interval_longer_than_a_chunk_is_split_into_sub_chunks():
    p = loop_plan(60, 20, 6)  # intervals of 20 steps, chunks of 6: 4 sub-chunks of 6 (the last one 2 steps)
    assert (p.n_chunks, p.records_per_chunk, p.n_sub, p.sub_steps) == (3, 1, 4, 6)
    assert int(p.active.sum()) == 60 and p.active[:, 0, -1].sum(axis=-1).tolist() == [2, 2, 2]
    q = loop_plan(60, 20)  # default chunk ⌈√60⌉ = 8; the divisors of 20 within [4, 16] are 4, 5, 10: 10 is nearest
    assert (q.n_sub, q.sub_steps) == (2, 10) and q.active is None


def test_default_plan_divides_the_records_into_whole_chunks_where_a_divisor_is_near():
    """5000 steps: ⌈√5000⌉ = 71, 5000 has the divisor 50 within [36, 142] (nearest to 71 is 50), so
    no slot is padded; 7919 (prime) has no divisor there, so the last chunk is padded."""
    p = loop_plan(5000, 1)
    assert p.active is None and p.records_per_chunk * p.n_chunks == 5000
    divisors = [d for d in range(36, 143) if 5000 % d == 0]
    assert p.records_per_chunk == min(divisors, key=lambda d: abs(d - 71))
    q = loop_plan(7919, 1)
    assert q.records_per_chunk == default_checkpoint_chunk(7919) and q.active is not None


def test_checkpointed_keeps_the_value_and_the_gradient():
    f = lambda x: jnp.sum(jnp.sin(x) * x ** 2)  # noqa: E731
    x = jnp.linspace(-1.0, 2.0, 7)
    assert checkpointed(f, False) is f
    g = checkpointed(f, True)
    np.testing.assert_allclose(float(g(x)), float(f(x)), rtol=1e-15)
    analytic = np.cos(np.asarray(x)) * np.asarray(x) ** 2 + 2 * np.asarray(x) * np.sin(np.asarray(x))
    np.testing.assert_allclose(np.asarray(jax.grad(g)(x)), analytic, rtol=1e-13)


@pytest.mark.parametrize("length", [1, 3])
def test_scan_or_inline_equals_lax_scan(length):
    def body(c, x):
        return c * 2.0 + x, {"c": c, "x": x}

    xs = jnp.arange(1.0, length + 1.0)
    got = scan_or_inline(body, jnp.asarray(0.5), xs, length)
    ref = lax.scan(body, jnp.asarray(0.5), xs, length=length)
    for a, b in zip(jax.tree.leaves(got), jax.tree.leaves(ref)):
        assert a.shape == b.shape
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    c, ys = scan_or_inline(lambda c, x: (c + 1.0, c), jnp.asarray(0.0), None, length)
    assert float(c) == length and np.asarray(ys).tolist() == list(range(length))
