"""The full-order step as a map on scaled first-order states (:mod:`jaxbelt.rom.full_steps`) on a
coarse idle-translated 1D belt, against the time loop's own recorded snapshots
(:func:`jaxbelt.rom.snapshots.collect_first_order`): ``F`` takes each post-transport snapshot to the
next (and each pre-transport one to the next with ``order="pre"``), ``F²`` two ahead, batched rows
alike; its Jacobian-vector products against central differences; the chunked evaluation against
one call on the whole array."""

import jax.numpy as jnp
import numpy as np
import pytest

from jaxbelt.rom.full_steps import apply_steps, full_step_map, in_chunks, jvp_columns, jvp_one, run_data_at_start
from jaxbelt.rom.snapshots import collect_first_order
from helpers import load, scene_with

N_STEPS = 4


@pytest.fixture(scope="module")
def machine():
    model, options = load(scene_with(lambda d: d["mesh"].update(roller_elements=[5, 5], free_elements=[6, 6]),
                                     "two-roller-1d-idle-translated"))
    options = options.replace(n_steps=N_STEPS)
    _, Z_pre, Z_post = collect_first_order(model, options)
    run_data = run_data_at_start(model, options.solver, options.dt)
    return model, options, np.asarray(Z_pre), np.asarray(Z_post), run_data


def _close(a, b):
    np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-9, atol=1e-12 * np.abs(np.asarray(b)).max())


def test_one_step_takes_each_post_transport_snapshot_to_the_next(machine):
    model, opts, _, Z, run_data = machine
    out = apply_steps(model, opts.dt, opts.solver, "post", 1, jnp.asarray(Z[:, :-1].T), run_data)
    assert np.abs(Z[:, 1:] - Z[:, :-1]).max() > 1e-6  # the states move: the check can fail
    _close(out.T, Z[:, 1:])


def test_two_steps_reach_two_snapshots_ahead(machine):
    model, opts, _, Z, run_data = machine
    out = apply_steps(model, opts.dt, opts.solver, "post", 2, jnp.asarray(Z[:, :-2].T), run_data)
    _close(out.T, Z[:, 2:])


def test_pre_transport_order_transports_then_solves(machine):
    model, opts, Z_pre, _, run_data = machine
    out = apply_steps(model, opts.dt, opts.solver, "pre", 1, jnp.asarray(Z_pre[:, :-1].T), run_data)
    _close(out.T, Z_pre[:, 1:])


def test_an_unknown_order_is_refused(machine):
    model, opts, *_ = machine
    with pytest.raises(ValueError, match="order must be 'post' or 'pre'"):
        full_step_map(model, opts.dt, opts.solver, order="mid")


def test_jacobian_products_equal_central_differences(machine):
    model, opts, _, Z, run_data = machine
    z = jnp.asarray(Z[:, 2])
    rng = np.random.default_rng(0)
    V = rng.standard_normal((Z.shape[0], 2)) * np.abs(Z).max(axis=1, keepdims=True) + 1e-9
    JV = np.asarray(jvp_columns(model, opts.dt, opts.solver, "post", 1, z, jnp.asarray(V), run_data))
    h = 1e-4
    pts = np.concatenate([np.asarray(z)[:, None] + h * V, np.asarray(z)[:, None] - h * V], axis=1).T
    F = np.asarray(apply_steps(model, opts.dt, opts.solver, "post", 1, jnp.asarray(pts), run_data))
    fd = ((F[:2] - F[2:]) / (2 * h)).T
    np.testing.assert_allclose(JV, fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())
    Jv = jvp_one(model, opts.dt, opts.solver, "post", 1, z, jnp.asarray(V[:, 1]), run_data)
    np.testing.assert_allclose(np.asarray(Jv), JV[:, 1], rtol=1e-12, atol=1e-15 * np.abs(JV).max())


@pytest.mark.parametrize("axis,chunk", [(0, 3), (0, 7), (1, 2), (1, 5)])
def test_chunks_equal_one_call_and_compile_one_shape(axis, chunk):
    X = np.arange(35.0).reshape(7, 5) if axis == 0 else np.arange(35.0).reshape(5, 7)
    shapes = []

    def fn(part):
        shapes.append(part.shape)
        return jnp.cumsum(part ** 2, axis=1 - axis)  # acts within each row (axis 0) or column (axis 1)

    out = in_chunks(fn, X, chunk, axis)
    assert isinstance(out, np.ndarray)
    np.testing.assert_array_equal(out, np.cumsum(X ** 2, axis=1 - axis))
    assert len(shapes) == -(-7 // chunk) and len(set(shapes)) == 1
    assert shapes[0][axis] == chunk


def test_no_columns_give_an_empty_result_of_the_outputs_shape():
    out = in_chunks(lambda part: jnp.concatenate([part, part], axis=0), np.zeros((3, 0)), 4, 1)
    assert isinstance(out, np.ndarray) and out.shape == (6, 0)
