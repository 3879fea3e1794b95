"""Figures (matplotlib, imported lazily: nothing else in jaxbelt imports this module).

Displacements are drawn in mm and times in s, as in the source's figures.
"""

from __future__ import annotations

import numpy as np


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_run(traj, mesh, path, times=None, title: str = ""):
    """Tracer trajectories over time and the displacement along the belt at chosen times.

    **Arguments:** ``traj``: a :class:`~jaxbelt.Trajectory`; ``mesh``: the scene's
    :class:`~jaxbelt.Mesh`; ``path``: output PNG; ``times``: times (s) for the profile panel
    (default: four evenly spaced). With ``fields = "full"`` the profile is the whole grid,
    otherwise the tracers.
    """
    plt = _plt()
    t = np.asarray(traj.t)
    tu = np.asarray(traj.tracer_u) * 1e3
    lateral = traj.tracer_v is not None
    fig, axes = plt.subplots(3 if lateral else 2, 1, figsize=(9, 10 if lateral else 7.5), constrained_layout=True)
    ax1, ax2 = axes[0], axes[-1]
    for k in range(tu.shape[1]):
        ax1.plot(t, tu[:, k], lw=0.8)
    ax1.set_xlabel("t [s]")
    ax1.set_ylabel("tracer displacement u (x) [mm]")
    ax1.set_title(title or "tracer trajectories")
    ax1.grid(alpha=0.3)
    if lateral:
        tv = np.asarray(traj.tracer_v) * 1e3
        for k in range(tv.shape[1]):
            axes[1].plot(t, tv[:, k], lw=0.8)
        axes[1].set_xlabel("t [s]")
        axes[1].set_ylabel("tracer displacement v (z) [mm]")
        axes[1].grid(alpha=0.3)

    if times is None:
        times = t[np.linspace(0, len(t) - 1, 4).astype(int)]
    idx = [int(np.argmin(np.abs(t - tt))) for tt in times]
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
    ax2.set_xlabel("position along the belt x [mm] (dashed: roller arc starts, dotted: free spans)")
    ax2.set_ylabel("u [mm]")
    ax2.legend(fontsize=8)
    ax2.grid(alpha=0.3)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def plot_scene(scene, mesh, path):
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
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


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


def plot_reduction(report, t, rmse_mm, path, singular_values=None, eigs=None, eig_weights=None,
                   estimate_t=None, estimate_mm=None, tol_mm=0.02):
    """The figure of ``jaxbelt reduce --plot``: singular values of the training snapshots (with
    ``report["modes"]`` marked), the DMD eigenvalues when ``eigs`` is given (DMD-type methods),
    and the RMSE over time ``t`` (s) with the indicator estimate — a 1 × 3 figure, or 1 × 2
    without eigenvalues. ``report``: the dict the command prints (scene, method, modes, rmse_mm).
    Returns ``path``."""
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
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


# ----------------------------------------------------------------------------- tolerance design


def plot_sensitivity(report: dict, path):
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
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_tolerance_box(result: dict, path):
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
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_yield(metric_values, limit_um: float, result: dict, path):
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
    fig.savefig(path, dpi=120)
    plt.close(fig)
