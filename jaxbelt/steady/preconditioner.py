"""The right preconditioner of the steady solves (:mod:`jaxbelt.steady.fixed_point`): the period
map's element-mass transport inverted exactly (:class:`MassTransportPreconditioner`), applied to
the mass block of the flat unknowns GMRES works on (:func:`preconditioned`)."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.flatten_util
import jax.numpy as jnp
import jax.scipy.linalg
from jax import lax

from ..model import BeltModel
from ..transport import transport_masses, upwind_weights


class MassTransportPreconditioner(eqx.Module):
    """The right preconditioner of the steady solves: the period map's element-mass transport
    inverted exactly, the identity elsewhere (:mod:`jaxbelt.steady.fixed_point`, *Iterations*).

    The slow directions of ``Φ`` are the element masses carried around the loop: the transport step
    (eq. 3.57) moves each element row's masses by one cyclic upwind matrix ``C`` per step, so over a
    period ``T = Cⁿᵖ``, whose eigenvalues lie close to the unit circle (a mass pattern travels
    round the belt, damped only by the upwind diffusion). With the belt's nominal shift per step
    (its speed times ``Δt``) ``C`` is the same for every element row (the shift rule's uniform
    weights), so ``M = I − T + 𝟙𝟙ᵀ/n`` is one small dense matrix (``n`` elements round the loop),
    factorised once; the rank-one term regularises the row's conserved total mass, the direction
    ``I − T`` leaves singular. ``M⁻¹`` is applied to the mass block (in its scaled units, rows
    ``m_e0``-weighted), the other blocks are passed through."""

    lu: tuple
    scale: jax.Array  # (n,) m_e0 along the loop (one element row)

    def solve(self, r_m, transpose: bool = False):
        """``M⁻¹ r_m`` (or ``M⁻ᵀ r_m``) for the scaled mass block ``r_m`` ((n,) or (n, rows))."""
        d = self.scale if r_m.ndim == 1 else self.scale[:, None]
        if transpose:  # (D⁻¹ M D)⁻ᵀ = D Mᵀ⁻¹ D⁻¹
            return jax.scipy.linalg.lu_solve(self.lu, r_m / d, trans=1) * d
        return jax.scipy.linalg.lu_solve(self.lu, r_m * d) / d


def mass_transport_preconditioner(model: BeltModel, dt, n: int) -> MassTransportPreconditioner:
    """:class:`MassTransportPreconditioner` of ``model``'s period map (``n`` steps of ``dt``)."""
    ell = model.ell
    v = jnp.einsum("nbq,q->nb", model.R, model.omega)
    v = v[:, 0::2] if model.kind == "2d" else v
    v = v.reshape(-1)[jnp.argmax(jnp.abs(v))]  # the drive's surface speed, signed
    shift = lax.stop_gradient(v * dt)
    a, fwd = upwind_weights(jnp.full((ell.shape[0], 1), shift), ell)
    C = transport_masses(jnp.eye(ell.shape[0], dtype=ell.dtype), a, fwd)
    eye = jnp.eye(ell.shape[0], dtype=ell.dtype)
    M = eye - jnp.linalg.matrix_power(C, n) + 1.0 / ell.shape[0]
    M = jnp.where(shift == 0, eye, M)  # a belt no drive moves (torque-driven, at rest): no transport to invert
    m0 = model.m_e0 if model.m_e0.ndim == 1 else model.m_e0[:, 0]
    return MassTransportPreconditioner(lu=lax.stop_gradient(jax.scipy.linalg.lu_factor(M)),
                                       scale=lax.stop_gradient(m0))


def preconditioned(pre: MassTransportPreconditioner | None, y_template, transpose: bool = False):
    """``None`` without a preconditioner, else ``z ↦ M⁻¹ z`` on flat vectors shaped like
    ``y_template`` (the unknowns, or the walk system's ``(unknowns, c)``): the mass block
    (``state_fields``' fifth) preconditioned, the rest passed."""
    if pre is None:
        return None
    _, unravel = jax.flatten_util.ravel_pytree(y_template)
    walking = isinstance(y_template[0], tuple)

    def apply(z):
        tree = unravel(z)
        fields = tree[0] if walking else tree
        fields = fields[:4] + (pre.solve(fields[4], transpose),) + fields[5:]
        return jax.flatten_util.ravel_pytree((fields, tree[1]) if walking else fields)[0]

    return apply
