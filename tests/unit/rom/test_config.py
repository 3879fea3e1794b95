"""The request of a reduction (jaxbelt.rom.config.ReduceConfig): the full run's settings as one
``RunOptions``, and every setting checked when the request is made, before anything runs."""

import pytest

import jaxbelt as jb
from jaxbelt import rom


@pytest.fixture(scope="module")
def options():
    return jb.RunOptions.from_scene(jb.load_scene("two-roller-1d")).replace(n_steps=40)


def test_the_full_run_is_read_from_its_options(options):
    c = rom.ReduceConfig(method=rom.DMDc(modes=4), options=options.replace(saveat=jb.SaveAt(every=5)))
    assert c.options.n_steps == 40 and c.options.saveat.every == 5 and c.options.solver is options.solver
    assert c.train_window == 20  # default: half the run, at most 200 steps
    assert rom.ReduceConfig(method=rom.DMDc(), options=options, train_steps=7).train_window == 7


@pytest.mark.parametrize("changes,message", [
    (dict(options=None), "RunOptions"),
    (dict(stride=-1), "stride = -1"),
    (dict(calibration_runs=-2), "calibration_runs = -2"),
    (dict(method="dmdc"), "a reduction"),
])
def test_a_bad_setting_is_named(options, changes, message):
    with pytest.raises(ValueError, match=message):
        rom.ReduceConfig(**{"method": rom.DMDc(), "options": options, **changes})


def test_a_run_without_steps_is_named(options):
    with pytest.raises(ValueError, match="options.n_steps = 0"):
        rom.ReduceConfig(method=rom.DMDc(), options=options.replace(n_steps=0))
