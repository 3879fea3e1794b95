"""Figures (matplotlib, imported lazily: nothing else in jaxbelt imports this module).

Displacements are drawn in mm and times in s, as in the source's figures.

The functions that draw a whole figure (:func:`plot_run`, :func:`plot_scene`,
:func:`plot_reduction`, :func:`plot_sensitivity`, :func:`plot_tolerance_box`, :func:`plot_yield`)
write a PNG and return its path when given ``path``; with ``path=None`` they return the open
:class:`matplotlib.figure.Figure` (shown inline in Jupyter). The panel functions take an ``ax``.
This module never selects a matplotlib backend: a notebook keeps its inline backend; the command
line sets ``MPLBACKEND=Agg`` (unless the user set one) before matplotlib is imported.
"""

from __future__ import annotations

import numpy as np


def _plt():
    import matplotlib.pyplot as plt  # the user's / environment's backend (see the module docstring)

    return plt


def _finish(fig, path, dpi=120):
    """Write ``fig`` to ``path`` and close it (returns ``path``), or return the open figure when
    ``path`` is ``None``."""
    if path is None:
        return fig
    fig.savefig(path, dpi=dpi)
    _plt().close(fig)
    return path


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


def _tracer_legend(ax, labels):
    ax.legend(fontsize=6, ncol=max(1, int(np.ceil(len(labels) / 18))), loc="upper left",
              bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, title="tracers", title_fontsize=7)


def plot_run(traj, mesh, path=None, times=None, title: str = ""):
    """Tracer trajectories over time and the displacement along the belt at chosen times.

    **Arguments:** ``traj``: a :class:`~jaxbelt.Trajectory`; ``mesh``: the scene's
    :class:`~jaxbelt.Mesh`; ``path``: output PNG (``None``: return the figure); ``times``: times (s) for the profile panel
    (default: four evenly spaced). With ``fields = "full"`` the profile is the whole grid,
    otherwise the tracers. Every tracer is labelled with its segment and position
    (:func:`tracer_labels`, e.g. ``"span 2, 40 % / z = +20 mm"``).
    """
    plt = _plt()
    t = np.asarray(traj.t)
    tu = np.asarray(traj.tracer_u) * 1e3
    lateral = traj.tracer_v is not None
    labels, styles = tracer_labels(mesh), tracer_styles(mesh)
    fig, axes = plt.subplots(3 if lateral else 2, 1, figsize=(11, 10 if lateral else 7.5), constrained_layout=True)
    ax1, ax2 = axes[0], axes[-1]
    for k in range(tu.shape[1]):
        ax1.plot(t, tu[:, k], lw=0.8, label=labels[k], **styles[k])
    ax1.set_xlabel("t [s]")
    ax1.set_ylabel("tracer displacement u (x) [mm]")
    ax1.set_title(title or "tracer trajectories")
    ax1.grid(alpha=0.3)
    _tracer_legend(ax1, labels)
    if lateral:
        tv = np.asarray(traj.tracer_v) * 1e3
        for k in range(tv.shape[1]):
            axes[1].plot(t, tv[:, k], lw=0.8, **styles[k])
        axes[1].set_xlabel("t [s]")
        axes[1].set_ylabel("tracer displacement v (z) [mm]\n(tracers as above)")
        axes[1].grid(alpha=0.3)

    if times is None:
        idx = [int(i) for i in np.linspace(0, len(t) - 1, 4).astype(int)]
    else:  # the nearest recorded times; ValueError for a time outside the run
        idx = select_times(t, times)
    seg_x = np.asarray(mesh.x)[np.asarray(mesh.segment_starts)] * 1e3
    if traj.u is not None:
        x = np.asarray(mesh.x) * 1e3
        prof = np.asarray(traj.u)[:, :, 0 if mesh.n_eta == 1 else 2 * (mesh.n_eta // 2)] * 1e3  # centre row
        for i in idx:
            ax2.plot(x, prof[i], lw=1, label=f"t = {t[i]:.3g} s")
    else:
        order = np.argsort(mesh.tracer_x)
        x = np.asarray(mesh.tracer_x)[order] * 1e3
        for i in idx:
            ax2.plot(x, tu[i, order], "o-", ms=3, lw=1, label=f"t = {t[i]:.3g} s")
    for k, xs in enumerate(seg_x):
        ax2.axvline(xs, color="0.6", lw=0.7, ls="--" if k % 2 == 0 else ":")
    segs = belt_segments(mesh)
    top = ax2.secondary_xaxis("top")
    top.set_xticks([0.5e3 * (g["x0"] + g["x1"]) for g in segs], [g["label"] for g in segs], fontsize=7)
    top.tick_params(length=0)
    ax2.set_xlabel("position along the belt x [mm] (dashed: roller arc starts, dotted: free spans)")
    ax2.set_ylabel("u [mm]")
    ax2.legend(fontsize=8)
    ax2.grid(alpha=0.3)
    return _finish(fig, path)


def plot_scene(scene, mesh, path=None):
    """Rollers, belt path, contact points and tracer points in the (x³ᴰ, y³ᴰ) plane (mm), as the
    source's Figures 2.2 / 7.1."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(8, 6), constrained_layout=True)
    for j, r in enumerate(scene.rollers):
        c = np.array(r.center) * 1e3
        style = dict(fill=False, lw=1.5, color="tab:red" if r.external else "tab:blue")
        ax.add_patch(plt.Circle(c, r.radius * 1e3, **style))
        ax.annotate(f"{j + 1}: {r.name}\n({r.role}{', external' if r.external else ''})", c, ha="center",
                    va="center", fontsize=8)
    # belt path: arcs and spans
    for seg in mesh.path.segments:
        if seg.kind == "free":
            pts = np.stack([seg.start, seg.end]) * 1e3
        else:
            j = seg.index
            th = seg.theta_in + seg.sense * seg.wrap * np.linspace(0, 1, 60)
            pts = (mesh.path.centers[j] + mesh.path.radii[j] * np.stack([np.cos(th), np.sin(th)], 1)) * 1e3
        ax.plot(pts[:, 0], pts[:, 1], color="k", lw=1)
        ax.plot(*(seg.start * 1e3), "o", color="tab:orange", ms=4)
    # tracers: position along the path → point in the plane
    xs = np.cumsum([0.0] + [s.length for s in mesh.path.segments])
    for xt in mesh.tracer_x:
        k = int(np.searchsorted(xs, xt, side="right") - 1)
        seg, f = mesh.path.segments[k], (xt - xs[k]) / mesh.path.segments[k].length
        if seg.kind == "free":
            p = seg.start + f * (seg.end - seg.start)
        else:
            th = seg.theta_in + seg.sense * seg.wrap * f
            p = mesh.path.centers[seg.index] + mesh.path.radii[seg.index] * np.array([np.cos(th), np.sin(th)])
        ax.plot(*(p * 1e3), "x", color="tab:green", ms=5)
    ax.plot([], [], "o", color="tab:orange", label="contact lines")
    ax.plot([], [], "x", color="tab:green", label="tracer points")
    ax.set_aspect("equal")
    ax.set_xlabel("x³ᴰ [mm]")
    ax.set_ylabel("y³ᴰ [mm]")
    ax.set_title(f"{scene.name}: belt path {mesh.length * 1e3:.1f} mm")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    return _finish(fig, path)


# -- model order reduction (``jaxbelt reduce``) ------------------------------------------------


def _ax(ax, figsize=(6, 4.5)):
    """``ax`` or a new single-panel figure; returns ``(fig or None, ax)``."""
    if ax is not None:
        return None, ax
    plt = _plt()
    fig, ax = plt.subplots(figsize=figsize, constrained_layout=True)
    return fig, ax


def plot_singular_values(s, n_modes=None, ax=None):
    """Normalised singular values ``σ_i / σ_0`` of a snapshot matrix (semilog), the source's
    Figures 6.2 / 7.3, with the chosen number of modes ``n_modes`` marked. Returns the axes."""
    _, ax = _ax(ax)
    s = np.abs(np.asarray(s, float))
    rel = s / s[0] if s.size and s[0] > 0 else s
    i = np.arange(1, rel.size + 1)
    ax.semilogy(i, np.where(rel > 0, rel, np.nan), ".-", ms=3, lw=0.8, color="tab:blue")
    if n_modes is not None and 0 < n_modes <= rel.size:
        ax.axvline(n_modes + 0.5, color="tab:red", lw=1, ls="--", label=f"{n_modes} modes kept")
        ax.semilogy(i[:n_modes], np.where(rel[:n_modes] > 0, rel[:n_modes], np.nan), ".", ms=5, color="tab:red")
        ax.legend(fontsize=8)
    ax.set_xlabel("index i")
    ax.set_ylabel("σᵢ / σ₀")
    ax.set_title("singular values of the snapshots")
    ax.grid(alpha=0.3, which="both")
    return ax


def plot_dmd_eigenvalues(eigs, weights=None, ax=None):
    """DMD eigenvalues in the complex plane with the unit circle (the source's Figure 6.7),
    coloured by ``weights`` — e.g. the scaled mode norms ``‖φ_i b_i‖``
    (:meth:`~jaxbelt.rom.DMDModel.scaled_mode_norms`), on a log scale when they span more than two
    decades — with a colorbar. Returns the axes."""
    plt = _plt()
    fig, ax = _ax(ax, figsize=(5.5, 5))
    lam = np.asarray(eigs).reshape(-1)
    th = np.linspace(0, 2 * np.pi, 400)
    ax.plot(np.cos(th), np.sin(th), color="0.5", lw=0.8, ls="--", label="unit circle")
    if weights is None:
        ax.plot(lam.real, lam.imag, "o", ms=4, mfc="none", color="tab:blue", label=f"{lam.size} eigenvalues")
    else:
        from matplotlib.colors import LogNorm, Normalize

        w = np.abs(np.asarray(weights, float)).reshape(-1)
        pos = w[w > 0]
        log = pos.size > 1 and pos.max() / pos.min() > 100
        norm = LogNorm(pos.min(), pos.max()) if log else Normalize(w.min(), w.max())
        order = np.argsort(w)  # strongest modes drawn last, on top
        sc = ax.scatter(lam.real[order], lam.imag[order], c=np.maximum(w[order], pos.min() if log else 0), s=18,
                        cmap="viridis", norm=norm, label=f"{lam.size} eigenvalues")
        plt.colorbar(sc, ax=ax, label="scaled mode norm ‖φᵢ bᵢ‖")
    ax.set_aspect("equal")
    ax.set_xlabel("Re λ")
    ax.set_ylabel("Im λ")
    ax.set_title("DMD eigenvalues")
    ax.legend(fontsize=8, loc="lower left")
    ax.grid(alpha=0.3)
    return ax


def plot_rmse_over_time(t, rmse_mm, tol_mm=0.02, estimate_mm=None, ax=None, estimate_t=None):
    """Tracer RMSE of a reduced model against the full one at every time step (mm, semilog), the
    tolerance ``tol_mm`` and, optionally, the residual indicator's estimate ``estimate_mm``
    (:func:`jaxbelt.rom.indicator.residual_indicator`) at times ``estimate_t`` (default ``t``).
    Returns the axes."""
    _, ax = _ax(ax)
    t = np.asarray(t, float)
    e = np.asarray(rmse_mm, float)
    ax.semilogy(t, np.where(e > 0, e, np.nan), lw=1, color="tab:blue", label="RMSE vs full model")
    if tol_mm is not None:
        ax.axhline(tol_mm, color="tab:red", lw=1, ls="--", label=f"tolerance {tol_mm:g} mm")
    if estimate_mm is not None:
        est = np.asarray(estimate_mm, float)
        te = t if estimate_t is None else np.asarray(estimate_t, float)
        ax.semilogy(te, np.where(est > 0, est, np.nan), "o-", ms=3, lw=1, color="tab:orange",
                    label="residual indicator estimate")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("tracer RMSE [mm]")
    ax.set_title("error over time")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, which="both")
    return ax


def plot_reduction(report, t, rmse_mm, path=None, singular_values=None, eigs=None, eig_weights=None,
                   estimate_t=None, estimate_mm=None, tol_mm=0.02):
    """The figure of ``jaxbelt reduce --plot``: singular values of the training snapshots (with
    ``report["modes"]`` marked), the DMD eigenvalues when ``eigs`` is given (DMD-type methods),
    and the RMSE over time ``t`` (s) with the indicator estimate — a 1 × 3 figure, or 1 × 2
    without eigenvalues. ``report``: the dict the command prints (scene, method, modes, rmse_mm).
    Returns ``path``, or the figure when ``path`` is ``None``."""
    plt = _plt()
    panels = (singular_values is not None) + (eigs is not None) + 1
    fig, axes = plt.subplots(1, panels, figsize=(5.5 * panels, 4.5), constrained_layout=True)
    axes = np.atleast_1d(axes)
    k = 0
    if singular_values is not None:
        plot_singular_values(singular_values, report.get("modes"), ax=axes[k])
        k += 1
    if eigs is not None:
        plot_dmd_eigenvalues(eigs, eig_weights, ax=axes[k])
        k += 1
    plot_rmse_over_time(t, rmse_mm, tol_mm, estimate_mm, ax=axes[k], estimate_t=estimate_t)
    rm = report.get("rmse_mm")
    fig.suptitle(f"{report.get('scene', '')}: {report.get('method', '')}, {report.get('modes')} modes"
                 + (f", RMSE {rm:.3g} mm" if isinstance(rm, (int, float)) else ""))
    return _finish(fig, path)


# ----------------------------------------------------------------------------- tolerance design


def plot_sensitivity(report: dict, path=None):
    """Bars of the gradient per roller and component (``jaxbelt sensitivity``): translations in
    µm/mm, rotations in µm/mrad, structurally zero components hatched."""
    plt = _plt()
    rollers = list(report["gradient"])
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    zero = {z["component"] for z in report.get("structural_zero", [])}
    for ax, group, unit, comps in ((axes[0], "translation_um_per_mm", "µm/mm", "xyz"),
                                   (axes[1], "rotation_um_per_mrad", "µm/mrad", "xyz")):
        width = 0.8 / len(comps)
        for c, axis in enumerate(comps):
            vals = [report["gradient"][r][group][c] for r in rollers]
            pos = np.arange(len(rollers)) + (c - (len(comps) - 1) / 2) * width
            bars = ax.bar(pos, vals, width, label=axis)
            key = ("d" if group.startswith("translation") else "a") + axis
            for b, r in zip(bars, rollers):
                if f"{r}:{key}" in zero:
                    b.set_hatch("//")
        ax.axhline(0, color="k", lw=0.6)
        ax.set_xticks(np.arange(len(rollers)), rollers)
        ax.set_ylabel(f"d {report['metric']} / d misalignment [{unit}]")
        ax.set_title("translation" if group.startswith("translation") else "rotation (hatched: no static effect)")
        ax.legend(title="axis")
        ax.grid(alpha=0.3, axis="y")
    fig.suptitle(f"{report['metric']} = {report['value_um']:.4g} µm at t = {report['t_eval_s']:.3g} s")
    return _finish(fig, path)


def plot_tolerance_box(result: dict, path=None):
    """Half-widths of the tolerance box per component (log scale), binding components marked,
    capped (unconstrained) ones grey; beside it the verification runs against the limit."""
    plt = _plt()
    labels, h, units = result["labels"], np.asarray(result["half_widths"]), result["units"]
    binding = set(result["binding"][:3])
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 4.5), constrained_layout=True,
                                  gridspec_kw={"width_ratios": [2, 1]})
    colors = ["tab:red" if lab in binding else "tab:grey" if lab in result["unconstrained"] else "tab:blue"
              for lab in labels]
    ax.bar(np.arange(len(h)), h, color=colors)
    ax.set_yscale("log")
    ax.set_xticks(np.arange(len(h)), [f"{lab}\n[{u}]" for lab, u in zip(labels, units)], rotation=60, fontsize=7)
    ax.set_ylabel("half-width (mm or mrad)")
    ax.set_title("tolerance box (red: binding, grey: capped / not felt)")
    ax.grid(alpha=0.3, axis="y")
    rows = result["verification"]
    ax2.scatter([r["predicted_um"] for r in rows], [r["full_um"] for r in rows],
                c=["tab:red" if r["kind"] == "worst corner" else "tab:blue" for r in rows])
    lim = result["limit_um"]
    ax2.axhline(lim, color="k", ls="--", lw=0.8)
    ax2.axhspan(0.97 * lim, lim, color="tab:green", alpha=0.15)
    ax2.plot([0, 1.05 * lim], [0, 1.05 * lim], color="grey", lw=0.6)
    ax2.set_xlabel("linear model [µm]")
    ax2.set_ylabel("full run [µm]")
    ax2.set_title("verification (red: worst corners)")
    fig.suptitle(f"{result['metric']} ≤ {lim:g} µm: verified worst case {result['worst_case_um']:.3f} µm")
    return _finish(fig, path)


def plot_yield(metric_values, limit_um: float, result: dict, path=None):
    """Histogram of the metric over the Monte-Carlo samples with the limit and the yield."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4.2), constrained_layout=True)
    ax.hist(np.asarray(metric_values), bins=40, color="tab:blue", alpha=0.8)
    ax.axvline(limit_um, color="tab:red", lw=1.5, label=f"limit {limit_um:g} µm")
    lo, hi = result["ci95"]
    ax.set_title(f"yield {result['yield']:.4f} (95 %: {lo:.4f}–{hi:.4f}), {result['samples']} samples")
    ax.set_xlabel(f"{result['metric']} [µm]")
    ax.set_ylabel("configurations")
    ax.legend()
    ax.grid(alpha=0.3)
    return _finish(fig, path)


# ----------------------------------------------------------------------------- belt segments and tracer labels


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
        raise ValueError("the trajectory holds no full fields (Trajectory.u is None): simulate a model with "
                         "full_fields=True (model.replace(full_fields=True), or [output] fields = \"full\" "
                         "in the scene)")
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
    - ``traj``: its :class:`~jaxbelt.Trajectory` with full fields (``traj.u``, from a model with
      ``full_fields=True``), or anything with ``t`` (k,) and ``u`` (k, n_xi, b).
    - ``times``: times (s); each is drawn at the nearest recorded time (the panel title gives it).
      Default: three evenly spaced recorded times, the last one included. A time outside the run
      raises :class:`ValueError`.
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
    idx = select_times(t, times, spacing=model.dt * model.every if times is not None else None)
    n_r, n_c = len(idx), len(comps)
    z = np.asarray(model.z0) * 1e3
    one_row = z.size == 1
    if ax is None:
        plt = _plt()
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
    from .rollers import rotation_xyz

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
        plt = _plt()
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
