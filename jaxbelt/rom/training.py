"""Training designs for one reduced model over a box of misalignments (every roller direction).

A reduced model trained on a few configurations fails in directions none of them varied (the
source's Table 7.3 tests move roller 3 along x, which no Table 7.4 run did: 0.04–0.54 mm). The
remedy is to train on every direction of the box the model is meant for. The belt's response is
linear in small misalignments (``jaxbelt.design``: 0.05 mm / mrad per component deviates from the
Jacobian's prediction by < 1e-9 relative on the design scene), so the span of the responses to
each component alone contains the response to any combination: the **axial design** — the
aligned machine and each component at ± its half-width, ``2P + 1`` runs — is enough, and a
reduced model that takes the misalignments as its input (the fully reduced POD step's ``B μ``,
DMDc's ``B u``) predicts any point of the box. The two signs make the design symmetric about the
aligned machine, so the linearisation of the 2D lever arms (second order in the tilts) is not
biased to one side.
"""

from __future__ import annotations

import numpy as np

from ..misalignment import TO_SI, aligned, apply, parameter_space


def box_from_distribution(dist) -> np.ndarray:
    """Half-widths (P,) of the training box from a :class:`jaxbelt.design.Distribution` (the
    sweep's ``--dist`` file): a uniform law's half-width, three σ of a normal one."""
    return np.asarray([s if k == "uniform" else 3.0 * s for k, s in zip(dist.kind, dist.scale)], float)


def axial_design(model, components, half_widths):
    """The axial training design over the box ``|θ_k| ≤ h_k`` around the aligned ``model``.

    **Arguments:** ``components`` — labels ``"roller:component"`` (or a select string, as
    :func:`jaxbelt.design.parameter_space`); ``half_widths`` (P,) in mm / mrad.
    **Returns:** ``(models, thetas, space)``: the ``2P + 1`` compiled configurations (aligned
    first), their deviations (2P + 1, P) in mm / mrad and the parameter space.
    """
    space = parameter_space(model, list(components))
    h = np.asarray(half_widths, float)
    if h.shape != (space.size,) or not np.all(np.isfinite(h)) or np.any(h <= 0):
        raise ValueError(f"half_widths = {h.tolist()}: need {space.size} positive numbers (one per component)")
    base = aligned(model)
    thetas = [np.zeros(space.size)]
    for k in range(space.size):
        for sign in (1.0, -1.0):
            t = np.zeros(space.size)
            t[k] = sign * h[k]
            thetas.append(t)
    thetas = np.stack(thetas)
    return [apply(base, space, t, base=base.chi_static) for t in thetas], thetas, space


def position_in_box(model, space, half_widths) -> tuple[np.ndarray, list[str]]:
    """``model``'s own misalignment in units of the box (``θ_k / h_k``; inside the box: all
    ``|·| ≤ 1``) and the components it misaligns that the box does not vary."""
    chi = np.asarray(model.chi_static) / TO_SI
    theta = chi[list(space.chi_index)]
    outside = [lab for lab, j in zip(parameter_space(model).labels(), parameter_space(model).chi_index)
               if j not in space.chi_index and abs(chi[j]) > 1e-12]
    return theta / np.asarray(half_widths, float), outside
