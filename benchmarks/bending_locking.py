"""Lateral (in-plane) bending of a clamped belt strip: the bilinear quad locks, QM6 does not.

A strip of width w (across, z) and length L (along, x), plane stress, E = 2.5 GPa, ν = 0.34,
t = 0.3 mm, meshed with ``n_eta`` nodes across (h = w / (n_eta − 1)) and elements of aspect
ratio ℓ/h, assembled (sparse) from jaxbelt's element matrices like
``tests/unit/test_prestress.py::_strip_deflection``. Two load cases, every node of the clamped end(s)
fixed in u and v, the load P spread equally over the nodes of the loaded section:

* ``clamped-clamped``: central lateral load; beam: ``δ = P L³/(192 EI) + P L/(4 κ G A)``;
* ``cantilever``: lateral tip load; beam: ``δ = P L³/(3 EI) + P L/(κ G A)``;

with ``EI = E t w³/12``, ``A = w t``, ``G = E/(2(1 + ν))``, κ = 5/6 (Timoshenko). FE deflection
is the mean lateral displacement of the loaded section. At L/w = 100 (the main table) the shear
term is 0.1 % (clamped–clamped) and 0.01 % (cantilever) of the bending term; at L/w = 10 (the
second, smaller table: clamped–clamped, n_eta = 5 to 18, ℓ/h = 1 to 3) it is 13 % (0.8 % for
the cantilever), and there it is needed: the converged QM6 answer is 0.99 of Timoshenko and
would be 1.12 of Euler–Bernoulli (the rest is the 2D clamp and point load, which beam theory
idealises).

Writes ``results/bending_locking.json`` and ``.png`` (ratio FE/beam against ℓ/h, q4 and qm6,
several n_eta). Runs in ~10 s. ``tests/unit/test_elements.py`` imports :func:`strip_deflection` and
:func:`beam_deflection` and pins the n_eta = 3 row.
"""

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from jaxbelt.elements import QUAD_ELEMENTS

E, NU, T, W = 2.5e9, 0.34, 3e-4, 0.02
KAPPA = 5.0 / 6.0
ASPECTS = (1, 2, 3, 5, 7, 10)
N_ETAS = (3, 5, 9, 18)


def strip_deflection(element, n_eta, aspect, case="clamped-clamped", L_over_w=100.0, w=W, E=E, nu=NU, t=T, P=1.0):
    """``(δ_FE, ℓ/h actually used)``: the number of elements along is rounded to an even integer."""
    L = L_over_w * w
    h = w / (n_eta - 1)
    nx = max(2, 2 * int(round(L / (aspect * h) / 2)))
    ell = L / nx
    Ke = np.asarray(QUAD_ELEMENTS[element](ell, h, E, nu, t))
    node = np.arange((nx + 1) * n_eta).reshape(nx + 1, n_eta)
    quad = np.stack([node[:-1, :-1], node[:-1, 1:], node[1:, :-1], node[1:, 1:]], axis=-1).reshape(-1, 4)
    dofs = np.stack([2 * quad, 2 * quad + 1], axis=-1).reshape(-1, 8)
    n = 2 * node.size
    K = sp.coo_matrix((np.broadcast_to(Ke, (len(dofs), 8, 8)).ravel(),
                       (np.repeat(dofs, 8, axis=1).ravel(), np.tile(dofs, (1, 8)).ravel())), shape=(n, n)).tocsc()
    loaded = node[nx // 2] if case == "clamped-clamped" else node[nx]
    clamped = [node[0], node[nx]] if case == "clamped-clamped" else [node[0]]
    F = np.zeros(n)
    F[2 * loaded + 1] = P / n_eta
    fixed = np.concatenate([np.concatenate([2 * c, 2 * c + 1]) for c in clamped])
    free = np.setdiff1d(np.arange(n), fixed)
    x = np.zeros(n)
    x[free] = spla.spsolve(K[free][:, free], F[free])
    return float(np.mean(x[2 * loaded + 1])), ell / h


def beam_deflection(case="clamped-clamped", L_over_w=100.0, w=W, E=E, nu=NU, t=T, P=1.0, shear=True):
    """Timoshenko (Euler–Bernoulli with ``shear=False``) deflection under the load."""
    L = L_over_w * w
    EI, GA = E * t * w**3 / 12, E / (2 * (1 + nu)) * w * t
    if case == "clamped-clamped":
        return P * L**3 / (192 * EI) + shear * P * L / (4 * KAPPA * GA)
    return P * L**3 / (3 * EI) + shear * P * L / (KAPPA * GA)


def table(case, L_over_w, elements=("q4", "qm6"), n_etas=N_ETAS, aspects=ASPECTS):
    beam = beam_deflection(case, L_over_w)
    rows = []
    for element in elements:
        for n_eta in n_etas:
            for a in aspects:
                d, a_used = strip_deflection(element, n_eta, a, case, L_over_w)
                rows.append({"element": element, "n_eta": n_eta, "aspect": a, "aspect_used": a_used,
                             "ratio": d / beam})
    return {"case": case, "L_over_w": L_over_w, "beam_m": beam,
            "shear_over_bending": beam / beam_deflection(case, L_over_w, shear=False) - 1.0, "rows": rows}


def print_table(tab):
    print(f"\n{tab['case']}, L/w = {tab['L_over_w']:g} (Timoshenko shear term {100 * tab['shear_over_bending']:.2f} % "
          f"of bending); FE/beam:")
    aspects = sorted({r["aspect"] for r in tab["rows"]})
    print(f"{'element':>7} {'n_eta':>5} " + " ".join(f"{'l/h=' + str(a):>8}" for a in aspects))
    for element in dict.fromkeys(r["element"] for r in tab["rows"]):
        for n_eta in dict.fromkeys(r["n_eta"] for r in tab["rows"]):
            rs = {r["aspect"]: r["ratio"] for r in tab["rows"] if r["element"] == element and r["n_eta"] == n_eta}
            print(f"{element:>7} {n_eta:>5} " + " ".join(f"{rs[a]:8.4f}" for a in aspects))


def main():
    from _common import RESULTS, write  # here, so that tests/unit/test_elements.py can import the strip

    tables = [table("clamped-clamped", 100.0), table("cantilever", 100.0),
              table("clamped-clamped", 10.0, n_etas=(5, 9, 18), aspects=(1, 2, 3))]
    for tab in tables:
        print_table(tab)
    write("bending_locking", {
        "setup": f"plane-stress strip w = {W * 1e3:g} mm, t = {T * 1e3:g} mm, E = {E:g} Pa, nu = {NU}; "
                 "clamped end nodes fixed in u and v; load P spread over the loaded section's nodes; "
                 "ratio = mean lateral deflection of that section / Timoshenko beam (kappa = 5/6)",
        "tables": tables})

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4), constrained_layout=True, sharey=True)
    colors = dict(zip(N_ETAS, ("tab:red", "tab:orange", "tab:green", "tab:blue")))
    for ax, tab in zip(axes, tables[:2]):
        for element, style in (("q4", "--o"), ("qm6", "-s")):
            for n_eta in N_ETAS:
                rs = [r for r in tab["rows"] if r["element"] == element and r["n_eta"] == n_eta]
                ax.plot([r["aspect_used"] for r in rs], [r["ratio"] for r in rs], style, color=colors[n_eta],
                        ms=4, label=f"{element}, n_eta = {n_eta}")
        ax.axhline(1.0, color="k", lw=0.8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xticks(ASPECTS, [str(a) for a in ASPECTS])
        ax.set_xlabel("element aspect ratio ℓ/h")
        ax.set_title(f"{tab['case']}, L/w = {tab['L_over_w']:g}")
    axes[0].set_ylabel("lateral deflection FE / Timoshenko beam")
    axes[1].legend(fontsize=7, ncol=2)
    fig.savefig(RESULTS / "bending_locking.png", dpi=120)
    plt.close(fig)
    print(f"wrote {RESULTS / 'bending_locking.png'}")


if __name__ == "__main__":
    main()
