"""What a scene file describes, as plain frozen dataclasses in SI units: the belt, the rollers,
the mesh, the time span, the outputs, the solver and the steering loops
(:func:`jaxbelt.scene.load_scene` reads and checks a file into them)."""

from __future__ import annotations

import dataclasses

from .registry import DEFAULT_INTEGRATOR, DEFAULT_LINEAR_SOLVER, DEFAULT_TRANSPORT



@dataclasses.dataclass(frozen=True)
class BeltSpec:
    width: float  # m
    thickness: float  # m
    youngs_modulus: float  # Pa
    poisson_ratio: float
    density: float  # kg/m³
    length: float | None = None  # m; None = path length

    @property
    def area(self) -> float:
        return self.width * self.thickness

    def pre_strain(self, path_length: float) -> float:
        """Uniform pre-strain ``ε₀ = L_path / L_belt − 1`` of a belt shorter than its path (0 without
        ``length``)."""
        return 0.0 if self.length is None else path_length / self.length - 1.0


@dataclasses.dataclass(frozen=True)
class RollerSpec:
    name: str
    center: tuple[float, float]  # m
    radius: float  # m
    width: float  # m
    mass: float  # kg
    external: bool
    role: str  # drive | idle | tension
    speed: float  # belt surface speed for a drive roller, m/s
    translation: tuple[float, float, float]  # m
    rotation: tuple[float, float, float]  # rad, applied x → y → z
    force: tuple[float, float, float]  # N; non-zero components are force-loaded (dynamic) DOFs
    torque: tuple[float, float, float]  # N·m about x, y (z: idle/tension rollers are torque free)


@dataclasses.dataclass(frozen=True)
class MeshSpec:
    n_eta: int = 1
    n_xi: int | None = None
    element_length: float | None = None  # m
    roller_elements: tuple[int, ...] | None = None
    free_elements: tuple[int, ...] | None = None
    element: str = "qm6"  # 2D quad: qm6 (incompatible modes, no bending locking) | q4 (bilinear)


@dataclasses.dataclass(frozen=True)
class TimeSpec:
    dt: float  # s
    t_end: float  # s
    start: str = "rest"  # rest | running (jaxbelt.registry.START_RULES; jaxbelt.initial_state)

    @property
    def n_steps(self) -> int:
        return int(round(self.t_end / self.dt))


@dataclasses.dataclass(frozen=True)
class OutputSpec:
    tracers_per_segment: int = 5
    fields: str = "tracers"  # tracers | full
    every: int = 1  # keep every k-th step
    tracers: tuple[tuple[float, float], ...] = ()  # extra tracers (x along the path, z), m


@dataclasses.dataclass(frozen=True)
class SolverSpec:
    integrator: str = DEFAULT_INTEGRATOR  # a name of jaxbelt.registry.INTEGRATORS
    linear_solver: str = DEFAULT_LINEAR_SOLVER  # a name of jaxbelt.registry.LINEAR_SOLVERS
    transport: str = DEFAULT_TRANSPORT  # a name of jaxbelt.registry.TRANSPORT_RULES
    lateral_transport: bool = False  # 2D: also transport v (lets a skewed roller steer the belt)
    tension_stiffening: bool = True  # 2D: initial-stress (geometric) stiffness of the membrane tension
    accuracy_um: float | None = None  # run on the cheapest grid whose estimated error is at most this (jaxbelt.accuracy)


@dataclasses.dataclass(frozen=True)
class ControlSpec:
    """One steering loop (``[[control]]``), SI units: an edge sensor feeding a PID controller
    that tilts one roller (:mod:`jaxbelt.control`)."""

    actuator: str  # roller name
    axis: str  # "x" | "y": the rotation component it drives
    sensor: tuple[float, float]  # (s along the path from roller 1's incoming contact line, z across), m
    kp: float  # rad/m (= mrad/mm)
    ki: float = 0.0  # rad/(m s)
    kd: float = 0.0  # rad s/m
    sample: float | None = None  # s; None: every step
    limit: float = 5e-3  # rad, symmetric range
    rate_limit: float | None = None  # rad/s
    lag: float = 0.0  # s, actuator first-order lag
    setpoint: float = 0.0  # m
    noise: float = 0.0  # m, sensor noise σ
    seed: int = 0
    edge_profile: tuple[tuple[float, float, float], ...] = ()  # (harmonic per loop, amplitude m, phase rad)


@dataclasses.dataclass(frozen=True)
class Scene:
    name: str
    kind: str  # "1d" | "2d"
    belt: BeltSpec
    rollers: tuple[RollerSpec, ...]
    mesh: MeshSpec
    time: TimeSpec
    output: OutputSpec
    solver: SolverSpec
    direction: int | None = None  # +1 ccw / -1 cw loop; None: from the layout
    description: str = ""
    control: tuple[ControlSpec, ...] = ()  # steering loops ([[control]] tables)

    def replace(self, **kw) -> "Scene":
        return dataclasses.replace(self, **kw)
