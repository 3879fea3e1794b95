"""Moved to :mod:`jaxbelt.bench.scipy_reference` (``jaxbelt bench`` uses it); kept as an alias."""

from jaxbelt.bench.scipy_reference import ScipyBelt  # noqa: F401
