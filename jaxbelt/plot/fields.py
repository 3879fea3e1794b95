"""The belt's fields over time and along the belt: heat maps of the displacements, the segments (arcs and spans) and the tracers' positions, labels and line styles."""

from __future__ import annotations

import numpy as np

from ._common import pyplot


def tracer_styles(model):
    """Matplotlib line styles per tracer: one colour per belt segment (:func:`belt_segments`),
    the line style changing along it, so that the legend (:func:`tracer_labels`) tells them apart."""
    segs = belt_segments(model)
    xt, _ = tracer_positions(model)
    seg_of = [next((k for k, s in enumerate(segs) if s["x0"] - 1e-12 <= x < s["x1"] - 1e-12), len(segs) - 1)
              for x in xt]
    dashes = ["-", "--", "-.", ":", (0, (5, 1, 1, 1, 1, 1))]
    count, out = {}, []
    for k in seg_of:
        n = count.get(k, 0)
        count[k] = n + 1
        out.append(dict(color=f"C{k % 10}", ls=dashes[n % len(dashes)]))
    return out


def tracer_legend(ax, labels):
    ax.legend(fontsize=6, ncol=max(1, int(np.ceil(len(labels) / 18))), loc="upper left",
              bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, title="tracers", title_fontsize=7)


def _grid(obj):
    """``(x, ell, node_roller, z, names)`` of a :class:`~jaxbelt.BeltModel` or a :class:`~jaxbelt.Mesh`."""
    x, ell, nr = (np.asarray(getattr(obj, k)) for k in ("x", "ell", "node_roller"))
    z = np.asarray(obj.z0 if hasattr(obj, "z0") else obj.z)
    if hasattr(obj, "roller_names"):
        names = list(obj.roller_names)
    else:
        names = [s.name for s in obj.path.segments if s.kind == "roller"]
    return x, ell, nr, z, names


def belt_segments(model):
    """The segments of the unrolled belt in path order: roller arcs and free spans.

    **Arguments:** ``model``: a :class:`~jaxbelt.BeltModel` (or a :class:`~jaxbelt.Mesh`).

    **Returns:** a list of dicts ``{"kind": "roller" | "free", "roller": j, "x0": m, "x1": m,
    "label": str}``: the arc of roller ``j`` (labelled with its name) runs between its two contact
    lines; free span ``j`` (labelled ``"span j+1"``) leaves roller ``j`` and ends on the next one.
    Their lengths add up to the belt length.
    """
    x, ell, nr, _, names = _grid(model)
    length = float(x[-1] + ell[-1])
    out = []
    for j, name in enumerate(names):
        cols = np.flatnonzero(nr == j)
        x0, x1 = float(x[cols[0]]), float(x[cols[-1]])
        nxt = np.flatnonzero(nr == (j + 1) % len(names))[0]
        x2 = float(x[nxt]) + (length if j == len(names) - 1 else 0.0)
        out.append(dict(kind="roller", roller=j, x0=x0, x1=x1, label=name))
        out.append(dict(kind="free", roller=j, x0=x1, x1=x2, label=f"span {j + 1}"))
    return out


def tracer_positions(model):
    """``(x, z)`` (m) of every tracer: arc length along the belt and lateral position, from a
    :class:`~jaxbelt.BeltModel` (element column + local coordinates) or a :class:`~jaxbelt.Mesh`."""
    if hasattr(model, "tracer_x"):
        return np.asarray(model.tracer_x, float), np.asarray(model.tracer_z, float)
    x, ell, _, z, _ = _grid(model)
    col, xi = np.asarray(model.tracer_col), np.asarray(model.tracer_xi)
    xt = x[col] + xi * ell[col]
    if len(z) == 1:
        return xt, np.zeros_like(xt)
    row, eta = np.asarray(model.tracer_row), np.asarray(model.tracer_eta)
    return xt, z[row] + eta * (z[row + 1] - z[row])


def tracer_labels(model):
    """One label per tracer: its segment and the position along it in the direction of motion,
    and in 2D its lateral position — ``"span 2, 40 % / z = +20 mm"``, ``"drive, 50 %"``
    (roller arcs carry the roller's name). ``model``: a :class:`~jaxbelt.BeltModel` or a
    :class:`~jaxbelt.Mesh`."""
    segs = belt_segments(model)
    xt, zt = tracer_positions(model)
    lateral = len(_grid(model)[3]) > 1
    labels = []
    for x, z in zip(xt, zt):
        s = next((s for s in segs if s["x0"] - 1e-12 <= x < s["x1"] - 1e-12), segs[-1])
        frac = (x - s["x0"]) / (s["x1"] - s["x0"])
        lab = f"{s['label']}, {100 * frac:.0f} %"
        labels.append(lab + (f" / z = {z * 1e3:+.0f} mm" if lateral else ""))
    return labels


def _mark_segments(ax, segs, top_labels=True):
    """Dashed lines at the contact lines, a dark band over the roller arcs along the top edge and
    the segment names on a secondary x axis at the top (mm)."""
    for s in segs:
        if s["kind"] == "roller":
            ax.axvspan(s["x0"] * 1e3, s["x1"] * 1e3, ymin=0.96, ymax=1.0, color="0.25", lw=0)
            for xc in (s["x0"], s["x1"]):
                ax.axvline(xc * 1e3, color="k", lw=0.6, ls="--", alpha=0.6)
    if top_labels:
        sec = ax.secondary_xaxis("top")
        sec.set_xticks([0.5e3 * (s["x0"] + s["x1"]) for s in segs], [s["label"] for s in segs], fontsize=7)
        sec.tick_params(length=0)
    return ax


# ----------------------------------------------------------------------------- full fields


def _field_components(model, components):
    kinds = ("u",) if model.kind == "1d" else ("u", "v")
    if components is None:
        return kinds
    comps = (components,) if isinstance(components, str) else tuple(components)
    for c in comps:
        if c not in ("u", "v"):
            raise ValueError(f"components: {c!r} is not a field component (expected 'u' or 'v')")
        if c == "v" and model.kind == "1d":
            raise ValueError("components: 'v' asked of a 1D model, which has no lateral displacement "
                             "(only 'u'); use a 2D scene")
    if not comps:
        raise ValueError("components: empty")
    return comps


def select_times(t, times, spacing=None):
    """Indices of the recorded times ``t`` nearest to ``times`` (s), with their check.

    ``times=None`` gives three evenly spaced recorded times, the last one included. A time
    farther than half the recording interval ``spacing`` (default: from ``t``) outside
    ``[t[0], t[-1]]``, or not finite, raises :class:`ValueError` naming it and the range.
    """
    t = np.asarray(t, float).reshape(-1)
    if t.size == 0:
        raise ValueError("the trajectory is empty (no recorded steps)")
    if times is None:
        return [int(i) for i in np.unique(np.linspace(0, t.size - 1, min(3, t.size)).round().astype(int))]
    times = np.atleast_1d(np.asarray(times, float))
    if times.size == 0:
        raise ValueError("times: empty")
    h = spacing if spacing is not None else (float(np.min(np.diff(t))) if t.size > 1 else float(t[0]))
    idx = []
    for tt in times:
        if not np.isfinite(tt) or tt < t[0] - 0.5 * h or tt > t[-1] + 0.5 * h:
            raise ValueError(f"times: t = {tt:g} s is outside the run (recorded {t[0]:g} … {t[-1]:g} s)")
        idx.append(int(np.argmin(np.abs(t - tt))))
    return idx


def field_values(model, u, component):
    """One component of full fields ``u`` ((n_xi, b) or (k, n_xi, b), as ``Trajectory.u`` /
    ``BeltState.u``) on the node grid, in m: ``(..., n_eta, n_xi)`` (rows = lateral positions
    ``model.z0``, columns = ``model.x``). ``component``: ``"u"`` (along the belt) or ``"v"``
    (lateral, 2D only)."""
    (c,) = _field_components(model, component)
    u = np.asarray(u, float)
    f = u[..., 0::2] if model.kind == "2d" and c == "u" else u[..., 1::2] if c == "v" else u
    return np.swapaxes(f, -1, -2)


def _full_fields(traj):
    u = getattr(traj, "u", None)
    if u is None:
        raise ValueError("the trajectory holds no full fields (Trajectory.u is None): simulate with "
                         "saveat=jaxbelt.SaveAt(fields=True) (a scene's [output] fields = \"full\" sets it in "
                         "jaxbelt.RunOptions.from_scene)")
    return np.asarray(traj.t, float), np.asarray(u, float)


def plot_fields(model, traj, times=None, components=None, ax=None, cmap="RdBu_r", title=None):
    """Heat maps of the displacement fields over the unrolled belt at chosen times.

    x axis: arc length along the belt path (mm, from the incoming contact line of roller 1, in the
    direction of motion), with the roller arcs marked (dark band on top, dashed contact lines,
    segment names on the top axis); y axis: the lateral position z (mm). Colour: the
    displacement in mm (nodal values, interpolated between the nodes), one colour scale per
    component shared by all times, symmetric about 0. One row per time, one column per component.
    In 1D (no lateral extent) each panel is a single strip.

    **Arguments:**

    - ``model``: the :class:`~jaxbelt.BeltModel` that was simulated.
    - ``traj``: its :class:`~jaxbelt.Trajectory` with full fields (``traj.u``, from
      ``jaxbelt.simulate(..., saveat=SaveAt(fields=True))``), or anything with ``t`` (k,) and
      ``u`` (k, n_xi, b).
    - ``times``: times (s); each is drawn at the nearest recorded time (the panel title gives it).
      Default: three evenly spaced recorded times, the last one included. A time more than half a
      recording interval (the spacing of ``traj.t``) outside the run raises :class:`ValueError`.
    - ``components``: ``"u"``, ``"v"`` or both (default: ``("u", "v")`` in 2D, ``("u",)`` in 1D;
      ``"v"`` of a 1D model raises :class:`ValueError`).
    - ``ax``: axes to draw into, ``len(times) × len(components)`` of them (any array shape, read
      row by row); default a new figure.

    **Returns:** the axes, an array of shape ``(len(times), len(components))``; the k-th row's
    ``QuadMesh`` holds the drawn values (mm) with the loop closed (column 0 repeated at the belt
    length): ``axes[k, c].collections[0].get_array()`` of shape ``(n_eta, n_xi + 1)`` (1D: 2 rows).
    """
    comps = _field_components(model, components)
    t, u = _full_fields(traj)
    idx = select_times(t, times)
    n_r, n_c = len(idx), len(comps)
    z = np.asarray(model.z0) * 1e3
    one_row = z.size == 1
    if ax is None:
        plt = pyplot()
        fig, axes = plt.subplots(n_r, n_c, figsize=(6.5 * n_c, 1.6 + (1.1 if one_row else 1.9) * n_r),
                                 constrained_layout=True, squeeze=False)
    else:
        axes = np.asarray(ax, dtype=object).reshape(-1)
        if axes.size != n_r * n_c:
            raise ValueError(f"ax: {axes.size} axes given for {n_r} time(s) × {n_c} component(s)")
        axes = axes.reshape(n_r, n_c)
        fig = axes[0, 0].figure
    x = np.asarray(model.x) * 1e3
    length = float(np.asarray(model.x)[-1] + np.asarray(model.ell)[-1]) * 1e3
    xc = np.append(x, length)
    zc = np.array([-0.5, 0.5]) if one_row else z
    X, Z = np.meshgrid(xc, zc)
    segs = belt_segments(model)
    for c, comp in enumerate(comps):
        vals = field_values(model, u[idx], comp) * 1e3  # (k, n_eta, n_xi) mm
        vals = np.concatenate([vals, vals[..., :1]], axis=-1)  # close the loop
        if one_row:
            vals = np.repeat(vals, 2, axis=-2)
        vmax = float(np.max(np.abs(vals))) or 1.0
        for r, k in enumerate(idx):
            a = axes[r, c]
            mesh = a.pcolormesh(X, Z, vals[r], shading="gouraud", cmap=cmap, vmin=-vmax, vmax=vmax)
            _mark_segments(a, segs, top_labels=(r == 0))
            a.set_xlim(0, length)
            a.set_title(f"{comp} at t = {t[k]:.4g} s" + (f" — {title}" if title and r == 0 and c == 0 else ""),
                        fontsize=9)
            if one_row:
                a.set_yticks([])
                a.set_ylabel("1D: no lateral extent", fontsize=8)
            else:
                a.set_ylabel("z [mm]")
            if r == n_r - 1:
                a.set_xlabel("arc length along the belt x [mm] (dark: roller arcs)")
        label = "u (along the belt) [mm]" if comp == "u" else "v (lateral) [mm]"
        fig.colorbar(mesh, ax=list(axes[:, c]), label=label, shrink=0.9)
    return axes
