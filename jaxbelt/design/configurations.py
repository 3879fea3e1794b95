"""A study's question at many configurations at once: :func:`at_configurations` (any function of
a configuration's deviations) and :func:`evaluate_configs` (everything a sweep stores per
configuration, :func:`jaxbelt.design.study.evaluate`), the one way every design command — a sweep's
samples, a surrogate's training and validation runs, a tolerance box's verification — evaluates
a study at a batch of configurations.

A time-stepped study's runs are one ``vmap`` batch. A steady study's solves are not batched inside
a program: each configuration is one call of the single steady solve's compiled program
(:func:`jaxbelt.steady.steady_states`), between two small batched programs — the starts
(each configuration's misalignment and its linear prediction of the steady state) before, the
deviations and whatever is read from them after. So the Newton–GMRES program of a scene is
compiled once, whichever command and whichever question asks for solves (the aligned machine,
a box's corners, a sweep's samples), instead of once more inside every batch that holds it.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..infra.programs import stored_jit
from ..infra.sharding import batched_map
from ..steady import steady_states
from .study import Study, evaluate, evaluate_deviation, run_deviation, steady_deviation, steady_start

STEADY_CHUNK = 4  # steady solves per block (they run in sequence: a block only bounds the padding)


@stored_jit
def _steady_inputs(study: Study, thetas):
    """Each row's misalignment vector ``chi_static`` and the start of its steady solve."""
    return jax.vmap(lambda t: (study.configured(t).chi_static, steady_start(study, t)))(thetas)


@stored_jit
def _from_steady(study: Study, states, from_deviation):
    return jax.vmap(lambda s: from_deviation(study, *steady_deviation(study, s)))(states)


@stored_jit
def _from_runs(study: Study, thetas, from_deviation):
    return jax.vmap(lambda t: from_deviation(study, *run_deviation(study, t)))(thetas)


def at_configurations(study: Study, thetas, from_deviation):
    """``from_deviation(study, d_u, d_v, angle)`` (a module-level function of a configuration's
    deviations, :func:`jaxbelt.design.study.run_deviation`) at every row of ``thetas`` (m, P):
    its outputs with a leading axis m. A steady study's solves run one compiled solve per row
    (module docstring), a time-stepped study's runs as one ``vmap`` batch."""
    thetas = jnp.asarray(thetas, study.base.dtype).reshape(-1, study.space.size)
    if not study.steady:
        return _from_runs(study, thetas, from_deviation)
    chis, starts = _steady_inputs(study, thetas)
    states = steady_states(study.model, study.options.solver, dt=study.options.dt, chis=chis, y0s=starts,
                           period_steps=study.period_steps)
    return _from_steady(study, states, from_deviation)


def evaluate_configs(study: Study, thetas, chunk: int | None = None, progress=None):
    """Full-model :func:`jaxbelt.design.study.evaluate` for every row of ``thetas`` (n, P),
    ``chunk`` configurations at a time, ``progress(done, chunk_result)`` called after each chunk.
    The rows are padded to a whole number of chunks (:func:`padded_rows`), so every call with the
    same ``chunk`` reuses one compilation: a time-stepped study's chunks are ``vmap`` batches
    sharded over the local devices (:func:`~jaxbelt.infra.sharding.batched_map`); a steady study's
    solves run one after another, one compiled solve per row (:func:`_steady_chunks`), where a
    padded row costs a whole solve, so its chunk is at most :data:`STEADY_CHUNK`.

    **Returns:** dict of numpy arrays with leading axis n."""
    thetas = np.asarray(thetas, float).reshape(-1, study.space.size)
    if study.steady:
        chunk = min(chunk or STEADY_CHUNK, STEADY_CHUNK)
    n = thetas.shape[0]
    if chunk is not None:
        thetas = padded_rows(thetas, chunk)
    if study.steady:
        out = _steady_chunks(study, thetas, chunk or len(thetas), progress)
    else:
        out = batched_map(evaluate, thetas, chunk=chunk, progress=progress, operand=study)
    return jax.tree.map(lambda a: a[:n], out)


def padded_rows(rows, chunk: int) -> np.ndarray:
    """``rows`` (n, …) with the last row repeated up to a whole number of ``chunk``-row blocks, so
    that every block of a batched evaluation has one shape: one compilation (no rows: none)."""
    rows = np.asarray(rows)
    return np.concatenate([rows, np.repeat(rows[-1:], -len(rows) % chunk, axis=0)]) if len(rows) else rows


def _steady_chunks(study, thetas, chunk, progress=None):
    """A steady study's :func:`jaxbelt.design.study.evaluate` at the rows of ``thetas``, ``chunk``
    rows at a time (:func:`at_configurations`: one compiled solve per row),
    ``progress(done, chunk_result)`` after each chunk."""
    parts = []
    for start in range(0, max(len(thetas), 1), chunk):  # (no configuration: one empty part)
        part = jax.tree.map(np.asarray, at_configurations(study, thetas[start:start + chunk], evaluate_deviation))
        parts.append(part)
        if progress is not None:
            progress(start + len(thetas[start:start + chunk]), part)
    return jax.tree.map(lambda *a: np.concatenate(a), *parts)


def evaluate_metric(study: Study, thetas, chunk: int | None = None):
    """The metric (n,) at every row of ``thetas`` (n, P) (full model, batched: :func:`evaluate_configs`)."""
    return np.asarray(evaluate_configs(study, thetas, chunk)["metric"])
