"""The tolerance box of a study, verified by full runs (jaxbelt.design.tolerance)."""

import numpy as np
from helpers import load

from jaxbelt import design


def test_box_on_the_default_scene_is_verified_by_full_runs():
    """The full-size scene (slow). Fast: the same box and verification on the coarse scene,
    through the CLI (tests/integration/cli/test_design.py::test_tolerance_json)."""
    model, opts = load("three-roller")  # the aligned nominal machine, N = 3762
    st = design.make_study(model, "lateral_max", opts, t_eval=0.1, components="roller 2:rotation,roller 3:dz")
    res = design.tolerance_box(st, 20.0, n_random=2, n_corners=2)
    assert res.verified and 0.97 * 20 <= res.worst_case_um <= 20.0
    full = [row.full_um for row in res.verification]
    assert max(full) == res.worst_case_um
    assert res.binding and set(res.binding) <= set(st.space.labels())
    # the box is around the scene's own misalignment, half-widths non-negative and finite
    assert np.all(res.half_widths >= 0) and np.all(np.isfinite(res.half_widths))

