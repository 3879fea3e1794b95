"""Assembly of the DAE ``K x + M ẍ = F`` for one time step (§3.3, §4.3, model specification §2–§4).

Rows, in the unknowns' order:

* free-belt DOF: ``K_f u + M_f ü = -f₀`` (eq. 3.36; ``f₀`` = pre-tension);
* belt DOF on a roller: the Backward-Euler no-slip row (eq. 3.35)
  ``u(t) - R_r χ(t) = u(t-Δt) - R_r χ(t-Δt)``;
* dynamic roller DOF: ``M_r χ̈ + Σ_k R_rᵀ f_k = Q_ext`` with ``f_k = m_k ü_k + (K_f u + f₀)_k``,
  the force the belt needs at roller node ``k``: lumped inertia, plus on contact lines the
  stiffness terms of the adjacent free elements (eq. 3.38–3.39, 4.29–4.30);
* prescribed roller DOF: ``χ = value`` (translation/tilt; drive: ``α_z(t) = α_z(t-Δt) + ωΔt``).

Everything is produced directly in the bordered block format (no dense N × N matrix).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from .linalg import BorderedBlockCyclic
from .model import BeltModel
from .rollers import exact_static_displacement


def roller_R(model: BeltModel, u, on_rollers: bool = False) -> jnp.ndarray:
    """``R_r`` (n, b, q) at the current state: in 2D the lever arm of the tilts is the node's
    current lateral position ``z + v`` (§4.2, weak nonlinearity), lagged by one step.

    ``on_rollers``: only the node columns on rollers (``model.contact_columns``, where ``R_r``
    can be non-zero), (n_on, b, q) — a fifth of the array on the default scene, and the
    products with it (:func:`roller_times`, :func:`belt_force_on_rollers`, which take either
    form) a fifth of the memory traffic. The full form where the columns are unknown."""
    idx = _on(model) if on_rollers else None
    R0, Rdz = (model.R, model.R_dz) if idx is None else (model.R[idx], model.R_dz[idx])
    if model.kind == "1d":
        return R0
    v = u[:, 1::2] if idx is None else u[idx][:, 1::2]
    lever = jnp.stack([v, jnp.zeros_like(v)], axis=-1).reshape(v.shape[0], -1)  # v on the u DOFs (no scatter)
    return R0 + Rdz * lever[:, :, None]


def _on(model: BeltModel):
    """Static indices of the node columns on rollers, or ``None`` if the model does not know them."""
    return None if model.contact_columns is None else np.asarray(model.contact_columns, int)


def roller_times(model: BeltModel, R, chi) -> jnp.ndarray:
    """``R_r χ`` (n, b) for ``R`` in either form of :func:`roller_R` (zero off the rollers)."""
    y = jnp.einsum("nbq,q->nb", R, chi)
    if R.shape[0] == model.n_xi:
        return y
    # back onto all columns by a gather from [y; 0] (a scatter is several times slower on a CPU)
    on = _on(model)
    pos = np.full(model.n_xi, len(on))
    pos[on] = np.arange(len(on))
    return jnp.concatenate([y, jnp.zeros((1, y.shape[1]), y.dtype)])[pos]


def belt_force_on_rollers(model: BeltModel, R, f) -> jnp.ndarray:
    """``Σ_k R_rᵀ f_k`` (q,) for nodal forces ``f`` (n, b) and ``R`` in either form of :func:`roller_R`."""
    return generalised_belt_force(R, f if R.shape[0] == model.n_xi else f[_on(model)])


def roller_surface_displacement(model: BeltModel, chi, R, static_offset=None) -> jnp.ndarray:
    """Displacement (n, b) of the roller surface under each roller node for roller DOFs ``chi``.

    Linear ``R_r χ`` plus, in 2D, the difference between the exact finite static motion
    (rotations x → y → z, §4.2) and its linearisation at the reference lever arm, so the
    static misalignment enters exactly and its increments linearly."""
    lin = roller_times(model, R, chi)
    if model.kind == "1d":
        return lin
    return lin + static_surface_offset(model) if static_offset is None else lin + static_offset


def static_surface_offset(model: BeltModel):
    """The part of :func:`roller_surface_displacement` that does not depend on the state: the
    exact finite static motion minus its linearisation at the reference lever arm, (n, b) in 2D,
    ``None`` in 1D. Constant over a run: the time loop computes it once, outside its scan."""
    if model.kind == "1d":
        return None
    cs = model.chi_static
    g = exact_static_displacement(cs.reshape(model.n_rollers, 6), model.node_roller, model.node_theta,
                                  model.node_radius, model.node_sense, model.z0)
    return g - jnp.einsum("nbq,q->nb", model.R, cs)


def nodal_masses(model: BeltModel, m_e) -> jnp.ndarray:
    """Lumped nodal masses (n, b): half of each adjacent element's mass in 1D (eq. 3.25–3.26), a
    quarter of each adjacent quad's in 2D (eq. 4.24), on both the u and the v DOF."""
    if m_e.ndim == 1:
        m = 0.5 * (m_e + jnp.roll(m_e, 1))
        return jnp.broadcast_to(m[:, None], (m.shape[0], model.block))
    col = m_e + jnp.roll(m_e, 1, axis=0)  # (n, n_eta-1): both element columns touching node column i
    zero = jnp.zeros((m_e.shape[0], 1))
    m = 0.25 * (jnp.concatenate([col, zero], axis=1) + jnp.concatenate([zero, col], axis=1))
    return jnp.repeat(m, 2, axis=1)


def generalised_belt_force(R, f) -> jnp.ndarray:
    """``Σ_k R_rᵀ f_k`` for nodal forces ``f`` (n, b): the belt's load on the roller DOFs (q,)."""
    return f.reshape(-1) @ R.reshape(-1, R.shape[-1])  # one product (an einsum over (n, b) is slower on a CPU)


def roller_stiffness_rows(R, Kd, Kl, Ku) -> jnp.ndarray:
    """Belt-column blocks (n, q, b) of ``Rᵀ K_f``: column ``i`` gets ``Σ_j R[j]ᵀ K_f[j, i]``."""
    tr = lambda a: jnp.swapaxes(a, 1, 2)
    return (
        tr(R) @ Kd
        + tr(jnp.roll(R, 1, axis=0)) @ jnp.roll(Ku, 1, axis=0)
        + tr(jnp.roll(R, -1, axis=0)) @ jnp.roll(Kl, -1, axis=0)
    )


def dae_matrices(model: BeltModel, m_e, R=None):
    """``(K, M)`` of the DAE in bordered block format for element masses ``m_e``."""
    R = model.R if R is None else R
    n, b, q = R.shape
    con = model.is_constraint
    dyn = model.dynamic
    eye = jnp.eye(b)[None]
    zero = jnp.zeros((n, b, b))
    K = BorderedBlockCyclic(
        diag=jnp.where(con[:, :, None], eye, model.K_diag),
        lower=jnp.where(con[:, :, None], zero, model.K_lower),
        upper=jnp.where(con[:, :, None], zero, model.K_upper),
        C=jnp.where(con[:, :, None], -R, 0.0),
        D=jnp.where(dyn[None, :, None], roller_stiffness_rows(R, model.K_diag, model.K_lower, model.K_upper), 0.0),
        E=jnp.diag(jnp.where(dyn, 0.0, 1.0)),
    )
    m = nodal_masses(model, m_e)
    Rm = jnp.swapaxes(R * m[:, :, None], 1, 2)  # (n, q, b) = R[i]ᵀ diag(m[i])
    M = BorderedBlockCyclic(
        diag=jnp.where(con[:, :, None], 0.0, m[:, :, None] * eye),
        lower=zero,
        upper=zero,
        C=jnp.zeros((n, b, q)),
        D=jnp.where(dyn[None, :, None], Rm, 0.0),
        E=jnp.diag(jnp.where(dyn, model.M_roller, 0.0)),
    )
    return K, M


def dae_rhs(model: BeltModel, u_prev, chi_prev, dt, R=None):
    """Right-hand side ``F`` for the step of size ``dt`` (s) from the (transported, reset) state
    ``(u_prev, χ_prev)``: ``(belt (n, b), roller (q,))``."""
    R = model.R if R is None else R
    con = model.is_constraint
    F_belt = jnp.where(con, u_prev - roller_times(model, R, chi_prev), -model.f0)
    target = model.chi_static + jnp.where(model.is_az, chi_prev, 0.0) + model.omega * dt
    F_roll = jnp.where(model.dynamic, model.Q_ext - belt_force_on_rollers(model, R, model.f0), target)
    return F_belt, F_roll


def static_rhs(model: BeltModel, R=None):
    """Right-hand side of the initial static problem ``K x = F`` (§3.4, §4.4.1): belt at rest on
    the misaligned rollers (``u_r = `` exact surface displacement), drive angle 0."""
    R = model.R if R is None else R
    offset = roller_surface_displacement(model, model.chi_static, R) - jnp.einsum("nbq,q->nb", R, model.chi_static)
    F_belt = jnp.where(model.is_constraint, offset, -model.f0)
    F_roll = jnp.where(model.dynamic, model.Q_ext - generalised_belt_force(R, model.f0), model.chi_static)
    return F_belt, F_roll


def free_belt_matvec(model: BeltModel, u) -> jnp.ndarray:
    """``K_f u`` (n, b) with the block-tridiagonal free-belt stiffness, without assembling ``K``."""
    return (jnp.einsum("nij,nj->ni", model.K_diag, u)
            + jnp.einsum("nij,nj->ni", model.K_lower, jnp.roll(u, 1, axis=0))
            + jnp.einsum("nij,nj->ni", model.K_upper, jnp.roll(u, -1, axis=0)))


def free_belt_stencil(model: BeltModel):
    """The free-belt stiffness of a 2D model as a nine-point stencil of 2 × 2 node blocks,
    ``(n, n_eta, 3, 3, 2, 2)``: entry ``[i, j, di, dj]`` couples node ``(i, j)`` to node
    ``(i + di - 1, j + dj - 1)`` (column index mod n). ``None`` in 1D.

    A bilinear quad couples a node only to the nodes of the elements it belongs to, so each
    ``2 n_eta``-square block of ``K_f`` is block-tridiagonal in ``η`` with 2 × 2 blocks — 12–13 %
    of its entries are non-zero on the default scene. The stencil keeps exactly those entries
    (``tests/integration/integrators/test_kept_interior.py`` checks :func:`stencil_matvec` against the block product), so a
    product costs a sixth of the block one: 67 k instead of 400 k multiply-adds on
    ``three-roller-t72``. Gathered from ``K_diag``/``K_lower``/``K_upper``, it carries their
    derivatives."""
    if model.kind != "2d":
        return None
    n, ne = model.n_xi, model.n_eta
    blocks = jnp.stack([model.K_lower, model.K_diag, model.K_upper], axis=1).reshape(n, 3, ne, 2, ne, 2)
    j = np.arange(ne)
    out = []
    for dj in (-1, 0, 1):
        inside = (j + dj >= 0) & (j + dj < ne)
        sub = blocks[:, :, j, :, np.clip(j + dj, 0, ne - 1), :]  # (ne, n, 3, 2, 2): advanced axes first
        out.append(jnp.moveaxis(jnp.where(inside[:, None, None, None, None], sub, 0.0), 0, 1))
    return jnp.stack(out, axis=3)


def stencil_matvec(S, u, columns=None):
    """``K_f u`` (n, b) from the stencil ``S`` of :func:`free_belt_stencil`; with ``columns``
    (static indices) only those node columns' rows, (len(columns), b).

    Written as the nine shifted 2 × 2 products, elementwise (XLA fuses them into one loop over
    the nodes): the same sum as an ``einsum`` over the stencil axes, which XLA's CPU backend
    lowers to a batched dot several times slower."""
    n, ne = S.shape[0], S.shape[1]
    U = jnp.pad(u.reshape(n, ne, 2), ((0, 0), (1, 1), (0, 0)))
    near = (jnp.roll(U, 1, axis=0), U, jnp.roll(U, -1, axis=0))  # columns i-1, i, i+1
    if columns is not None:
        idx = np.asarray(columns, int)
        S, near = S[idx], tuple(c[idx] for c in near)
    acc = jnp.zeros(S.shape[:2] + (2,), jnp.result_type(S, u))
    for di, col in enumerate(near):
        for dj in range(3):
            Uk, Sk = col[:, dj:dj + ne], S[:, :, di, dj]  # (m, ne, 2), (m, ne, 2, 2)
            acc = acc + Sk[..., 0] * Uk[..., None, 0] + Sk[..., 1] * Uk[..., None, 1]
    return acc.reshape(S.shape[0], 2 * ne)


def dae_apply(model: BeltModel, m_e, R, x_b, x_r, stencil=None):
    """Matrix-free ``(K x, M x)`` of the DAE, each split as ``(belt (n, b), roller (q,))``.

    Equals :func:`dae_matrices` followed by ``matvec`` (tested) at a fraction of the cost; used
    by the factorisation-reuse integrator, whose steps need products, not matrices. With
    ``stencil`` (:func:`free_belt_stencil`) the free-belt product uses it; ``R`` in either form
    of :func:`roller_R`."""
    con, dyn = model.is_constraint, model.dynamic
    Kf_x = free_belt_matvec(model, x_b) if stencil is None else stencil_matvec(stencil, x_b)
    m = nodal_masses(model, m_e)
    Kx_b = jnp.where(con, x_b - roller_times(model, R, x_r), Kf_x)
    Kx_r = jnp.where(dyn, belt_force_on_rollers(model, R, Kf_x), x_r)
    Mx_b = jnp.where(con, 0.0, m * x_b)
    Mx_r = jnp.where(dyn, belt_force_on_rollers(model, R, m * x_b) + model.M_roller * x_r, 0.0)
    return (Kx_b, Kx_r), (Mx_b, Mx_r)


def step_matrix(model: BeltModel, m_e, R, dt) -> BorderedBlockCyclic:
    """``M + Δt² K`` assembled directly (one pass instead of two matrices and a sum)."""
    n, b, q = R.shape
    con = model.is_constraint[:, :, None]
    dyn = model.dynamic
    eye = jnp.eye(b)[None]
    m = nodal_masses(model, m_e)
    dt2 = dt**2
    RT = jnp.swapaxes(R, 1, 2)
    D = dt2 * roller_stiffness_rows(R, model.K_diag, model.K_lower, model.K_upper) + RT * m[:, None, :]
    return BorderedBlockCyclic(
        diag=jnp.where(con, dt2 * eye, m[:, :, None] * eye + dt2 * model.K_diag),
        lower=jnp.where(con, 0.0, dt2 * model.K_lower),
        upper=jnp.where(con, 0.0, dt2 * model.K_upper),
        C=jnp.where(con, -dt2 * R, 0.0),
        D=jnp.where(dyn[None, :, None], D, 0.0),
        E=jnp.diag(jnp.where(dyn, model.M_roller, dt2)),
    )
