"""Reduced models: singular values, DMD eigenvalues, the tracer RMSE over time and the reduction report's figure."""

from __future__ import annotations

import numpy as np

from ._common import axes_or_new, finish_figure, pyplot


def plot_singular_values(s, n_modes=None, ax=None):
    """Normalised singular values ``σ_i / σ_0`` of a snapshot matrix (semilog), the source's
    Figures 6.2 / 7.3, with the chosen number of modes ``n_modes`` marked. Returns the axes."""
    _, ax = axes_or_new(ax)
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
    plt = pyplot()
    fig, ax = axes_or_new(ax, figsize=(5.5, 5))
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


def plot_rmse_over_time(t, rmse_um, tol_um=20.0, estimate_um=None, ax=None, estimate_t=None,
                        estimate_label="error estimate"):
    """Tracer RMSE of a reduced model against the full one at every time step (µm, semilog), the
    tolerance ``tol_um`` and, optionally, an error estimate ``estimate_um`` in µm
    (:func:`jaxbelt.rom.error_estimate.error_rom`'s ``error_um``, or the triangle-inequality
    :func:`~jaxbelt.rom.error_estimate.residual_indicator`'s ``estimate_um``) at times
    ``estimate_t`` (default ``t``), labelled ``estimate_label``. Returns the axes."""
    _, ax = axes_or_new(ax)
    t = np.asarray(t, float)
    e = np.asarray(rmse_um, float)
    ax.semilogy(t, np.where(e > 0, e, np.nan), lw=1, color="tab:blue", label="RMSE vs full model")
    if tol_um is not None:
        ax.axhline(tol_um, color="tab:red", lw=1, ls="--", label=f"tolerance {tol_um:g} µm")
    if estimate_um is not None:
        est = np.asarray(estimate_um, float)
        te = t if estimate_t is None else np.asarray(estimate_t, float)
        ax.semilogy(te, np.where(est > 0, est, np.nan), "o-", ms=3, lw=1, color="tab:orange",
                    label=estimate_label)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("tracer RMSE [µm]")
    ax.set_title("error over time")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, which="both")
    return ax


def plot_reduction(report, t, rmse_um, path=None, singular_values=None, eigs=None, eig_weights=None,
                   estimate_t=None, estimate_um=None, tol_um=20.0):
    """The figure of ``jaxbelt reduce --plot``: singular values of the training snapshots (with
    ``report["modes"]`` marked), the DMD eigenvalues when ``eigs`` is given (DMD-type methods),
    and the RMSE over time ``t`` (s, µm) with the indicator estimate — a 1 × 3 figure, or 1 × 2
    without eigenvalues. ``report``: the dict the command prints (scene, method, modes, rmse_um).
    Returns ``path``, or the figure when ``path`` is ``None``."""
    plt = pyplot()
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
    plot_rmse_over_time(t, rmse_um, tol_um, estimate_um, ax=axes[k], estimate_t=estimate_t)
    rm = report.get("rmse_um")
    fig.suptitle(f"{report.get('scene', '')}: {report.get('method', '')}, {report.get('modes')} modes"
                 + (f", RMSE {rm:.3g} µm" if isinstance(rm, (int, float)) else ""))
    return finish_figure(fig, path)


# ----------------------------------------------------------------------------- tolerance design
