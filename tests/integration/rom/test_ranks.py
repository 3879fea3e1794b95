"""One offline projection serves every rank: ``ReducedStep.truncate`` / ``fit_reduced_pod_ranks``."""

import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from helpers import load
from jaxbelt.rom import collect_first_order, fit_reduced_pod, fit_reduced_pod_ranks, parameters


@pytest.fixture(scope="module")
def training():
    m, opts = load("two-roller-1d-train1")
    _, Zp, Zq = collect_first_order(m, jb.RunOptions(jb.make_solver(), 150, opts.dt))  # the training run of test_rom_dmdc / test_rom_error_estimate
    Z = jnp.concatenate([Zp, Zq], axis=1)
    return m, opts.dt, Z, fit_reduced_pod_ranks(m, Z, (4, 12, 8), opts.dt)


def test_truncated_operators_equal_a_fit_at_that_rank(training):
    m, dt, Z, many = training
    assert sorted(many) == [4, 8, 12]
    for r in (4, 8):
        direct = fit_reduced_pod(m, Z, dt, n_modes=r)
        for name in ("A", "B", "d", "c", "Z", "G", "H", "h", "C_tracer", "basis"):
            a, b = np.asarray(getattr(many[r], name)), np.asarray(getattr(direct, name))
            assert a.shape == b.shape, name
            assert np.abs(a - b).max() <= 1e-10 * max(1.0, np.abs(b).max()), name
        xi0 = many[r].project(m, jb.initial_state(m))
        out_t = many[r].run(xi0, parameters(m), 50).tracer_u
        out_d = direct.run(direct.project(m, jb.initial_state(m)), parameters(m), 50).tracer_u
        assert float(jnp.max(jnp.abs(out_t - out_d))) < 1e-9


def test_truncate_rejects_ranks_out_of_range(training):
    rom = training[3][4]
    with pytest.raises(ValueError, match="outside"):
        rom.truncate(5)
    with pytest.raises(ValueError, match="outside"):
        rom.truncate(0)
