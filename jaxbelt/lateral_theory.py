"""Independent reference for belt walk: the loop of moving tensioned Timoshenko beams (numpy).

Each free span is a tensioned Timoshenko beam in steady lateral walk (Shelton & Reid, "Lateral
dynamics of a real moving web", ASME J. Dyn. Syst. Meas. Control 93, 1971), with inertia
neglected (``ρ A V² ≪ T`` on every scene here). Along a span (``0 ≤ x ≤ L`` from the exit of one
roller to the entry of the next, ``y`` the lateral centre-line displacement, ``φ`` the rotation of
the cross-sections, tension ``T`` acting along the centre line):

    κ G A (y' − φ) + T y' = Q            (lateral equilibrium, Q constant: no side load)
    E I φ'' + κ G A (y' − φ) = 0         (moment equilibrium)

so the slope ``ψ = y'`` obeys ``E I (1 + T / κGA) ψ'' − T ψ = −Q`` with the span parameter
``k² = T / (E I (1 + T/κGA))`` (``K L`` in the Euler–Bernoulli limit). The roller conditions, with
``σ`` the lateral slope of a roller's circumferential lines in the unrolled belt frame at a
contact point (``σ = αₓ t_y − α_y t_x`` for a roller rotated by ``α``, ``t`` the direction of
travel) and ``c`` the walk rate:

* **normal entry** at every entry line, ``c = V (σ_in − y'(L))`` (Lorig; Shelton);
* **zero moment** at every entry line, ``φ'(L) = 0``: the sections are carried onto the roller
  with the orientation they have, which in steady state does not change along the belt there;
* **no slip on the roller**: the material keeps its position and section orientation relative
  to the roller surface, so from the entry to the exit of roller ``j``
  ``y_out = y_in + Δv_s − c W / V`` (``W`` the wrap length, ``Δv_s`` the change of the roller
  surface's lateral position over the wrap: ``2 r αₓ`` for a twisted roller with a half wrap)
  and ``φ_out − σ_out = φ_in − σ_in``;

plus the loop's closure and one gauge (the lateral origin). That is ``4 p + 1`` linear equations
for ``4 p`` span constants and ``c``. The Euler–Bernoulli beam is the limit ``κ G A → ∞``
(``φ = y'``), the string the limit ``k L → ∞``: straight spans and, for two rollers with one
skewed by ``α``, ``c = V α L_span / L_loop``. Derivation and comparison with the 2D model:
``docs/lateral.md``. Plain numpy, no JAX: it is a test and benchmark reference, not the engine.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .geometry import belt_path

SHEAR_COEFFICIENT = 5.0 / 6.0  # rectangular section (Timoshenko / Reissner)


@dataclasses.dataclass(frozen=True)
class LoopGeometry:
    """The loop as the reference needs it: per span ``L``, direction of travel ``t`` (p, 2); per
    roller the wrap length ``W``, radius and the outward normals at its entry and exit (p, 2).
    Span ``j`` leaves roller ``j`` and enters roller ``j + 1``."""

    span_length: np.ndarray
    span_direction: np.ndarray
    wrap_length: np.ndarray
    radius: np.ndarray
    normal_in: np.ndarray
    normal_out: np.ndarray

    @classmethod
    def from_path(cls, path) -> "LoopGeometry":
        """From a :class:`jaxbelt.geometry.BeltPath` (arcs and spans alternate, roller 1 first)."""
        arcs = [s for s in path.segments if s.kind == "roller"]
        spans = [s for s in path.segments if s.kind == "free"]
        c = np.asarray(path.centers)
        r = np.asarray(path.radii)
        t = np.array([(s.end - s.start) / s.length for s in spans])
        n_in = np.array([(a.start - c[a.index]) / r[a.index] for a in arcs])
        n_out = np.array([(a.end - c[a.index]) / r[a.index] for a in arcs])
        return cls(np.array([s.length for s in spans]), t, np.array([a.length for a in arcs]), r, n_in, n_out)


def roller_slope(alpha, t):
    """Lateral slope ``e_z · (α × t)`` of a roller's circumferential lines along the direction of
    travel ``t`` (2,) for a small rotation ``α`` (3,) of the roller."""
    return alpha[0] * t[1] - alpha[1] * t[0]


def surface_lateral(alpha, radius, n):
    """Lateral displacement ``e_z · (α × r n)`` of the roller surface at outward normal ``n``."""
    return radius * (alpha[0] * n[1] - alpha[1] * n[0])


def steering_split(geom: LoopGeometry, alpha):
    """How each roller's rotation ``alpha`` (p, 3) steers: the skew seen by its entering span
    (``σ_in``) and leaving span (``σ_out``), rad, and the twist's per-pass lateral shift of the
    surface over the wrap (``Δv_s``), m — a tilt about x of a roller whose spans are not parallel
    to the x axis is part skew, part twist."""
    alpha = np.asarray(alpha, float).reshape(-1, 3)
    p = len(geom.span_length)
    rows = []
    for j in range(p):
        t_in, t_out = geom.span_direction[(j - 1) % p], geom.span_direction[j]
        rows.append({"skew_in_rad": float(roller_slope(alpha[j], t_in)),
                     "skew_out_rad": float(roller_slope(alpha[j], t_out)),
                     "per_pass_shift_m": float(surface_lateral(alpha[j], geom.radius[j], geom.normal_out[j])
                                               - surface_lateral(alpha[j], geom.radius[j], geom.normal_in[j]))})
    return rows


def _span_rows(x, L, T, EI, S):
    """Rows (4, 4) giving ``(y, y', φ, φ')`` at ``x`` from the span constants ``(A, B, Q, D)``."""
    tau = 0.0 if np.isinf(S) else T / S
    q_over_s = 0.0 if np.isinf(S) else 1.0 / S
    if T > 0:
        k = np.sqrt(T / (EI * (1.0 + tau)))
        e0, e1 = np.exp(-k * x), np.exp(-k * (L - x))
        y = [-e0 / k, e1 / k, x / T, 1.0]
        yp = [e0, e1, 1.0 / T, 0.0]
        phi = [(1 + tau) * e0, (1 + tau) * e1, (1 + tau) / T - q_over_s, 0.0]
        phip = [-(1 + tau) * k * e0, (1 + tau) * k * e1, 0.0, 0.0]
    else:  # φ = B + A x − Q x² / (2 EI), y' = φ + Q / S
        y = [x**2 / 2, x, x * q_over_s - x**3 / (6 * EI), 1.0]
        yp = [x, 1.0, q_over_s - x**2 / (2 * EI), 0.0]
        phi = [x, 1.0, -(x**2) / (2 * EI), 0.0]
        phip = [1.0, 0.0, -x / EI, 0.0]
    return np.array([y, yp, phi, phip])


def beam_walk_rate(geom: LoopGeometry, alpha, tension, EI, kGA=np.inf, speed=1.0, return_shape=False):
    """Steady walk rate ``c`` (m/s) of the belt for roller rotations ``alpha`` (p, 3) rad.

    ``tension`` (p,) span tensions in N (or a scalar), ``EI`` the belt's in-plane bending
    stiffness ``E t w³ / 12``, ``kGA`` its shear stiffness ``κ G A`` (``inf``: Euler–Bernoulli),
    ``speed`` the belt speed ``V``. With ``return_shape`` also a function ``(span, x) → (y, φ)``
    of the steady span shape relative to the walking frame."""
    p = len(geom.span_length)
    alpha = np.asarray(alpha, float).reshape(p, 3)
    T = np.broadcast_to(np.asarray(tension, float), (p,))
    n = 4 * p + 1
    M, rhs = np.zeros((n, n)), np.zeros(n)
    ic = 4 * p  # column of c
    row = 0
    for j in range(p):  # roller j: incoming span j-1, outgoing span j
        i = (j - 1) % p
        Li, Lj = geom.span_length[i], geom.span_length[j]
        end_i = _span_rows(Li, Li, T[i], EI, kGA)
        start_j = _span_rows(0.0, Lj, T[j], EI, kGA)
        s_in = roller_slope(alpha[j], geom.span_direction[i])
        s_out = roller_slope(alpha[j], geom.span_direction[j])
        dv = surface_lateral(alpha[j], geom.radius[j], geom.normal_out[j]) - surface_lateral(
            alpha[j], geom.radius[j], geom.normal_in[j])
        # no slip over the wrap: lateral position and section orientation relative to the roller
        M[row, 4 * j:4 * j + 4] = start_j[0]
        M[row, 4 * i:4 * i + 4] -= end_i[0]
        M[row, ic] = geom.wrap_length[j] / speed
        rhs[row] = dv
        row += 1
        M[row, 4 * j:4 * j + 4] = start_j[2]
        M[row, 4 * i:4 * i + 4] -= end_i[2]
        rhs[row] = s_out - s_in
        row += 1
        # entry of span i into roller j: zero moment and normal entry
        M[row, 4 * i:4 * i + 4] = end_i[3]
        row += 1
        M[row, 4 * i:4 * i + 4] = end_i[1]
        M[row, ic] = 1.0 / speed
        rhs[row] = s_in
        row += 1
    M[row, 3] = 1.0  # gauge: D of span 0
    sol = np.linalg.solve(M, rhs)
    c = float(sol[ic])
    if not return_shape:
        return c

    def shape(j, x):
        rows = _span_rows(x, geom.span_length[j], T[j], EI, kGA)
        return rows[0] @ sol[4 * j:4 * j + 4], rows[2] @ sol[4 * j:4 * j + 4]

    return c, shape


def span_tracer_shapes(mesh, tracer_v, shape):
    """The tracers on the free spans: their positions along the belt (m), the model's lateral
    displacements ``tracer_v`` there and the reference ``shape`` (from :func:`beam_walk_rate` with
    ``return_shape``) at the same points, both with their mean removed (the walk's offset and the
    reference's gauge)."""
    starts = np.cumsum([0.0] + [seg.length for seg in mesh.path.segments])
    xs, model, ref = [], [], []
    for k, seg in enumerate(mesh.path.segments):
        if seg.kind != "free":
            continue
        span = sum(q.kind == "free" for q in mesh.path.segments[:k])
        on = (mesh.tracer_x >= starts[k]) & (mesh.tracer_x <= starts[k + 1])
        xs += list(mesh.tracer_x[on])
        model += list(np.asarray(tracer_v)[on])
        ref += [shape(span, x - starts[k])[0] for x in mesh.tracer_x[on]]
    model, ref = np.array(model), np.array(ref)
    return np.array(xs), model - model.mean(), ref - ref.mean()


def belt_section(width, thickness, youngs_modulus, poisson_ratio, kappa=SHEAR_COEFFICIENT):
    """``(EI, κGA)`` of a belt strip in plane stress: ``E t w³ / 12`` and ``κ E/(2(1+ν)) w t``."""
    EI = youngs_modulus * thickness * width**3 / 12.0
    kGA = kappa * youngs_modulus / (2.0 * (1.0 + poisson_ratio)) * width * thickness
    return EI, kGA


def scene_geometry(scene) -> tuple[LoopGeometry, float]:
    """The :class:`LoopGeometry` of a :class:`jaxbelt.scene_spec.Scene`'s belt path, and the path length (m)."""
    rl = scene.rollers
    path = belt_path(np.array([r.center for r in rl]), np.array([r.radius for r in rl]),
                     np.array([r.external for r in rl]), scene.direction)
    return LoopGeometry.from_path(path), path.length


def scene_walk_rate(scene, rotation=None, tension=None, shear=True):
    """:func:`beam_walk_rate` for a compiled-from :class:`jaxbelt.scene_spec.Scene`: geometry from its belt
    path, EI and κGA from its belt, tension ``E A ε₀`` from its pre-tension unless given, the
    drive speed as ``V``; ``rotation`` (p, 3) rad defaults to the scene's roller rotations."""
    rl = scene.rollers
    geom, path_length = scene_geometry(scene)
    b = scene.belt
    EI, kGA = belt_section(b.width, b.thickness, b.youngs_modulus, b.poisson_ratio)
    if tension is None:
        tension = b.youngs_modulus * b.pre_strain(path_length) * b.area
    if rotation is None:
        rotation = np.array([r.rotation for r in rl])
    V = next(r.speed for r in rl if r.role == "drive")
    return beam_walk_rate(geom, rotation, tension, EI, kGA if shear else np.inf, speed=V)


def string_loop_transfer(geom: LoopGeometry, omega, rotation, speed, sensor_span: int, sensor_x: float):
    """Shelton's first-order span model closed around the loop (string limit, ``K L ≫ 1``):
    ``G(iω)``, the lateral displacement at a sensor per rad of a roller rotation, complex.

    ``rotation`` (p, 3) the rotation the actuator makes per rad (a unit vector on the actuated
    roller's row), ``speed`` ``V``, the sensor ``sensor_x`` m past the start of span
    ``sensor_span``. Per span ``j`` (start ``x_j`` at roller ``j``'s exit, end ``e_j`` at roller
    ``j + 1``'s entry, length ``L_j``, ``τ_j = L_j / V``; straight, since the boundary layers of
    length ``1/K`` are negligible) normal entry gives ``τ_j ė_j + e_j = x_j + L_j σ_in u``; per wrap
    (no slip) a pure transport delay ``W / V`` with the surface's lateral shift
    ``x_{j+1}(t) = e_j(t − W/V) − v_in u(t − W/V) + v_out u(t)`` (0 for a skew, the twist's
    per-pass shift for a tilt about x); the sensor reads the straight span,
    ``x_j + (sensor_x / L_j)(e_j − x_j)``. Derivation: ``docs/steering.md``."""
    w = np.atleast_1d(np.asarray(omega, float))
    p = len(geom.span_length)
    alpha = np.asarray(rotation, float).reshape(p, 3)
    V = float(speed)
    out = np.empty(w.shape, complex)
    for n, om in enumerate(w):
        s = 1j * om
        M = np.zeros((2 * p, 2 * p), complex)  # unknowns x_0, e_0, x_1, e_1, …
        rhs = np.zeros(2 * p, complex)
        for j in range(p):
            L, tau = geom.span_length[j], geom.span_length[j] / V
            r = (j + 1) % p  # the roller span j enters
            s_in = roller_slope(alpha[r], geom.span_direction[j])
            M[2 * j, 2 * j + 1] = 1.0 + tau * s
            M[2 * j, 2 * j] = -1.0
            rhs[2 * j] = L * s_in
            delay = np.exp(-s * geom.wrap_length[r] / V)
            v_in = surface_lateral(alpha[r], geom.radius[r], geom.normal_in[r])
            v_out = surface_lateral(alpha[r], geom.radius[r], geom.normal_out[r])
            M[2 * j + 1, 2 * r] = 1.0
            M[2 * j + 1, 2 * j + 1] = -delay
            rhs[2 * j + 1] = v_out - delay * v_in
        sol = np.linalg.solve(M, rhs)
        f = sensor_x / geom.span_length[sensor_span]
        out[n] = (1 - f) * sol[2 * sensor_span] + f * sol[2 * sensor_span + 1]
    return out


def string_loop_response(scene, omega, loop: int = 0):
    """:func:`string_loop_transfer` for loop ``loop`` (a ``[[control]]`` table) of a
    :class:`jaxbelt.scene_spec.Scene`: the actuated roller and axis, the drive speed as ``V`` and the
    sensor's position along the path (which must lie on a free span). Returns ``G(iω)`` (m per
    rad) with the machine's own sign; its low-frequency limit is ``c / (iω)`` with ``c`` the
    string walk rate ``V Σ L σ_in / L_loop`` of :func:`beam_walk_rate`'s string limit."""
    geom, _ = scene_geometry(scene)
    rl = scene.rollers
    spec = scene.control[loop]
    names = [r.name for r in rl]
    rot = np.zeros((len(rl), 3))
    rot[names.index(spec.actuator), "xyz".index(spec.axis)] = 1.0
    V = next(r.speed for r in rl if r.role == "drive")
    s = float(spec.sensor[0])
    pos = 0.0
    for j in range(len(rl)):  # arc of roller j, then span j
        pos += geom.wrap_length[j]
        if s < pos:
            raise ValueError(f"the sensor at s = {s * 1e3:g} mm lies on roller {names[j]!r}'s wrap, not on a free span")
        if s <= pos + geom.span_length[j]:
            return string_loop_transfer(geom, omega, rot, V, j, s - pos)
        pos += geom.span_length[j]
    raise ValueError(f"the sensor at s = {s * 1e3:g} mm lies beyond the belt path")
