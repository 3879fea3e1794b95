"""The linear model of a study's runs: :class:`LinearDeviation`, their tracer deviations and actuator
angles at the scene's own misalignment (``θ = 0``) with their derivatives with respect to every
varied component.

A study builds it (:func:`jaxbelt.design.study.make_study` with ``jacobian=True``, or
:func:`jaxbelt.design.study.linearise`) and keeps it *beside* itself, not in its pytree: no run
reads it. What reads a linear response reads it from here instead of running again — the
response's Jacobian (:func:`jaxbelt.design.response_jacobian`), hence the tolerance box
(:mod:`jaxbelt.design.linear_box`), FORM's start and the RSS stack-up, and a steady study's
surrogate. It is a function of the deviations alone, so it serves every metric and every set of
limits of the same study.
"""

from __future__ import annotations

import equinox as eqx
import jax


class LinearDeviation(eqx.Module):
    """The deviations of a study's runs (:func:`~jaxbelt.design.study.run_deviation`) at ``θ = 0``
    and their derivatives with respect to every component of ``θ``: ``d(θ) ≈ d(0) + ∂d θ`` (module
    docstring).

    **Fields:** ``d_u_um``, ``d_v_um`` (n_steps, n_tr) the tracer deviations at ``θ = 0``, µm
    (``d_v_um`` ``None`` in 1D); ``angle_mrad`` (n_steps, n_c) the actuator angles there, mrad
    (``None`` without a loop); ``d_u_um_per_theta``, ``d_v_um_per_theta``,
    ``angle_mrad_per_theta`` their derivatives, the same shapes with a trailing axis P, per mm
    (translations) or mrad (rotations).
    """

    d_u_um: jax.Array
    d_v_um: jax.Array | None
    angle_mrad: jax.Array | None
    d_u_um_per_theta: jax.Array
    d_v_um_per_theta: jax.Array | None
    angle_mrad_per_theta: jax.Array | None

    @property
    def at_zero(self) -> tuple:
        """``(d_u, d_v, angle)`` at ``θ = 0`` (µm, µm, mrad), as
        :func:`~jaxbelt.design.study.run_deviation` returns them."""
        return self.d_u_um, self.d_v_um, self.angle_mrad

    @property
    def derivatives(self) -> tuple:
        """``(∂d_u, ∂d_v, ∂angle)``, each with a trailing axis P."""
        return self.d_u_um_per_theta, self.d_v_um_per_theta, self.angle_mrad_per_theta

    def deviation(self, theta) -> tuple:
        """``(d_u, d_v, angle)`` of the linear model at ``theta`` (P,), mm / mrad."""
        return tuple(None if a is None else a + b @ theta for a, b in zip(self.at_zero, self.derivatives))


def linear_deviation(at_zero, derivatives) -> LinearDeviation:
    """:class:`LinearDeviation` from ``(d_u, d_v, angle)`` and their derivatives."""
    return LinearDeviation(*at_zero, *derivatives)
