"""Tension stiffening: the membrane stress of the aligned machine and its initial-stress stiffness.

A tensioned belt resists lateral (in-plane transverse) motion not only by its bending stiffness
``E t w³/12`` but by its tension: a moving, tensioned span is a tensioned beam,
``EI y'''' − T y'' = …`` (Shelton & Reid 1971), whose lateral behaviour is set by the span
parameter ``K L`` with ``K² = T / EI``. In a linear finite-element model the ``T y''`` term is the
*initial-stress* (geometric) stiffness of the membrane stress state ``σ₀``,

$$ K_σ = t \\int_A G^T σ_0 G \\, dA \\otimes I_2, \\qquad
G = \\begin{bmatrix} ∂N/∂x \\\\ ∂N/∂z \\end{bmatrix},\\quad
σ_0 = \\begin{bmatrix} σ_{xx} & τ_{xz} \\\\ τ_{xz} & σ_{zz} \\end{bmatrix}, $$

the second-order work of ``σ₀`` on the displacement gradients, for ``u`` and ``v`` alike (the
consistent linearisation about a prestressed state). ``σ₀`` is the pre-tension (``length_mm``
shorter than the path: ``σ_xx = E ε₀``) plus the stress of the *aligned* machine's static
solution ``K x = F`` (what a tension roller's force or a drive sets up), evaluated at the 2 × 2
Gauss points of every free quad; roller elements carry no stiffness (the belt is pinned to the
roller surface), so they get none. Misalignments do not change ``σ₀`` (that would be second
order), so the model stays linear in them.

Decision (``[solver] tension_stiffening``, default ``true``): it matters exactly where lateral motion
matters, costs nothing per step (it is folded into the free-belt stiffness blocks at compile time)
and is zero for a belt without tension — the source's scenes (no pre-tension, no tension roller)
are unchanged by it. Set it ``false`` to reproduce a model without it.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from .elements import GAUSS_POINTS, column_pair_to_blocks, plane_stress_D, quad_B, quad_dofs
from .infra.programs import stored_jit
from .state import initial_state


def quad_geometric_stiffness(ell, w, sig_gp, t):
    """Initial-stress stiffness (8 × 8) of the ``ℓ × w`` bilinear rectangle for the stresses
    ``sig_gp`` (4, 3) = ``[σ_xx, σ_zz, τ_xz]`` at its 2 × 2 Gauss points (order ``(ξ, η)`` =
    ``(g0, g0), (g0, g1), (g1, g0), (g1, g1)``); DOFs interleaved ``u, v`` as in :func:`quad_B`."""
    K = jnp.zeros((4, 4))
    k = 0
    for gx in GAUSS_POINTS:
        for gz in GAUSS_POINTS:
            B = quad_B(gx, gz, ell, w)
            G = jnp.stack([B[0, 0::2], B[1, 1::2]])  # (2, 4): ∂N/∂x, ∂N/∂z
            sx, sz, txz = sig_gp[k]
            S = jnp.array([[sx, txz], [txz, sz]])
            K = K + G.T @ S @ G
            k += 1
    return t * jnp.kron(K, jnp.eye(2)) * (ell * w / 4.0)


def quad_gauss_stress(ell, w, u_e, E, nu, sig_pre):
    """Stresses (4, 3) at the Gauss points of one quad with nodal displacements ``u_e`` (8,):
    ``D B u_e + σ_pre``."""
    D = plane_stress_D(E, nu)
    return jnp.stack([D @ (quad_B(gx, gz, ell, w) @ u_e) + sig_pre for gx in GAUSS_POINTS for gz in GAUSS_POINTS])


@stored_jit
def membrane_stress(model, u, elem_free, E, nu, eps0):
    """Gauss-point stresses (n, n_eta-1, 4, 3) of the belt displacement ``u`` (n, b) plus the
    pre-tension ``σ_xx = E ε₀``; zero on roller elements (``elem_free`` (n,) 0/1)."""
    w_rows = jnp.diff(model.z0)
    idx = quad_dofs(model.n_eta)  # (n_eta-1, 8) into the column pair [u_i; u_{i+1}]
    pair = jnp.concatenate([u, jnp.roll(u, -1, axis=0)], axis=1)  # (n, 2b)
    u_e = pair[:, idx]  # (n, n_eta-1, 8)
    sig_pre = jnp.array([E * eps0, 0.0, 0.0])
    sig = jax.vmap(jax.vmap(quad_gauss_stress, in_axes=(None, 0, 0, None, None, None)),
                   in_axes=(0, None, 0, None, None, None))(model.ell, w_rows, u_e, E, nu, sig_pre)
    return sig * jnp.asarray(elem_free, sig.dtype)[:, None, None, None]


@stored_jit
def geometric_stiffness_blocks(model, sig, t):
    """``K_σ`` scattered into the cyclic block-tridiagonal format: ``(diag, lower, upper)`` (n, b, b)."""
    n, n_eta = model.n_xi, model.n_eta
    w_rows = jnp.diff(model.z0)
    Kq = jax.vmap(jax.vmap(quad_geometric_stiffness, in_axes=(None, 0, 0, None)),
                  in_axes=(0, None, 0, None))(model.ell, w_rows, sig, t)  # (n, n_eta-1, 8, 8)
    idx = quad_dofs(n_eta)
    Kc = jnp.zeros((n, 4 * n_eta, 4 * n_eta)).at[:, idx[:, :, None], idx[:, None, :]].add(Kq)
    return column_pair_to_blocks(Kc)


def with_tension_stiffening(model, elem_free, E, nu, t, eps0):
    """``model`` with ``K_σ`` of the aligned machine's static membrane stress added to its
    free-belt stiffness blocks (module docstring)."""
    aligned = model.replace(chi_static=jnp.zeros_like(model.chi_static))
    u0 = initial_state(aligned).u
    sig = membrane_stress(model, u0, elem_free, E, nu, eps0)
    Kd, Kl, Ku = geometric_stiffness_blocks(model, sig, t)
    return model.replace(K_diag=model.K_diag + Kd, K_lower=model.K_lower + Kl, K_upper=model.K_upper + Ku)


def span_forces(scene, mesh, model) -> list[dict]:
    """Net membrane force of every free span in the static solution of ``model`` (its own
    misalignments), N: ``t Σ_rows w_row σ̄_xx`` in 2D (σ̄ the element's Gauss-point mean, plane
    stress, pre-tension included), ``E A (u' + ε₀)`` in 1D, averaged over the span's elements.

    **Returns:** per span ``{"span": "roller a → roller b", "force_n", "strain", "x_m"}`` with
    ``strain = force / (E A)`` and ``x_m`` the span's mid-point along the belt."""
    belt = scene.belt
    eps0 = belt.pre_strain(mesh.length)
    u = initial_state(model).u
    free = np.asarray(mesh.elem_free, bool)
    if model.kind == "1d":
        ell = np.asarray(mesh.ell)
        ux = np.asarray(u[:, 0])
        force = belt.youngs_modulus * belt.area * ((np.roll(ux, -1) - ux) / ell + eps0)
    else:
        sig = np.asarray(membrane_stress(model, u, free.astype(float), belt.youngs_modulus,
                                         belt.poisson_ratio, eps0))  # (n, n_eta-1, 4, 3)
        w_rows = np.diff(np.asarray(mesh.z))
        force = belt.thickness * (sig[..., 0].mean(axis=2) * w_rows[None, :]).sum(axis=1)
    names = [r.name for r in scene.rollers]
    starts = list(mesh.segment_starts) + [mesh.n_xi]
    out = []
    for k, seg in enumerate(mesh.path.segments):
        if seg.kind != "free":
            continue
        cols = np.arange(starts[k], starts[k + 1])
        cols = cols[free[cols]]
        a = seg.index
        f = float(force[cols].mean())
        out.append({"span": f"{names[a]} → {names[(a + 1) % len(names)]}", "force_n": f,
                    "strain": f / (belt.youngs_modulus * belt.area),
                    "x_m": float(mesh.x[cols].mean() + 0.5 * mesh.ell[cols].mean())})
    return out


SLACK_STRAIN = 1e-6  # net compressive strain above round-off of the static solution
STRAIN_LIMIT = 0.05  # tensile strain beyond the small-strain model (overstrained_spans)


def slack_spans(scene, mesh, model, spans=None) -> list[dict]:
    """The spans of :func:`span_forces` under net compression (strain below ``−SLACK_STRAIN``):
    the belt is longer than its path there and would sag or lift off; the linear model carries
    the compression like a tension, so its lateral and longitudinal answers are not a real
    belt's. Decision: warn (CLI: stderr line with "slack", JSON ``slack``), do not refuse — the
    source's own scenes have no pre-tension, and a roller moved a few mm inwards already puts a
    span under slight compression; how much is acceptable is the user's call. ``spans``: the
    :func:`span_forces` of the model where already computed."""
    spans = span_forces(scene, mesh, model) if spans is None else spans
    return [s for s in spans if s["strain"] < -SLACK_STRAIN]


def overstrained_spans(scene, mesh, model, spans=None) -> list[dict]:
    """The spans of :func:`span_forces` stretched beyond ``STRAIN_LIMIT`` (5 %) in the static
    solution: the model is small-strain linear elasticity (and its kinematics linear in the
    misalignments), which a belt stretched this far has left — a roller moved by a sizeable
    fraction of the belt length, or a belt much shorter than its path. Decision: warn like a
    slack span (CLI: stderr line, JSON ``overstrained``), do not refuse; 5 % lies far above the
    pre-strains of the built-in scenes (at most 0.14 %) and above the elastic range of the usual belt
    materials (steel ~0.2 %, fabric-reinforced elastomers a few per cent)."""
    spans = span_forces(scene, mesh, model) if spans is None else spans
    return [s for s in spans if s["strain"] > STRAIN_LIMIT]


def overstrain_message(spans: list[dict]) -> str:
    """One line naming the overstrained spans, their force and strain."""
    parts = [f"{s['span']} ({s['force_n']:.3g} N, strain {s['strain']:.3g})" for s in spans]
    return (f"belt stretched beyond {100 * STRAIN_LIMIT:g} % in the static solution of " + "; ".join(parts)
            + " — beyond the small-strain linear model; check the roller translations and belt.length_mm")


def slack_message(slack: list[dict]) -> str:
    """One line naming the slack spans, their compressive force and strain."""
    parts = [f"{s['span']} ({s['force_n']:.3g} N, strain {s['strain']:.2e}, around x = {s['x_m']:.3f} m)"
             for s in slack]
    return ("slack belt: net compression in the static solution of " + "; ".join(parts)
            + " — the belt is longer than its path there; add pre-tension (belt.length_mm) or a tension roller")
