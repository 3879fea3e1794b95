"""Shared by the reduction tests: two short 1D configurations (the scenes ``jaxbelt reduce``'s tests
use) and their run settings."""

import pytest

import jaxbelt as jb

N_STEPS, TRAIN_STEPS = 40, 20  # steps predicted and compared; steps of each training run


@pytest.fixture(scope="module")
def setup():
    """``(models, options)``: ``two-roller-1d`` and ``two-roller-1d-train1``, the first's run settings."""
    scenes = [jb.load_scene(n) for n in ("two-roller-1d", "two-roller-1d-train1")]
    return [jb.build_model(s) for s in scenes], jb.RunOptions.from_scene(scenes[0])
