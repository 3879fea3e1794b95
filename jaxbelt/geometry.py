"""Belt path geometry: rollers in the (x³ᴰ, y³ᴰ) plane, common tangents and wrap arcs.

The belt runs around the rollers in their numbering order (§2.1, model specification §4). Each roller
carries a *wrap sense* ``s_j = ±1``: ``+1`` when the belt goes counter-clockwise around it
(seen from +z³ᴰ), ``-1`` when clockwise. For a loop travelled counter-clockwise the internal
rollers have ``s = +1`` and the external ones ``s = -1``; a clockwise loop flips both.

With the *signed radius* ``ρ_j = s_j r_j`` the belt touches roller ``j`` at
``p = c_j - ρ_j J e`` where ``e`` is the unit direction of travel and ``J`` the rotation by
+90°. A free span from roller ``a`` to roller ``b`` therefore satisfies
``c_b - c_a = L e + (ρ_b - ρ_a) J e``, which gives the span length
``L = sqrt(|Δ|² - Δρ²)`` and ``e = (L I - Δρ J) Δ / |Δ|²``. Equal signs give the outer
tangent, opposite signs the crossing tangent. ``|Δ| <= |Δρ|`` means no such tangent exists
(impossible belt path).

Everything here is plain numpy: geometry is computed once when a scene is compiled.
"""

from __future__ import annotations

import dataclasses

import numpy as np


class PathError(ValueError):
    """The rollers admit no belt path (crossing tangents of overlapping rollers, ...)."""


@dataclasses.dataclass(frozen=True)
class Segment:
    """One belt segment: a wrap arc on a roller or a free span between two rollers.

    Angles are those of the outward roller normal ``n(θ) = (cos θ, sin θ)``; along an arc the
    angle runs from ``theta_in`` in the wrap sense ``sense`` for ``wrap`` radians.
    """

    kind: str  # "roller" | "free"
    index: int  # roller index (arc) or index of the span's upstream roller (free)
    length: float  # m, along the belt
    start: np.ndarray  # (2,) point where the segment starts, m
    end: np.ndarray  # (2,) point where it ends, m
    theta_in: float = 0.0
    wrap: float = 0.0
    sense: int = 1
    name: str = ""


@dataclasses.dataclass(frozen=True)
class BeltPath:
    """The closed belt path: segments in order, starting at the incoming contact line of roller 1."""

    segments: tuple[Segment, ...]
    centers: np.ndarray  # (p, 2) m
    radii: np.ndarray  # (p,) m
    senses: np.ndarray  # (p,) ±1

    @property
    def length(self) -> float:
        return float(sum(s.length for s in self.segments))

    @property
    def n_rollers(self) -> int:
        return len(self.radii)


def _rot90(v: np.ndarray) -> np.ndarray:
    return np.array([-v[1], v[0]])


def loop_orientation(centers: np.ndarray) -> int:
    """+1 if the roller polygon (in numbering order) is counter-clockwise, -1 if clockwise.

    Two rollers (or collinear ones) span no area; the belt then runs counter-clockwise.
    """
    x, y = centers[:, 0], centers[:, 1]
    area2 = float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    scale = float(np.max(np.ptp(centers, axis=0)) ** 2) if len(centers) > 1 else 1.0
    if abs(area2) <= 1e-12 * max(scale, 1e-300):
        return 1
    return 1 if area2 > 0 else -1


def wrap_senses(centers: np.ndarray, external: np.ndarray, direction: int | None = None) -> np.ndarray:
    """Wrap sense of every roller: the loop's orientation for internal rollers, flipped for external."""
    o = loop_orientation(centers) if direction is None else int(direction)
    return np.where(np.asarray(external, bool), -o, o).astype(int)


def tangent_span(c_a, rho_a, c_b, rho_b):
    """Common tangent from roller a to roller b for signed radii ρ (see module docstring).

    **Returns:** ``(p_a, p_b, e, L)``: leaving point on a, arriving point on b, direction, length.
    """
    c_a, c_b = np.asarray(c_a, float), np.asarray(c_b, float)
    delta = c_b - c_a
    dist2 = float(delta @ delta)
    drho = rho_b - rho_a
    if dist2 - drho**2 <= 1e-18 * max(dist2, 1e-30):
        raise PathError(
            f"no common tangent between rollers at {c_a * 1e3} mm and {c_b * 1e3} mm "
            f"(centre distance {np.sqrt(dist2) * 1e3:.3f} mm <= |Δρ| = {abs(drho) * 1e3:.3f} mm)"
        )
    L = np.sqrt(dist2 - drho**2)
    e = (L * delta - drho * _rot90(delta)) / dist2
    p_a = c_a - rho_a * _rot90(e)
    p_b = c_b - rho_b * _rot90(e)
    return p_a, p_b, e, float(L)


def belt_path(centers, radii, external, direction: int | None = None, names=None) -> BeltPath:
    """Build the closed belt path around rollers ``0..p-1`` (numbering order = path order).

    **Arguments:**
    - `centers`: (p, 2) roller centres, m. `radii`: (p,) m. `external`: (p,) bool.
    - `direction`: +1 / -1 to force a counter-clockwise / clockwise loop; default from the layout.

    **Returns:** a :class:`BeltPath` whose first segment is the wrap arc of roller 0, starting
    at its incoming contact line, followed by the free span to roller 1, and so on.
    """
    centers = np.asarray(centers, float)
    radii = np.asarray(radii, float)
    p = len(radii)
    senses = wrap_senses(centers, external, direction)
    rho = senses * radii
    names = names or [f"roller {j + 1}" for j in range(p)]
    spans = [tangent_span(centers[j], rho[j], centers[(j + 1) % p], rho[(j + 1) % p]) for j in range(p)]
    segments = []
    for j in range(p):
        p_in = spans[j - 1][1]  # arrival point of the span coming from roller j-1
        p_out = spans[j][0]
        th_in = np.arctan2(*(p_in - centers[j])[::-1])
        th_out = np.arctan2(*(p_out - centers[j])[::-1])
        wrap = float(np.mod(senses[j] * (th_out - th_in), 2 * np.pi))
        if wrap < 1e-9:
            raise PathError(f"{names[j]}: the belt does not wrap it (wrap angle {wrap:.3g} rad)")
        segments.append(
            Segment("roller", j, radii[j] * wrap, p_in, p_out, float(th_in), wrap, int(senses[j]), names[j])
        )
        pa, pb, _, L = spans[j]
        segments.append(Segment("free", j, L, pa, pb, name=f"{names[j]} → {names[(j + 1) % p]}"))
    turning = sum(seg.sense * seg.wrap for seg in segments if seg.kind == "roller")
    o = loop_orientation(centers) if direction is None else int(direction)
    if abs(turning - 2 * np.pi * o) > 1e-6:
        wraps = ", ".join(f"{n}: {np.degrees(s.wrap):.1f}°" for n, s in zip(names, segments[::2]))
        raise PathError(f"the belt does not form a simple loop (total turning {np.degrees(turning):.1f}°, "
                        f"expected {360 * o}°; wraps {wraps}); a roller inside a concave bend must be external")
    _check_spans_clear(segments, centers, radii, names)
    return BeltPath(tuple(segments), centers, radii, senses)


def _check_spans_clear(segments, centers, radii, names):
    """Reject a path whose free span cuts through a roller it does not touch."""
    for seg in segments:
        if seg.kind != "free":
            continue
        a, b = seg.start, seg.end
        ab = b - a
        for k, (c, r) in enumerate(zip(centers, radii)):
            t = np.clip((c - a) @ ab / (ab @ ab), 0.0, 1.0)
            d = np.linalg.norm(a + t * ab - c)
            if d < r * (1 - 1e-6) and 1e-6 < t < 1 - 1e-6:
                raise PathError(f"free span {seg.name} passes through {names[k]}")


def arc_angles(seg: Segment, fractions) -> np.ndarray:
    """Angles θ of the points at the given fractions (0..1) along a wrap arc."""
    return seg.theta_in + seg.sense * seg.wrap * np.asarray(fractions, float)
