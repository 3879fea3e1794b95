"""The belt in 3D: its surface over the rollers, displaced and coloured by a field."""

from __future__ import annotations

import numpy as np

from ..rollers import rotation_xyz
from ._common import pyplot
from .fields import field_values


def _reconstruct_centres(model):
    """Roller centres (p, 2), m, relative to roller 1's centre, from the node geometry of the model:
    each arc's nodes lie at ``c_j + r_j n(θ)``, each free span is the straight line of its length
    leaving an arc along the tangent ``s (−sin θ, cos θ)``."""
    x, nr = np.asarray(model.x), np.asarray(model.node_roller)
    th, rad, sense = (np.asarray(getattr(model, k)) for k in ("node_theta", "node_radius", "node_sense"))
    p = model.n_rollers
    n = lambda a: np.array([np.cos(a), np.sin(a)])  # noqa: E731
    c = np.zeros((p, 2))
    for j in range(p - 1):
        cols = np.flatnonzero(nr == j)
        i_out, i_in = cols[-1], np.flatnonzero(nr == j + 1)[0]
        p_out = c[j] + rad[i_out] * n(th[i_out])
        e = sense[i_out] * np.array([-np.sin(th[i_out]), np.cos(th[i_out])])
        p_in = p_out + (x[i_in] - x[i_out]) * e
        c[j + 1] = p_in - rad[i_in] * n(th[i_in])
    return c


def belt_geometry_3d(model, mesh=None):
    """Reference position of every belt node in 3D, m: ``(n_xi, n_eta, 3)`` as ``(x³ᴰ, y³ᴰ, z)``
    with the unit tangent ``t`` (direction of motion) and the outward normal ``n`` of each column
    (n_xi, 3) each, and the roller centres (p, 2). The centres come from ``mesh.path`` when a
    :class:`~jaxbelt.Mesh` is given, otherwise from the model's node geometry with roller 1 at the
    origin (:func:`belt_segments`: arcs at their radius and wrap angles, straight free spans)."""
    x, nr = np.asarray(model.x), np.asarray(model.node_roller)
    th, rad, sense = (np.asarray(getattr(model, k)) for k in ("node_theta", "node_radius", "node_sense"))
    centres = np.asarray(mesh.path.centers, float) if mesh is not None else _reconstruct_centres(model)
    length = float(x[-1] + np.asarray(model.ell)[-1])
    on = nr >= 0
    j = np.maximum(nr, 0)
    nvec = np.stack([np.cos(th), np.sin(th)], axis=1)
    pts = np.where(on[:, None], centres[j] + rad[:, None] * nvec, np.nan)
    tang = np.where(on[:, None], sense[:, None] * np.stack([-np.sin(th), np.cos(th)], axis=1), np.nan)
    # free spans: straight lines between the last node of an arc and the first of the next
    cols_on = np.flatnonzero(on)
    for i in np.flatnonzero(~on):
        a = cols_on[cols_on < i].max() if np.any(cols_on < i) else cols_on.max()
        b = cols_on[cols_on > i].min() if np.any(cols_on > i) else cols_on.min()
        xa, xb = x[a] - (length if a > i else 0.0), x[b] + (length if b < i else 0.0)
        f = (x[i] - xa) / (xb - xa)
        pts[i] = (1 - f) * pts[a] + f * pts[b]
        d = pts[b] - pts[a]
        tang[i] = d / np.linalg.norm(d)
    normal = np.stack([tang[:, 1], -tang[:, 0]], axis=1)  # right of the motion
    normal = np.where(on[:, None], nvec, normal)
    z = np.asarray(model.z0)
    P = np.concatenate([np.repeat(pts[:, None, :], z.size, 1), np.broadcast_to(z[None, :, None], (x.size, z.size, 1))], 2)
    zero = np.zeros((x.size, 1))
    return P, np.concatenate([tang, zero], 1), np.concatenate([normal, zero], 1), centres


def _roller_frames(model, chi, scale):
    """Per roller: centre offset (3,) and rotation (3, 3) of its static/solved motion, scaled."""
    p, dofs = model.n_rollers, model.dofs
    chi = np.asarray(chi, float).reshape(p, len(dofs))
    get = lambda k: chi[:, dofs.index(k)] if k in dofs else np.zeros(p)  # noqa: E731
    d = scale * np.stack([get("dx"), get("dy"), get("dz")], 1)
    Q = np.stack([np.asarray(rotation_xyz(scale * a, scale * b, 0.0)) for a, b in zip(get("ax"), get("ay"))])
    return d, Q


def belt_surface_3d(model, u, chi=None, mesh=None, exaggerate=1.0):
    """The belt surface that :func:`plot_belt_3d` draws: node positions in 3D (m) displaced by
    ``exaggerate × (u t + v e_z + w n)`` (``w``: the normal motion of the roller surface under
    ``chi`` on the arcs, interpolated linearly over the free spans; the model has no normal
    unknown).

    **Returns:** a dict with ``points`` (n_xi, n_eta, 3) as ``(x³ᴰ, y³ᴰ, z)``, the reference
    ``reference`` (same shape), the fields ``u``, ``v``, ``w`` (n_xi, n_eta) in m, and the roller
    ``centres`` (p, 2) (:func:`belt_geometry_3d`).
    """
    u = np.asarray(u, float)
    chi = np.asarray(model.chi_static if chi is None else chi, float).reshape(-1)
    P, tang, normal, centres = belt_geometry_3d(model, mesh)
    d, Q = _roller_frames(model, chi, 1.0)
    nr = np.asarray(model.node_roller)
    # normal motion of the roller surface under the (unscaled) roller motion, on arc nodes
    j = np.maximum(nr, 0)
    c3 = np.concatenate([centres, np.zeros((len(centres), 1))], 1)
    rel = P - c3[j][:, None, :]
    moved = d[j][:, None, :] + np.einsum("nab,nkb->nka", Q[j], rel) - rel
    w = np.einsum("nka,na->nk", moved, normal)
    on = nr >= 0
    cols_on, x = np.flatnonzero(on), np.asarray(model.x)
    length = float(x[-1] + np.asarray(model.ell)[-1])
    xa_ext = np.concatenate([x[cols_on] - length, x[cols_on], x[cols_on] + length])
    w_ext = np.concatenate([w[cols_on]] * 3)
    w = np.stack([np.interp(x, xa_ext, w_ext[:, k]) for k in range(w.shape[1])], 1)
    fu = field_values(model, u, "u").T  # (n_xi, n_eta)
    fv = field_values(model, u, "v").T if model.kind == "2d" else np.zeros_like(fu)
    disp = fu[..., None] * tang[:, None, :] + fv[..., None] * np.array([0.0, 0.0, 1.0]) + w[..., None] * normal[:, None, :]
    return dict(points=P + exaggerate * disp, reference=P, u=fu, v=fv, w=w, centres=centres)


def plot_belt_3d(model, u, chi=None, mesh=None, color_by="magnitude", exaggerate=1.0, ax=None,
                 cmap="viridis", title=None, roller_alpha=0.25):
    """3D view (``mplot3d``) of the rollers and the belt surface coloured by its displacement.

    Rollers are drawn as cylinders of their radius and face width at their centres, moved and
    tilted by their DOFs ``chi`` (translations ``d_x, d_y, d_z``, tilts ``α_x, α_y``); the belt as
    the surface of its node grid (2D) or a line (1D), coloured per element by ``color_by``:
    ``"magnitude"`` (``√(u² + v²)``; ``|u|`` in 1D), ``"u"`` or ``"v"`` (mm, of the true field).
    With ``exaggerate = f`` the belt displacements and the roller motions are drawn ``f`` times
    their size (the title states it): a belt node moves by ``f (u t + v e_z + w n)`` — ``t`` the
    tangent, ``n`` the outward normal; the model has no normal unknown, so ``w`` is the normal
    motion of the roller surface on the arcs and is interpolated linearly over the free spans.
    Plot axes: ``x³ᴰ`` and the lateral ``z`` horizontal, ``y³ᴰ`` up (mm).

    **Arguments:**

    - ``model``: the :class:`~jaxbelt.BeltModel`.
    - ``u``: a belt field (n_xi, b): ``state.u`` of :func:`jaxbelt.simulate`'s final state or
      ``traj.u[k]``.
    - ``chi``: roller DOFs (q,) or (p, d) at that time (``state.chi``, ``traj.roller_state[k]``);
      default ``model.chi_static``. The rotation about the roller axis is not drawn.
    - ``mesh``: the scene's :class:`~jaxbelt.Mesh` for the absolute roller positions (default:
      reconstructed from the model, roller 1 at the origin).
    - ``exaggerate``: the factor ``f`` (≥ 0; 0 draws the reference geometry).
    - ``ax``: a 3D axes (``projection="3d"``); default a new figure.

    **Returns:** the axes; its belt collection (``ax.collections[0]``) holds the colour values
    (mm) per element (2D: ``n_xi × (n_eta − 1)`` quads, column by column) in ``get_array()``.
    """
    if not np.isfinite(exaggerate) or exaggerate < 0:
        raise ValueError(f"exaggerate = {exaggerate}: must be a finite number ≥ 0")
    if color_by not in ("magnitude", "u", "v"):
        raise ValueError(f"color_by = {color_by!r}: expected 'magnitude', 'u' or 'v'")
    if color_by == "v" and model.kind == "1d":
        raise ValueError("color_by = 'v' asked of a 1D model, which has no lateral displacement")
    u = np.asarray(u, float)
    if u.shape != (model.n_xi, model.block):
        raise ValueError(f"u: shape {u.shape}, expected (n_xi, b) = {(model.n_xi, model.block)} "
                         "(one time: state.u or traj.u[k])")
    chi = np.asarray(model.chi_static if chi is None else chi, float).reshape(-1)
    from matplotlib.colors import Normalize
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    if ax is None:
        plt = pyplot()
        fig = plt.figure(figsize=(9, 7), constrained_layout=True)
        ax = fig.add_subplot(projection="3d")
    fig = ax.figure
    surf = belt_surface_3d(model, u, chi, mesh, exaggerate)
    Pd, fu, fv, centres = surf["points"], surf["u"], surf["v"], surf["centres"]
    c3 = np.concatenate([centres, np.zeros((len(centres), 1))], 1)
    nr = np.asarray(model.node_roller)
    val = {"u": fu, "v": fv, "magnitude": np.hypot(fu, fv)}[color_by] * 1e3
    to_plot = lambda a: np.stack([a[..., 0], a[..., 2], a[..., 1]], -1) * 1e3  # noqa: E731  (x, z, y) mm
    Pp = to_plot(np.concatenate([Pd, Pd[:1]], 0))  # closed loop
    vc = np.concatenate([val, val[:1]], 0)
    if model.kind == "2d":
        quads = np.stack([Pp[:-1, :-1], Pp[1:, :-1], Pp[1:, 1:], Pp[:-1, 1:]], 2).reshape(-1, 4, 3)
        cval = 0.25 * (vc[:-1, :-1] + vc[1:, :-1] + vc[1:, 1:] + vc[:-1, 1:]).reshape(-1)
        coll = Poly3DCollection(quads, cmap=cmap, edgecolor="none", linewidth=0)
    else:
        segs = np.stack([Pp[:-1, 0], Pp[1:, 0]], 1)
        cval = 0.5 * (vc[:-1, 0] + vc[1:, 0])
        coll = Line3DCollection(segs, cmap=cmap, linewidth=3)
    coll.set_array(cval)
    lo, hi = float(cval.min()), float(cval.max())
    coll.set_norm(Normalize(lo, hi if hi > lo else lo + 1e-12))
    ax.add_collection3d(coll)
    fig.colorbar(coll, ax=ax, shrink=0.6, label={"magnitude": "|(u, v)|" if model.kind == "2d" else "|u|",
                                                  "u": "u (along the belt)", "v": "v (lateral)"}[color_by] + " [mm]")
    # rollers
    d_s, Q_s = _roller_frames(model, chi, exaggerate)
    radius = np.array([np.asarray(model.node_radius)[nr == k][0] for k in range(model.n_rollers)])
    hw = np.asarray(model.roller_half_width)
    phi = np.linspace(0, 2 * np.pi, 41)
    extent = [Pp.reshape(-1, 3)]
    for k in range(model.n_rollers):
        local = np.stack(np.broadcast_arrays(radius[k] * np.cos(phi)[:, None], radius[k] * np.sin(phi)[:, None],
                                             np.array([-hw[k], hw[k]])[None, :]), -1)  # (41, 2, 3)
        pp = to_plot(c3[k] + d_s[k] + local @ Q_s[k].T)
        extent.append(pp.reshape(-1, 3))
        ax.plot_surface(pp[..., 0], pp[..., 1], pp[..., 2], color="tab:grey", alpha=roller_alpha, linewidth=0,
                        shade=True)
        for e in range(2):
            ax.plot(pp[:, e, 0], pp[:, e, 1], pp[:, e, 2], color="0.3", lw=0.8)
        axis = to_plot(c3[k] + d_s[k] + np.outer([-1.15 * hw[k], 1.15 * hw[k]], Q_s[k][:, 2]))
        ax.plot(axis[:, 0], axis[:, 1], axis[:, 2], color="k", lw=1, ls="-.")
        ax.text(*axis[1], model.roller_names[k], fontsize=8)
    allp = np.concatenate(extent)
    lo3, hi3 = allp.min(0), allp.max(0)
    pad = 0.05 * (hi3 - lo3).max()
    ax.set_xlim(lo3[0] - pad, hi3[0] + pad)
    ax.set_ylim(lo3[1] - pad, hi3[1] + pad)
    ax.set_zlim(lo3[2] - pad, hi3[2] + pad)
    ax.set_box_aspect(tuple(hi3 - lo3 + 2 * pad))
    ax.set_xlabel("x³ᴰ [mm]")
    ax.set_ylabel("z (lateral) [mm]")
    ax.set_zlabel("y³ᴰ [mm]")
    ex = f"displacements × {exaggerate:g}" if exaggerate != 1 else "displacements to scale"
    ax.set_title((title + "\n" if title else "") + f"belt coloured by {color_by} [mm]; {ex}", fontsize=9)
    return ax
