"""The time loop's layout (``jaxbelt.loop_plan.loop_plan``): every step taken once, the step traced
once whatever the run length and record interval, the records those of a plain step-by-step loop."""

import jax
import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt import timeloop
from jaxbelt.loop_plan import loop_plan
from helpers import scene_fixtures


@pytest.mark.parametrize("n,every,checkpoint", [(5000, 1, None), (57, 1, None), (17, 3, None), (17, 3, 1),
                                                (17, 3, 6), (17, 3, 0), (1100, 200, None), (10, 50, None),
                                                (0, 1, None), (7919, 1, None)])
def test_plan_takes_every_step_once_and_keeps_the_records(n, every, checkpoint):
    p = loop_plan(n, every, checkpoint)
    active = p.slots if p.active is None else int(p.active.sum())
    assert active == n and p.n_out == n // every
    assert p.n_chunks * p.records_per_chunk >= -(-n // every)
    if p.active is not None:  # padding only in the last chunk (and a partial last interval)
        assert p.active.shape == (p.n_chunks, p.records_per_chunk, p.n_sub, p.sub_steps)
        assert p.active[:-1].all() or every > 1
    if checkpoint is None and n > 1:  # chunks of ~√n steps: reverse-mode memory stays ~√n
        steps_per_chunk = p.records_per_chunk * p.n_sub * p.sub_steps if every <= n else p.sub_steps
        assert steps_per_chunk <= 2 * np.sqrt(n) + 2 or p.n_sub > 1
    if checkpoint == 0:
        assert p.n_chunks <= 1


def test_default_plan_of_the_100_s_run_pads_nothing():
    p = loop_plan(5000, 1)
    assert p.active is None and (p.n_chunks, p.records_per_chunk) == (100, 50)


loaded, model, dt = scene_fixtures("two-roller-1d-idle-translated")


@pytest.mark.parametrize("n,every,traces", [(56, 1, 1), (7, 1, 2), (17, 3, 2), (57, 1, 2), (40, 7, 2)])
def test_step_is_traced_once_whatever_the_length(model, dt, monkeypatch, n, every, traces):
    """Tracing ``run`` calls the step once in the loop body, and once more for its record's
    shapes where the loop pads or records every few steps: no remainder chunk, tail loop or
    separate recording step adds a copy to compile."""
    calls = []
    make_step = timeloop.make_step

    def counting(*args, **kw):
        step = make_step(*args, **kw)

        def counted(s):
            calls.append(1)
            return step(s)

        return counted

    monkeypatch.setattr(timeloop, "make_step", counting)
    saveat = jb.SaveAt(every=every)
    jax.make_jaxpr(lambda s: timeloop.run(model, jb.DirectBackwardEuler(), s, dt, n, saveat))(jb.initial_state(model))
    assert len(calls) == traces


def test_records_equal_a_step_by_step_loop(model, dt):
    """17 steps recorded every 3rd (a tail of 2 without a record, padded slots) with 2-step
    checkpoint chunks: the records and the final state are those of 17 single steps."""
    integ = jb.DirectBackwardEuler()
    s = jb.initial_state(model)
    final, tr = jax.jit(lambda s: timeloop.run(model, integ, s, dt, 17, jb.SaveAt(every=3), 2))(s)
    step = jax.jit(timeloop.make_step(model, integ, dt))
    recs = []
    for k in range(17):
        s, rec = step(s)
        if (k + 1) % 3 == 0:
            recs.append(rec)
    assert tr.t.shape == (5,)
    np.testing.assert_array_equal(np.asarray(tr.t), np.asarray([r["t"] for r in recs]))
    np.testing.assert_allclose(np.asarray(tr.tracer_u), np.stack([r["tracer_u"] for r in recs]), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(np.asarray(tr.roller_reaction), np.stack([r["roller_reaction"] for r in recs]),
                               rtol=1e-10, atol=1e-12)
    for a, b in zip(jax.tree.leaves(final), jax.tree.leaves(s)):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-12, atol=1e-15)
    assert int(final.step) == 17
