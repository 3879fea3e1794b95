"""Roller misalignments as parameters: which components can vary, in which units, and how they
enter a model. Shared by the reduced models (:mod:`jaxbelt.rom`, their training designs) and
tolerance design (:mod:`jaxbelt.design`).

:func:`with_misalignment` sets translations and rotations in SI units.

A design vector ``theta`` (P,) holds *deviations from the scene's own misalignment* of the
selected components, in design units: translations in **mm**, rotations in **mrad**. Metrics are
in µm, so gradients come out in µm/mm and µm/mrad — numbers of order 1–100 that optimisers and
finite differences handle well. :func:`apply` maps ``theta`` onto a model's ``chi_static`` (SI),
purely and differentiably.

Components per roller, in the order of model specification §1: ``dx, dy, dz`` (translation along x³ᴰ, y³ᴰ,
z³ᴰ) and ``ax, ay, az`` (rotation about them). Two kinds are *structurally zero* and never
become parameters:

- ``az``, the rotation about the roller's own axis: a static offset of it is a relabelling of
  the roller surface, not a misalignment (model specification §6);
- a force/torque-loaded DOF (a tension roller's loaded translation): its position is a dynamic
  unknown set by the load, so no static value can be prescribed.

The 1D model carries only ``dx`` and ``az`` per roller, so only ``dx`` can vary there.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

COMPONENTS = ("dx", "dy", "dz", "ax", "ay", "az")
TRANSLATIONS = ("dx", "dy", "dz")
ROTATIONS = ("ax", "ay", "az")
UNIT = {"dx": "mm", "dy": "mm", "dz": "mm", "ax": "mrad", "ay": "mrad", "az": "mrad"}
TO_SI = 1e-3  # mm → m and mrad → rad alike


@dataclasses.dataclass(frozen=True)
class ParameterSpace:
    """Selected misalignment components of a compiled model (a static, hashable description).

    **Fields:** ``roller_names`` (p,); ``entries`` ((roller index, component), ...) of the P
    parameters; ``chi_index`` (P,) their positions in ``model.chi_static``; ``structural``
    {(roller index, component): reason} of the components that cannot vary.
    """

    roller_names: tuple
    entries: tuple
    chi_index: tuple
    structural: tuple

    @property
    def size(self) -> int:
        return len(self.entries)

    def labels(self) -> list[str]:
        """``"roller 2:ax"`` per parameter."""
        return [f"{self.roller_names[j]}:{c}" for j, c in self.entries]

    def units(self) -> list[str]:
        return [UNIT[c] for _, c in self.entries]

    def per_roller(self, values, fill=0.0) -> dict:
        """``{roller name: {"translation": [x, y, z], "rotation": [x, y, z]}}`` from (P,) values;
        components that are not parameters get ``fill``."""
        values = np.asarray(values, float)
        out = {name: {"translation": [fill] * 3, "rotation": [fill] * 3} for name in self.roller_names}
        for k, (j, c) in enumerate(self.entries):
            group = "translation" if c in TRANSLATIONS else "rotation"
            out[self.roller_names[j]][group]["xyz".index(c[1])] = float(values[k])
        return out

    def index(self, roller: str, component: str) -> int:
        j = self.roller_names.index(roller)
        return self.entries.index((j, component))


def parameter_space(model, select: str | list | None = None) -> ParameterSpace:
    """Every component that can vary in ``model`` (``select=None``), or those named by ``select``.

    ``select``: a list of items or a comma-separated string, each ``"ROLLER"`` (all of its
    components), ``"ROLLER:translation"``, ``"ROLLER:rotation"`` or ``"ROLLER:COMPONENT"`` with a
    component of :data:`COMPONENTS`. Raises ``ValueError`` naming the item for an unknown roller
    or component, or for a component that is structurally zero.
    """
    names, dofs = tuple(model.roller_names), tuple(model.dofs)
    dynamic = np.asarray(model.dynamic).reshape(len(names), len(dofs))
    free, structural = [], {}
    for j in range(len(names)):
        for c in COMPONENTS:
            if c not in dofs:
                structural[(j, c)] = f"not modelled by the {model.kind} model"
            elif c == "az":
                structural[(j, c)] = "rotation about the roller's own axis has no static effect"
            elif dynamic[j, dofs.index(c)]:
                structural[(j, c)] = "force/torque-loaded: the load sets it"
            else:
                free.append((j, c))
    if select is not None:
        items = [s.strip() for s in (select.split(",") if isinstance(select, str) else select) if s.strip()]
        if not items:
            raise ValueError(f"components = {select!r}: names no component")
        chosen = []
        for item in items:
            roller, _, comp = item.partition(":")
            roller, comp = roller.strip(), comp.strip()
            if roller not in names:
                raise ValueError(f"components = {item!r}: no roller named {roller!r} (rollers: {', '.join(names)})")
            j = names.index(roller)
            group = {"": COMPONENTS, "translation": TRANSLATIONS, "rotation": ROTATIONS}.get(comp, (comp,))
            if comp and group == (comp,) and comp not in COMPONENTS:
                raise ValueError(f"components = {item!r}: unknown component {comp!r} "
                                 f"(translation, rotation or one of {', '.join(COMPONENTS)})")
            picked = [(j, c) for c in group if (j, c) in free]
            if comp in COMPONENTS and not picked:
                raise ValueError(f"components = {item!r}: {structural[(j, comp)]}")
            chosen += [e for e in picked if e not in chosen]
        free = sorted(chosen, key=lambda e: (e[0], COMPONENTS.index(e[1])))
    chi_index = tuple(j * len(dofs) + dofs.index(c) for j, c in free)
    return ParameterSpace(names, tuple(free), chi_index, tuple(sorted(structural.items())))


def apply(model, space: ParameterSpace, theta, base=None):
    """``model`` with ``chi_static = base + theta`` (design units → SI) on the selected components.

    **Arguments:** ``theta`` (P,) deviations in mm / mrad (traceable); ``base`` (q,) the
    misalignment they are added to, default the model's own ``chi_static``.
    """
    base = model.chi_static if base is None else base
    idx = jnp.asarray(space.chi_index, dtype=jnp.int32)
    chi = base.at[idx].add(TO_SI * jnp.asarray(theta, base.dtype))
    return model.replace(chi_static=chi)


def dof_directions(model, dofs, scale: float = 1.0, rows: int | None = None):
    """Directions in ``chi_static`` along roller DOFs: (rows, q), row ``i`` ``scale`` at ``dofs[i]``
    (flat indices of ``chi_static``) and zero elsewhere, the rows beyond ``len(dofs)`` zero (``rows``
    default ``len(dofs)``): what :func:`jaxbelt.steady.steady_with_tangents` differentiates along."""
    q, k = model.chi_static.shape[0], len(dofs)
    rows = k if rows is None else rows
    return jnp.zeros((rows, q), model.chi_static.dtype).at[jnp.arange(k), jnp.asarray(dofs, jnp.int32)].set(scale)


def aligned(model):
    """The same machine with every misalignment set to zero (the metrics' reference)."""
    return model.replace(chi_static=jnp.zeros_like(model.chi_static))


def with_misalignment(model, translation=None, rotation=None):
    """``model`` with new static roller misalignments (traceable, for ``grad`` and ``vmap``).

    **Arguments:** ``translation``: (p,) x translations in 1D or (p, 3), m; ``rotation``: (p, 3)
    tilts, rad (2D only). ``None`` keeps the current value. A component the model does not carry
    (1D: anything but x translation) must be zero: ``ValueError`` otherwise.
    **Returns:** the model with its ``chi_static`` (q,) replaced.
    """
    chi = model.chi_static.reshape(model.n_rollers, len(model.dofs))
    if translation is not None:
        t = jnp.asarray(translation)
        p = model.n_rollers
        if t.shape not in ((p,), (p, 3)):
            raise ValueError(f"translation: shape {t.shape}, expected ({p},) (x translations) or ({p}, 3) — one row "
                             f"per roller ({p} rollers), m")
        if t.ndim == 1:
            t = jnp.stack([t, jnp.zeros_like(t), jnp.zeros_like(t)], axis=1)
        for k, ax in enumerate("xyz"):
            if f"d{ax}" in model.dofs:
                chi = chi.at[:, model.dofs.index(f"d{ax}")].set(t[:, k])
            else:
                _require_zero(t[:, k], f"translation along {ax}", model.kind)
    if rotation is not None:
        a = jnp.asarray(rotation)
        if a.shape != (model.n_rollers, 3):
            raise ValueError(f"rotation: shape {a.shape}, expected ({model.n_rollers}, 3) — one row per roller, rad")
        for k, ax in enumerate("xy"):
            if f"a{ax}" in model.dofs:
                chi = chi.at[:, model.dofs.index(f"a{ax}")].set(a[:, k])
            else:
                _require_zero(a[:, k], f"rotation about {ax}", model.kind)
    return model.replace(chi_static=chi.reshape(-1))


def _require_zero(v, what, kind):
    if not isinstance(v, jax.core.Tracer) and np.any(np.asarray(v) != 0):
        raise ValueError(f"the {kind} model has no {what}")
