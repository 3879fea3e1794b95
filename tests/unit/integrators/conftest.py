"""The machine every integrator of this folder steps: the coarse pre-tensioned two-roller string
with its idle roller moved (:func:`helpers.pretensioned_idle_translated_machine`), built once."""

import pytest

from helpers import pretensioned_idle_translated_machine


@pytest.fixture(scope="package")
def model():
    return pretensioned_idle_translated_machine()
