"""The transport (interpolation) step that keeps the grid fixed in space (§3.5, model specification §3).

After a solve the belt material has moved by ``ũ`` while the grid stays put. Each grid point
takes the value of the material that now sits on it, by exact linear interpolation between the
displaced positions of its two neighbouring material points (eq. 3.55–3.56): with the upwind
neighbour ``i-1`` (``ũ_i >= 0``) the weight is ``a_i = ũ_i / (ℓ_{i-1} - ũ_{i-1} + ũ_i)``, with the
neighbour ``i+1`` (``ũ_i < 0``) it is ``a_i = -ũ_i / (ℓ_i + ũ_{i+1} - ũ_i)``, and
``f_i ← a_i f_src + (1 - a_i) f_i``. Which displacement enters the weights is the choice of
relabelling rule below; the CFL condition ``V Δt < ℓ_min`` is checked when a scene is loaded.

Decisions where the source is silent (documented here, tested in ``tests/``):

* **Mean.** ``ū`` is the plain mean over all belt nodes (of ``ũ`` for the shift rule, of the
  interpolated ``u`` for the source rule); either way a rigid shift of the belt is removed
  exactly.
* **Velocities** are material quantities and are interpolated with the same weights, without
  mean subtraction (the moving reference only relabels material points).
* **Mass** is transported as element masses in flux form (eq. 3.57): the mass crossing grid
  point ``i`` is ``a_i m_{i-1}`` (forward) or ``-a_i m_i`` (backward), and every element gains
  what crosses its left node and loses what crosses its right node. On the closed loop this
  telescopes, so the total mass is conserved to round-off. (Under the shift rule below the
  flux is ``s`` times the line density, so a uniform belt keeps ``ρAℓ`` in every element: mass
  per material length does not change with strain. Under the source rule mass moves between
  elements as the belt is strained.)
* **Roller arcs.** On a roller the material keeps its displacement *relative to the roller
  surface*, ``w = u - R_r χ`` (no slip). Interpolating ``u`` itself would smear the geometric
  part ``R_r χ`` of a translated/tilted roller along the arc and, over a revolution, erase the
  misalignment from the free spans. So between two nodes of the same roller ``w`` is
  interpolated and ``R_r χ`` of the node added back; across a contact line (upwind node on a
  free span) the plain value is used. Without misalignment (or in the source's variant) this
  changes nothing, since ``R_r χ`` is then the same rigid rotation at every node of a roller.
* **Entry lines and the normal-entry law** (2D, ``lateral_transport = true``). Material that
  crosses an *entry* contact line (free span upstream, roller downstream) keeps its lateral
  position relative to the roller surface *continued tangentially* past the contact line:
  ``v_entry ← a v_up + (1 - a) v_entry + s σ``, ``σ`` the lateral slope of the roller's
  circumferential lines at the contact line (its skew as the entering span sees it), ``s`` the
  distance transported.
  In steady walk at rate ``c`` this is Shelton's normal-entry law ``c = V (σ − y')``, i.e. the
  belt's Eulerian slope is continuous across the entry line. Plain values across the line (the
  rule before) give ``c = −V y'`` instead: the belt enters a skewed roller as if it were
  aligned, held there by a concentrated lateral friction force that a real contact (finite
  friction per area) cannot supply, and a tight belt on a skewed roller hardly walks
  (``docs/lateral.md`` §4). Only ``v`` is continued: the longitudinal ``u`` keeps the plain
  value, so the 1D model and the source's variant are unchanged.
* **Rotations** about the roller axes (``α_z``) are reset to zero (the roller's 'mean').

Two relabelling rules (``[solver] transport``):

* ``"shift"`` (default): the reference frame moves by ``s = mean(ũ)``; grid point ``X_i`` takes
  the material labelled ``X_i - s``, i.e. uniform weights ``a = s / ℓ`` (upwind) and
  ``u ← ũ(X_i - s) - s``. This is the consistent relabelling of a moving reference: the weights
  only see the belt's motion during the step, so the CFL condition ``V Δt < ℓ_min`` is exactly
  what keeps ``0 <= a < 1``. On ``two-roller-1d`` with the idle roller 1 mm out it gives the
  analytic steady strain d / (D + π r) to round-off for every Δt and mesh, and equal drive and
  idle speeds (``tests/integration/test_transport.py``).
* ``"source"``: eq. 3.55–3.56 literally, as model specification §3 writes it: each grid point takes the
  material whose *displaced position* ``X + ũ`` lies on it, then the mean is subtracted. The
  weights see the whole displacement ``ũ`` (static misalignment response included), not only
  the step's motion. Two consequences, both measured in ``tests/integration/test_transport.py``:
  (1) with the idle roller 1 mm out the steady span strain is 0.002185 at Δt = 5 ms and 0.001965
  at 2.5 ms instead of 0.0023144: an error that does not vanish as Δt → 0 but grows; (2) once
  ``|ũ|`` exceeds an element length the weights leave [0, 1) and the step extrapolates: on
  ``two-roller-1d-train1`` (10 mm translation, 3.9 mm elements) they reach 3–40 during the
  start-up, and round-off differences grow 10⁸-fold. Kept for comparison with the source.

Because the source rule fails silently, every run records the range of the weights
(``Trajectory.transport_weights``); the CLI warns when it leaves [0, 1).
"""

from __future__ import annotations

import jax.numpy as jnp

from .assembly import roller_R, roller_surface_displacement
from .model import BeltModel
from .registry import TRANSPORT_RULES


def upwind_weights(u, ell):
    """Interpolation weights ``a`` (n, k) and flow direction ``fwd`` for displacements ``u`` (n, k)."""
    ell = ell[:, None]
    fwd = u >= 0
    a_fwd = u / (jnp.roll(ell, 1, axis=0) - jnp.roll(u, 1, axis=0) + u)
    a_bwd = -u / (ell + jnp.roll(u, -1, axis=0) - u)
    return jnp.where(fwd, a_fwd, a_bwd), fwd


def upwind_values(f, fwd):
    """The upwind neighbour's value of a nodal field ``f`` (n, ...)."""
    return jnp.where(fwd, jnp.roll(f, 1, axis=0), jnp.roll(f, -1, axis=0))


def interpolate(f, a, fwd):
    """``a f_src + (1 - a) f`` (eq. 3.55 without the mean)."""
    return a * upwind_values(f, fwd) + (1.0 - a) * f


def transport_masses(m_e, a, fwd):
    """Element masses after transport (eq. 3.57, flux form; conserves ``Σ m_e`` exactly)."""
    flux = jnp.where(fwd, a * jnp.roll(m_e, 1, axis=0), -a * m_e)
    return m_e + flux - jnp.roll(flux, -1, axis=0)


def roller_relative_correction(model: BeltModel, a, fwd, r):
    """``a (r_i - r_src)`` where the upwind node lies on the same roller, else 0 (all (n, b))."""
    rollers = jnp.broadcast_to(model.node_roller[:, None], r.shape)
    same = (upwind_values(rollers, fwd) == rollers) & (rollers >= 0)
    return jnp.where(same, a * (r - upwind_values(r, fwd)), 0.0)


def roller_skew(model: BeltModel, chi):
    """The lateral slope ``ψ`` (n,) of the roller surface's circumferential lines under each node
    column, along the direction of increasing ``x``: ``ψ = s (α_x cos θ + α_y sin θ)`` for the
    node's roller tilted by ``(α_x, α_y)`` (its DOFs in ``chi``), ``s`` the wrap sense, 0 on free
    spans — the derivative of the surface's lateral position ``v_s = d_z + r (α_x sin θ − α_y cos θ)``
    along the arc, exactly (model specification §3; :mod:`jaxbelt.rollers`)."""
    c = chi.reshape(model.n_rollers, len(model.dofs))
    j = jnp.maximum(model.node_roller, 0)
    ax, ay = c[j, model.dofs.index("ax")], c[j, model.dofs.index("ay")]
    psi = model.node_sense * (ax * jnp.cos(model.node_theta) + ay * jnp.sin(model.node_theta))
    return jnp.where(model.node_roller >= 0, psi, 0.0)


def entry_line_correction(model: BeltModel, a, fwd, chi):
    """``a ℓ_up σ`` at entry contact-line nodes, else 0 (all (n, b)).

    An entry node lies on a roller whose upwind neighbour does not; ``σ`` is the lateral slope of
    the roller's circumferential lines at the node along the flow (:func:`roller_skew`, exact for
    the current tilt ``chi``: a difference quotient of the nodal surface displacement on a coarse
    arc overstates it, by 8 % on 30° elements), continued over the upwind element of length
    ``ℓ_up`` (module docstring, normal-entry law)."""
    rollers = jnp.broadcast_to(model.node_roller[:, None], a.shape)
    up = upwind_values(rollers, fwd)
    entry = (rollers >= 0) & (up != rollers)
    ell = model.ell[:, None]
    ell_up = jnp.where(fwd, jnp.roll(ell, 1, axis=0), ell)
    psi = roller_skew(model, chi)[:, None]
    slope = jnp.where(fwd, psi, -psi)
    return jnp.where(entry, a * ell_up * slope, 0.0)


def _x_dofs(model: BeltModel, f):
    """The longitudinal components (n, n_eta) of a belt field (n, b)."""
    return f if model.kind == "1d" else f[:, 0::2]


def transport_step(model: BeltModel, u, u_dot, chi, m_e, rule: str = "shift"):
    """Interpolate the solved state back onto the grid.

    **Arguments:** ``u``, ``u_dot`` (n, b) after the solve; ``chi`` (q,) roller DOFs;
    ``m_e`` element masses, (n,) in 1D, (n, n_eta - 1) in 2D; ``rule`` ``"shift"`` or
    ``"source"`` (module docstring). In 2D only x is transported unless ``model.lateral_transport``.
    **Returns:** ``(u, u_dot, chi, m_e)`` on the grid, ``α_z`` reset to 0.
    """
    u_new, u_dot_new, chi_new, m_new, _ = transport_step_with_weights(model, u, u_dot, chi, m_e, rule=rule)
    return u_new, u_dot_new, chi_new, m_new


def transport_step_with_weights(model: BeltModel, u, u_dot, chi, m_e, s=None, R=None, static_offset=None,
                                rule: str = "shift"):
    """:func:`transport_step` plus the ``(min, max)`` of the interpolation weights (diagnostic).

    ``s`` (shift rule only) imposes the shift instead of ``mean(ũ)`` and ``R`` freezes the roller
    kinematics used for the roller-relative correction: with both given the step is affine in
    ``(u, u_dot, chi)`` — what the fully reduced step (:mod:`jaxbelt.rom.pod_step`) projects.
    ``static_offset``: :func:`jaxbelt.assembly.static_surface_offset`, if already computed."""
    ux = _x_dofs(model, u)
    if rule not in TRANSPORT_RULES:
        raise ValueError(f"unknown transport rule {rule!r} (one of {', '.join(TRANSPORT_RULES)})")
    shift = rule == "shift"
    if s is None:
        s = jnp.mean(ux)
    elif not shift:
        raise ValueError("an imposed shift needs the 'shift' transport rule")
    a_x, fwd_x = upwind_weights(jnp.full_like(ux, s) if shift else ux, model.ell)
    if model.kind == "1d":
        a, fwd = a_x, fwd_x
    else:  # u and v of a node share the node's weight; v is frozen (a = 0) unless transported
        a_v = a_x if model.lateral_transport else jnp.zeros_like(a_x)
        a = jnp.stack([a_x, a_v], axis=2).reshape(u.shape)
        fwd = jnp.repeat(fwd_x, 2, axis=1)
    r = roller_surface_displacement(model, chi, roller_R(model, u, on_rollers=True) if R is None else R,
                                    static_offset)
    u_new = interpolate(u, a, fwd) + roller_relative_correction(model, a, fwd, r)
    if model.kind == "2d" and model.lateral_transport:  # normal entry: lateral DOFs only
        v_mask = jnp.tile(jnp.array([0.0, 1.0]), model.n_eta)
        u_new = u_new + v_mask * entry_line_correction(model, a, fwd, chi)
    mean = s if shift else jnp.mean(_x_dofs(model, u_new))
    x_mask = jnp.ones(u.shape[1]) if model.kind == "1d" else jnp.tile(jnp.array([1.0, 0.0]), model.n_eta)
    u_new = u_new - mean * x_mask
    u_dot_new = interpolate(u_dot, a, fwd)
    if m_e.ndim == 1:
        m_new = transport_masses(m_e, a_x[:, 0], fwd_x[:, 0])
    else:  # element rows move with the mean displacement of their two node rows
        ue = jnp.full_like(m_e, s) if shift else 0.5 * (ux[:, :-1] + ux[:, 1:])
        a_e, fwd_e = upwind_weights(ue, model.ell)
        m_new = transport_masses(m_e, a_e, fwd_e)
    chi_new = jnp.where(model.is_az, 0.0, chi)
    return u_new, u_dot_new, chi_new, m_new, jnp.stack([jnp.min(a_x), jnp.max(a_x)])
