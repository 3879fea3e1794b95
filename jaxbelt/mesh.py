"""The fixed grid on the unrolled belt (§3.1.1, §4.1.1, model specification §4).

``x`` is the arc length along the belt path, starting at the incoming contact line of roller 1
and increasing in the direction of motion; the loop closes after ``path.length``. Columns of
nodes ``i = 0..n_xi-1`` sit at ``x_i``; element ``i`` joins column ``i`` and ``i+1`` (mod
``n_xi``), so there are as many element columns as node columns. Contact lines are grid
lines: the arc of roller ``j`` holds ``n_r_j + 1`` columns (both contact lines), a free span
``n_f_j - 1`` interior columns. Across the width ``n_eta`` rows sit at ``z`` evenly spaced in
``[-w/2, w/2]`` (2D only; 1D has one row at ``z = 0``).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .geometry import BeltPath, PathError, arc_angles, belt_path
from .scene import Scene, SceneError

MIN_ARC_ELEMENTS = 5  # §7.2.1: at least five elements along the belt on every roller


@dataclasses.dataclass(frozen=True)
class Mesh:
    path: BeltPath
    roller_elements: tuple[int, ...]
    free_elements: tuple[int, ...]
    x: np.ndarray  # (n_xi,) arc-length position of each node column, m
    ell: np.ndarray  # (n_xi,) length of element column i (from column i to i+1), m
    z: np.ndarray  # (n_eta,) lateral node positions, m
    node_roller: np.ndarray  # (n_xi,) roller index of a column on a roller arc, -1 on a free span
    node_theta: np.ndarray  # (n_xi,) wrap angle θ of a roller column (0 on free spans)
    elem_free: np.ndarray  # (n_xi,) bool: element column i is a free-belt element
    segment_starts: np.ndarray  # (2p,) first column of each segment (arc, span, arc, ...)
    tracer_x: np.ndarray  # (n_tr,) m
    tracer_z: np.ndarray  # (n_tr,) m

    @property
    def n_xi(self) -> int:
        return len(self.x)

    @property
    def n_eta(self) -> int:
        return len(self.z)

    @property
    def length(self) -> float:
        return float(self.x[-1] + self.ell[-1])

    def tracer_location(self):
        """Element column and local coordinate ``ξ ∈ [0, 1)`` of every tracer along the belt."""
        xs = np.mod(self.tracer_x, self.length)
        col = np.clip(np.searchsorted(self.x, xs, side="right") - 1, 0, self.n_xi - 1)
        xi = (xs - self.x[col]) / self.ell[col]
        return col.astype(np.int32), xi


def _segment_counts(scene: Scene, path: BeltPath):
    p = path.n_rollers
    arcs = [s for s in path.segments if s.kind == "roller"]
    spans = [s for s in path.segments if s.kind == "free"]
    m = scene.mesh
    if m.roller_elements is not None:
        return tuple(m.roller_elements), tuple(m.free_elements), "mesh.roller_elements"
    if m.element_length is not None:
        h, key = m.element_length, "mesh.element_length_mm"
    elif m.n_xi is not None:
        h, key = path.length / m.n_xi, "mesh.n_xi"
    else:  # default: ten elements on the shortest arc
        h, key = min(a.length for a in arcs) / 10.0, "mesh (default element length)"
    nr = [max(1, int(round(a.length / h))) for a in arcs]
    nf = [max(1, int(round(s.length / h))) for s in spans]
    if m.n_xi is not None and m.element_length is None:
        # distribute the rounding remainder so that the total is exactly n_xi
        counts = nr + nf
        lengths = [a.length for a in arcs] + [s.length for s in spans]
        while sum(counts) != m.n_xi:
            step = 1 if sum(counts) < m.n_xi else -1
            err = [(c + step) * h - L for c, L in zip(counts, lengths)]
            k = int(np.argmin([abs(e) if (c + step) >= 1 else np.inf for e, c in zip(err, counts)]))
            counts[k] += step
        nr, nf = counts[:p], counts[p:]
    return tuple(nr), tuple(nf), key


CFL_ADVICE_FACTOR = 0.9  # of the CFL bound V dt < ℓ_min, the step advised (cfl_advice)


def cfl_advice(h_min: float, V: float, name: str = "dt") -> str:
    """The step to use after a refused one: ``CFL_ADVICE_FACTOR`` of the bound ``ℓ_min / V`` (s),
    with why — the belt runs a few per cent faster than ``V`` while it starts up, so a step at
    the bound makes the transport step extrapolate. ``name``: the option or key to name."""
    bound = h_min / V
    return (f"use {name} <= {CFL_ADVICE_FACTOR * bound:.4g} s (the bound is {bound:.4g} s; the belt runs a few "
            "per cent faster than V while it starts up, so a step at the bound extrapolates)")


def build_mesh(scene: Scene) -> Mesh:
    """Belt path + grid for a scene, with the geometry/mesh checks of model specification §1."""
    rollers = scene.rollers
    try:
        path = belt_path(
            [r.center for r in rollers], [r.radius for r in rollers], [r.external for r in rollers],
            direction=scene.direction, names=[r.name for r in rollers],
        )
    except PathError as e:
        raise SceneError(f"roller.center_mm = {[[round(float(c) * 1e3, 3) for c in r.center] for r in rollers]}: "
                         f"impossible belt path: {e}") from None
    if scene.belt.length is not None and scene.belt.length > path.length * (1 + 1e-12):
        raise SceneError(f"belt.length_mm = {scene.belt.length * 1e3:g}: longer than the belt path "
                         f"({path.length * 1e3:.3f} mm); a slack belt cannot be modelled")
    nr, nf, key = _segment_counts(scene, path)
    for j, n in enumerate(nr):
        if n < MIN_ARC_ELEMENTS:
            raise SceneError(f"{key}: {n} element(s) on the arc of {rollers[j].name!r} "
                             f"(wrap {path.segments[2 * j].length * 1e3:.2f} mm); at least {MIN_ARC_ELEMENTS} are needed")

    xs, ells, node_roller, node_theta, elem_free, starts = [], [], [], [], [], []
    x0 = 0.0
    for seg in path.segments:
        starts.append(len(xs))
        if seg.kind == "roller":
            n = nr[seg.index]
            h = seg.length / n
            fr = np.arange(n + 1) / n
            xs += list(x0 + fr * seg.length)
            th = arc_angles(seg, fr)
            node_roller += [seg.index] * (n + 1)
            node_theta += list(th)
            ells += [h] * n
            elem_free += [False] * n
        else:
            n = nf[seg.index]
            h = seg.length / n
            fr = np.arange(1, n) / n
            xs += list(x0 + fr * seg.length)
            node_roller += [-1] * (n - 1)
            node_theta += [0.0] * (n - 1)
            ells += [h] * n
            elem_free += [True] * n
        x0 += seg.length
    # element i joins column i and i+1: the arc elements start at the arc's first column, and the
    # last element of a free span ends on the next arc's first column, so lengths line up.
    x = np.asarray(xs)
    ell = np.asarray(ells)
    assert len(x) == len(ell) == sum(nr) + sum(nf)

    V = max((r.speed for r in rollers if r.role == "drive"), default=0.0)
    h_min = float(ell.min())
    if V * scene.time.dt >= h_min:
        raise SceneError(
            f"time.dt_s = {scene.time.dt:g}: violates the CFL condition of the transport step "
            f"(belt speed {V:g} m/s × dt = {V * scene.time.dt * 1e3:.4g} mm >= smallest element "
            f"{h_min * 1e3:.4g} mm); {cfl_advice(h_min, V, 'dt_s')}"
        )

    n_eta = scene.mesh.n_eta
    z = np.zeros(1) if n_eta == 1 else np.linspace(-scene.belt.width / 2, scene.belt.width / 2, n_eta)
    k = scene.output.tracers_per_segment
    tx, tz = [], []
    for seg, s0 in zip(path.segments, np.cumsum([0.0] + [s.length for s in path.segments[:-1]])):
        tx += list(s0 + (np.arange(k) + 0.5) / k * seg.length) if k else []
        tz += [0.0] * k
    for (xt, zt) in scene.output.tracers:
        if not 0.0 <= xt < path.length:
            raise SceneError(f"output.tracers_mm: x = {xt * 1e3:g} mm outside the belt [0, {path.length * 1e3:.3f})")
        if abs(zt) > scene.belt.width / 2 * (1 + 1e-12):
            raise SceneError(f"output.tracers_mm: z = {zt * 1e3:g} mm outside the belt width")
        tx.append(xt)
        tz.append(zt)
    if not tx:
        raise SceneError("output.tracers_per_segment = 0 and no output.tracers_mm: the scene records nothing")
    return Mesh(
        path=path, roller_elements=nr, free_elements=nf, x=x, ell=ell, z=z,
        node_roller=np.asarray(node_roller, np.int32), node_theta=np.asarray(node_theta),
        elem_free=np.asarray(elem_free, bool), segment_starts=np.asarray(starts),
        tracer_x=np.asarray(tx), tracer_z=np.asarray(tz),
    )
