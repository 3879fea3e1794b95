"""Tolerance design (MODEL.md §6): metrics, sensitivities, tolerance boxes, yield, sharding.

Sits above :mod:`jaxbelt.timeloop` and :mod:`jaxbelt.rom` and is never imported by them.
"""
