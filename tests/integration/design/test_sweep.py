"""The sweep store (jaxbelt.design.sweep): a sweep resumes and extends its store."""

import jax.numpy as jnp
import numpy as np
import pytest

from jaxbelt import design
from jaxbelt.infra.store import load_sweep


def test_sweep_store_resumes_and_extends(study, tmp_path, dist, chunk):
    limit = 1.1 * float(design.metric_value(study, jnp.zeros(4)))
    out = tmp_path / "sweep.zarr"
    first = design.run_sweep(study, dist, 8, limit, chunk=chunk, out=out, with_form=False)
    again = design.run_sweep(study, dist, 16, limit, chunk=chunk, out=out, with_form=False)
    fresh = design.run_sweep(study, dist, 16, limit, chunk=chunk, with_form=False)
    np.testing.assert_allclose(again.metric_values, fresh.metric_values, rtol=1e-12)
    np.testing.assert_allclose(again.metric_values[:8], first.metric_values, rtol=1e-12)
    ds = load_sweep(out)
    assert ds.sizes["config"] == 16 and ds.sizes["tracer"] == study.ref_u.shape[1]
    with pytest.raises(ValueError, match="another sweep"):
        design.run_sweep(study, dist, 8, 2 * limit, chunk=chunk, out=out, with_form=False)

