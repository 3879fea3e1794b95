"""A simulated run's tracer histories and a scene's layout (rollers, belt path, contact and tracer points)."""

from __future__ import annotations

import numpy as np

from ._common import finish_figure, pyplot
from .fields import tracer_legend, belt_segments, select_times, tracer_labels, tracer_styles


def plot_run(traj, mesh, path=None, times=None, title: str = ""):
    """Tracer trajectories over time and the displacement along the belt at chosen times (on a 2D
    belt both components: u along the belt and v across it).

    **Arguments:** ``traj``: a :class:`~jaxbelt.Trajectory`; ``mesh``: the scene's
    :class:`~jaxbelt.Mesh`; ``path``: output PNG (``None``: return the figure); ``times``: times (s) for the profile panel
    (default: four evenly spaced). With ``fields = "full"`` the profile is the whole grid,
    otherwise the tracers. Every tracer is labelled with its segment and position
    (:func:`tracer_labels`, e.g. ``"span 2, 40 % / z = +20 mm"``).
    """
    plt = pyplot()
    t = np.asarray(traj.t)
    tu = np.asarray(traj.tracer_u) * 1e3
    lateral = traj.tracer_v is not None
    steered = getattr(traj, "control_u", None) is not None
    labels, styles = tracer_labels(mesh), tracer_styles(mesh)
    n_ax = 2 + 2 * lateral + steered  # 2D: v over time and a v profile as well
    fig, axes = plt.subplots(n_ax, 1, figsize=(11, 2.5 + 2.5 * n_ax), constrained_layout=True)
    ax1 = axes[0]
    profile_axes = axes[-2:] if lateral else axes[-1:]
    if steered:
        plot_steering(axes[2], t, traj.sensor_v, traj.control_u)
    for k in range(tu.shape[1]):
        ax1.plot(t, tu[:, k], lw=0.8, label=labels[k], **styles[k])
    ax1.set_xlabel("t [s]")
    ax1.set_ylabel("tracer displacement u (x) [mm]")
    ax1.set_title(title or "tracer trajectories")
    ax1.grid(alpha=0.3)
    tracer_legend(ax1, labels)
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
    segs = belt_segments(mesh)
    seg_x = np.array([g["x0"] for g in segs]) * 1e3  # where each segment begins (a span: its arc's exit contact)
    for comp, ax2 in zip(("u", "v"), profile_axes):
        if traj.u is not None:
            x = np.asarray(mesh.x) * 1e3
            centre = 0 if mesh.n_eta == 1 else 2 * (mesh.n_eta // 2)  # the centre row's u; its v next to it
            prof = np.asarray(traj.u)[:, :, centre + (comp == "v")] * 1e3
            for i in idx:
                ax2.plot(x, prof[i], lw=1, label=f"t = {t[i]:.3g} s")
        else:
            order = np.argsort(mesh.tracer_x)
            x = np.asarray(mesh.tracer_x)[order] * 1e3
            values = tu if comp == "u" else np.asarray(traj.tracer_v) * 1e3
            for i in idx:
                ax2.plot(x, values[i, order], "o-", ms=3, lw=1, label=f"t = {t[i]:.3g} s")
        for k, xs in enumerate(seg_x):
            ax2.axvline(xs, color="0.6", lw=0.7, ls="--" if k % 2 == 0 else ":")
        top = ax2.secondary_xaxis("top")
        top.set_xticks([0.5e3 * (g["x0"] + g["x1"]) for g in segs], [g["label"] for g in segs], fontsize=7)
        top.tick_params(length=0)
        ax2.set_xlabel("position along the belt x [mm] (dashed: roller arc starts, dotted: free spans)")
        ax2.set_ylabel("u (along) [mm]" if comp == "u" else "v (lateral) [mm]")
        ax2.legend(fontsize=8)
        ax2.grid(alpha=0.3)
    return finish_figure(fig, path)


def plot_steering(ax, t, sensor_v, control_u, labels=None):
    """Steering loops over time on ``ax``: the belt's lateral displacement at each sensor (µm,
    left axis, solid) and each actuator angle (mrad, right axis, dashed)."""
    y, u = np.asarray(sensor_v) * 1e6, np.asarray(control_u) * 1e3
    right = ax.twinx()
    for i in range(y.shape[1]):
        name = f" {labels[i]}" if labels else ""
        ax.plot(t, y[:, i], lw=1, color=f"C{i}", label=f"sensor{name}")
        right.plot(t, u[:, i], lw=1, ls="--", color=f"C{i}", label=f"actuator{name}")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("belt at the sensor v [µm] (solid)")
    right.set_ylabel("actuator angle [mrad] (dashed)")
    ax.axhline(0, color="0.6", lw=0.6)
    ax.grid(alpha=0.3)
    return ax


def plot_scene(scene, mesh, path=None):
    """Rollers, belt path, contact points and tracer points in the (x³ᴰ, y³ᴰ) plane (mm), as the
    source's Figures 2.2 / 7.1."""
    plt = pyplot()
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
    return finish_figure(fig, path)


# -- model order reduction (``jaxbelt reduce``) ------------------------------------------------
