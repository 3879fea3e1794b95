"""The machine of the steady-state tests and its steady state, shared by the package's modules."""

import pytest

import jaxbelt as jb
from jaxbelt.steady import steady_state

SCENE = "two-roller-steered"  # drive skewed 0.15 mrad, PI loop on the idle roller (N = 180)


@pytest.fixture(scope="package")
def machine():
    scene = jb.load_scene(SCENE)
    return jb.build_model(scene), jb.RunOptions.from_scene(scene)


@pytest.fixture(scope="package")
def steady(machine):
    model, opts = machine
    return steady_state(model, opts.solver, dt=opts.dt)
