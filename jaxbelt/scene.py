"""Scene files (TOML): loading, unit conversion and validation (model specification §1).

A scene is read into the frozen dataclasses of :mod:`jaxbelt.scene_spec`, in SI units. Every
rejection raises :class:`SceneError`, whose message names the offending key and value; nothing
is compiled or run for a scene that fails. Each value is read by the checked readers of
:mod:`jaxbelt.scene_values`. Geometry- and mesh-dependent checks (belt path, CFL, elements on an
arc) happen in :func:`jaxbelt.mesh.build_mesh`, which raises the same error type.
"""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path

import numpy as np

from .registry import (DEFAULT_INTEGRATOR, DEFAULT_LINEAR_SOLVER, DEFAULT_TRANSPORT, INTEGRATORS, LINEAR_SOLVERS,
                       START_RULES, TRANSPORT_RULES)
from .scene_spec import BeltSpec, ControlSpec, MeshSpec, OutputSpec, RollerSpec, Scene, SolverSpec, TimeSpec
from .scene_values import (SceneError, check_keys, choice, int_list, key_error, number, number_tuples,
                           vector)


# ---------------------------------------------------------------------------- schema

_ROLES = ("drive", "idle", "tension")
_SIDES = ("internal", "external")
_ELEMENTS = ("qm6", "q4")  # jaxbelt.elements.QUAD_ELEMENTS; the default (first) is argued in quad_qm6_stiffness

_TABLES = {
    "model": {"kind", "name", "description", "direction"},
    "belt": {"width_mm", "thickness_mm", "youngs_modulus_pa", "poisson_ratio", "density_kg_m3", "length_mm"},
    "roller": {
        "name", "center_mm", "radius_mm", "width_mm", "mass_kg", "side", "role", "speed_m_s",
        "translation_mm", "rotation_mrad", "force_n", "torque_nm",
    },
    "mesh": {"n_eta", "n_xi", "element_length_mm", "roller_elements", "free_elements", "element"},
    "time": {"dt_s", "t_end_s", "start"},
    "output": {"tracers_per_segment", "fields", "every", "tracers_mm"},
    "solver": {"integrator", "linear_solver", "transport", "lateral_transport", "tension_stiffening", "accuracy_um"},
    "control": {"actuator", "axis", "sensor_mm", "kp_mrad_per_mm", "ki_mrad_per_mm_s", "kd_mrad_s_per_mm",
                "sample_s", "limit_mrad", "rate_limit_mrad_s", "lag_s", "setpoint_mm", "noise_um", "seed",
                "edge_profile_um"},
}


# Range of static roller rotations (rad), from benchmarks/linearity_range.py on three-roller: the
# response's linearity error grows as ≈ 0.64 α (skew) and 0.30 α (tilt about x): 0.3–0.6 % at
# 10 mrad, 1.5–3.2 % at 50 mrad, 3–6 % at 100 mrad. Translations stay linear to 0.15 % at 100 mm
# (a large inward one is caught as a slack belt instead, jaxbelt.prestress.slack_spans).
ROTATION_WARN = 10e-3
ROTATION_REFUSE = 50e-3


class MisalignmentWarning(UserWarning):
    """A scene's static misalignment is inside the model's range but where its linearisation
    starts to cost accuracy (see ``ROTATION_WARN``)."""


# ---------------------------------------------------------------------------- parsing


def scene_from_dict(data: dict, name: str = "scene") -> Scene:
    """Validate a parsed TOML document and convert it to a :class:`Scene` in SI units.

    A document with ``extends = "built-in name"`` is a variant: see :func:`_extend`."""
    if "extends" in data:
        data = _extend(dict(data), name)
    for k in data:
        if k not in _TABLES:
            raise key_error(k, "…", f"unknown table (allowed: {', '.join(sorted(_TABLES))})")
    model = data.get("model", {})
    check_keys(model, _TABLES["model"], "model")
    kind = choice(model, "kind", "model", ("1d", "2d"))
    direction = None
    if "direction" in model:
        direction = {"ccw": 1, "cw": -1}.get(model["direction"])
        if direction is None:
            raise key_error("model.direction", model["direction"], "must be 'ccw' or 'cw'")

    belt = data.get("belt")
    if belt is None:
        raise key_error("belt", None, "required table is missing")
    check_keys(belt, _TABLES["belt"], "belt")
    nu = number(belt, "poisson_ratio", "belt", nonneg=True, hi=0.5)
    length = number(belt, "length_mm", "belt", required=False, positive=True)
    belt_spec = BeltSpec(
        width=number(belt, "width_mm", "belt", positive=True) * 1e-3,
        thickness=number(belt, "thickness_mm", "belt", positive=True) * 1e-3,
        youngs_modulus=number(belt, "youngs_modulus_pa", "belt", positive=True),
        poisson_ratio=float(nu),
        density=number(belt, "density_kg_m3", "belt", positive=True),
        length=None if length is None else length * 1e-3,
    )

    raw_rollers = data.get("roller")
    if not isinstance(raw_rollers, list):
        raise key_error("roller", raw_rollers, "scene needs [[roller]] tables (2 to 6)")
    if not 2 <= len(raw_rollers) <= 6:
        raise key_error("roller", f"{len(raw_rollers)} rollers", "a belt system has 2 to 6 rollers")
    rollers = tuple(_roller(r, j, kind) for j, r in enumerate(raw_rollers))
    _check_rollers(rollers, belt_spec)

    mesh = data.get("mesh", {})
    check_keys(mesh, _TABLES["mesh"], "mesh")
    p = len(rollers)
    n_eta = number(mesh, "n_eta", "mesh", required=False, default=1 if kind == "1d" else 9, integer=True, lo=1)
    if kind == "1d" and n_eta != 1:
        raise key_error("mesh.n_eta", n_eta, "the 1D model has one node across the width (n_eta = 1)")
    if kind == "2d" and n_eta < 2:
        raise key_error("mesh.n_eta", n_eta, "the 2D model needs at least 2 nodes across the width")
    el = number(mesh, "element_length_mm", "mesh", required=False, positive=True)
    mesh_spec = MeshSpec(
        n_eta=int(n_eta),
        n_xi=number(mesh, "n_xi", "mesh", required=False, integer=True, lo=2 * p),
        element_length=None if el is None else el * 1e-3,
        roller_elements=int_list(mesh, "roller_elements", "mesh", p),
        free_elements=int_list(mesh, "free_elements", "mesh", p),
        element=choice(mesh, "element", "mesh", _ELEMENTS, default=_ELEMENTS[0]),
    )
    if kind == "1d" and "element" in mesh:
        raise key_error("mesh.element", mesh["element"], "the 1D model is a string of bars; the element choice is 2D only")
    if (mesh_spec.roller_elements is None) != (mesh_spec.free_elements is None):
        raise key_error("mesh.roller_elements", mesh.get("roller_elements"),
                   "give roller_elements and free_elements together")
    if mesh_spec.free_elements is not None and min(mesh_spec.free_elements) < 1:
        raise key_error("mesh.free_elements", list(mesh_spec.free_elements), "every free span needs >= 1 element")

    time = data.get("time")
    if time is None:
        raise key_error("time", None, "required table is missing")
    check_keys(time, _TABLES["time"], "time")
    dt = number(time, "dt_s", "time", positive=True)
    t_end = number(time, "t_end_s", "time", positive=True)
    if t_end < dt:
        raise key_error("time.t_end_s", t_end, f"shorter than one step (dt_s = {dt})")
    start = time.get("start", "rest")
    if start not in START_RULES:
        raise key_error("time.start", start, f"one of {', '.join(START_RULES)}")
    time_spec = TimeSpec(float(dt), float(t_end), start)

    out = data.get("output", {})
    check_keys(out, _TABLES["output"], "output")
    tracers = tuple((t[0] * 1e-3, t[1] * 1e-3)
                    for t in number_tuples(out, "tracers_mm", "output", 2, "[x_mm, z_mm] pairs"))
    out_spec = OutputSpec(
        tracers_per_segment=number(out, "tracers_per_segment", "output", required=False, default=5,
                                    integer=True, lo=0),
        fields=choice(out, "fields", "output", ("tracers", "full"), default="tracers"),
        every=number(out, "every", "output", required=False, default=1, integer=True, lo=1),
        tracers=tracers,
    )

    solver = data.get("solver", {})
    check_keys(solver, _TABLES["solver"], "solver")
    solver_spec = SolverSpec(
        integrator=choice(solver, "integrator", "solver", tuple(INTEGRATORS), default=DEFAULT_INTEGRATOR),
        linear_solver=choice(solver, "linear_solver", "solver", tuple(LINEAR_SOLVERS),
                              default=DEFAULT_LINEAR_SOLVER),
        transport=choice(solver, "transport", "solver", tuple(TRANSPORT_RULES), default=DEFAULT_TRANSPORT),
        lateral_transport=choice(solver, "lateral_transport", "solver", (True, False), default=False),
        tension_stiffening=choice(solver, "tension_stiffening", "solver", (True, False), default=True),
        accuracy_um=number(solver, "accuracy_um", "solver", required=False, positive=True),
    )
    if data.get("control") and kind == "1d":
        raise key_error("control", "[[control]]", "a steering loop needs a 2D scene (model.kind = \"2d\"): the 1D model "
                   "has no lateral displacement to steer")
    if solver_spec.lateral_transport and kind == "1d":
        raise key_error("solver.lateral_transport", True, "the 1D model has no lateral displacement")
    raw_control = data.get("control", [])
    if isinstance(raw_control, dict):
        # one loop per [[control]] table: a single [control] table reads as "the machine's control
        # settings", and a second loop added later would need the file rewritten
        raise key_error("control", "[control]", "write a steering loop as an array of tables, [[control]] (one per loop)")
    if not isinstance(raw_control, list):
        raise key_error("control", raw_control, "must be [[control]] tables")
    control = tuple(_control(c, i, rollers, belt_spec, time_spec) for i, c in enumerate(raw_control))
    seen = {}
    for i, c in enumerate(control):
        other = seen.setdefault((c.actuator, c.axis), i)
        if other != i:
            raise key_error(f"control[{i}]", f"{c.actuator} about {c.axis}",
                       f"control[{other}] already drives this actuator about this axis: one loop per actuated "
                       "rotation (two would both act on it)")
    if control and not solver_spec.lateral_transport:
        raise key_error("solver.lateral_transport", False,
                   "a [[control]] steering loop needs lateral_transport = true (without it the belt cannot walk)")
    return Scene(
        name=str(model.get("name", name)), kind=kind, belt=belt_spec, rollers=rollers, mesh=mesh_spec,
        time=time_spec, output=out_spec, solver=solver_spec, direction=direction,
        description=str(model.get("description", "")), control=control,
    )


def _control(c: dict, i: int, rollers, belt: BeltSpec, time: TimeSpec) -> ControlSpec:
    """One ``[[control]]`` table, checked key by key (module :mod:`jaxbelt.control` for the law)."""
    where = f"control[{i}]"
    if not isinstance(c, dict):
        raise key_error(where, c, "must be a table")
    check_keys(c, _TABLES["control"], where)
    names = [r.name for r in rollers]
    if "actuator" not in c:
        raise key_error(f"{where}.actuator", None, f"required key is missing (a roller name: {', '.join(names)})")
    actuator = c["actuator"]
    if actuator not in names:
        raise key_error(f"{where}.actuator", actuator, f"no roller of that name ({', '.join(names)})")
    axis = choice(c, "axis", where, ("x", "y"))
    roller = rollers[names.index(actuator)]
    k = "xy".index(axis)
    if roller.torque[k] != 0.0:
        raise key_error(f"{where}.axis", axis, f"the {axis} rotation of {actuator!r} is torque-loaded (torque_nm[{k}] != 0), "
                   "not a prescribed DOF an actuator can drive")
    sensor = vector(c, "sensor_mm", where, 2)
    if abs(sensor[1]) * 1e-3 > belt.width / 2 * (1 + 1e-12):
        raise key_error(f"{where}.sensor_mm", list(sensor),
                   f"z = {sensor[1]:g} mm is off the belt (|z| <= width/2 = {belt.width / 2 * 1e3:g} mm)")
    if sensor[0] < 0:
        raise key_error(f"{where}.sensor_mm", list(sensor), "s must not be negative (mm along the path from roller 1)")
    sample = number(c, "sample_s", where, required=False, positive=True)
    if sample is not None:
        ratio = sample / time.dt
        if abs(ratio - round(ratio)) > 1e-6 * max(1.0, ratio):
            raise key_error(f"{where}.sample_s", sample, f"must be a whole multiple of time.dt_s = {time.dt:g}")
    rate = number(c, "rate_limit_mrad_s", where, required=False, positive=True)
    limit = number(c, "limit_mrad", where, required=False, default=5.0, positive=True) * 1e-3
    if abs(roller.rotation[k]) + limit > ROTATION_REFUSE:
        raise key_error(f"{where}.limit_mrad", limit * 1e3,
                   f"static rotation + range beyond the model's range of {ROTATION_REFUSE * 1e3:g} mrad")
    v = number_tuples(c, "edge_profile_um", where, 3, "[harmonic, amplitude_um, phase_rad] triples")
    for t in v:
        if not (float(t[0]).is_integer() and t[0] >= 1):
            raise key_error(f"{where}.edge_profile_um", v, f"harmonic {t[0]!r} must be a whole number >= 1 (per loop)")
    profile = tuple((float(t[0]), float(t[1]) * 1e-6, float(t[2])) for t in v)
    seed = c.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise key_error(f"{where}.seed", seed, "must be a non-negative integer")
    return ControlSpec(
        actuator=actuator, axis=axis, sensor=(sensor[0] * 1e-3, sensor[1] * 1e-3),
        kp=float(number(c, "kp_mrad_per_mm", where, nonneg=True)),
        ki=float(number(c, "ki_mrad_per_mm_s", where, required=False, default=0.0, nonneg=True)),
        kd=float(number(c, "kd_mrad_s_per_mm", where, required=False, default=0.0, nonneg=True)),
        sample=None if sample is None else float(sample),
        limit=float(limit),
        rate_limit=None if rate is None else float(rate) * 1e-3,
        lag=float(number(c, "lag_s", where, required=False, default=0.0, nonneg=True)),
        setpoint=float(number(c, "setpoint_mm", where, required=False, default=0.0)) * 1e-3,
        noise=float(number(c, "noise_um", where, required=False, default=0.0, nonneg=True)) * 1e-6,
        seed=int(seed), edge_profile=profile,
    )


def _roller(r: dict, j: int, kind: str) -> RollerSpec:
    where = f"roller[{j}]"
    if not isinstance(r, dict):
        raise key_error(where, r, "must be a table")
    check_keys(r, _TABLES["roller"], where)
    name = r.get("name", f"roller {j + 1}")
    if not isinstance(name, str) or not name.strip():
        raise key_error(f"{where}.name", name, "must be a non-empty string")
    role = choice(r, "role", where, _ROLES)
    side = choice(r, "side", where, _SIDES, default="internal")
    speed = number(r, "speed_m_s", where, required=role == "drive", default=0.0, positive=role == "drive")
    if role != "drive" and "speed_m_s" in r:
        raise key_error(f"{where}.speed_m_s", r["speed_m_s"], f"only a drive roller has a speed (role = {role!r})")
    translation = tuple(x * 1e-3 for x in vector(r, "translation_mm", where, 3, (0.0, 0.0, 0.0)))
    rotation = tuple(x * 1e-3 for x in vector(r, "rotation_mrad", where, 3, (0.0, 0.0, 0.0)))
    force = vector(r, "force_n", where, 3, (0.0, 0.0, 0.0))
    torque = vector(r, "torque_nm", where, 3, (0.0, 0.0, 0.0))
    if torque[2] != 0.0:
        raise key_error(f"{where}.torque_nm", list(torque),
                   "the torque about the roller axis is fixed by the role (drive: speed, idle/tension: 0)")
    loaded = [f != 0.0 for f in force] + [t != 0.0 for t in torque[:2]]
    if role == "tension" and not any(loaded):
        raise key_error(f"{where}.force_n", list(force), "a tension roller needs a non-zero force component")
    if role != "tension" and any(loaded):
        raise key_error(f"{where}.force_n", list(force), f"only a tension roller is force-loaded (role = {role!r})")
    for i, ax in enumerate("xyz"):
        if force[i] != 0.0 and translation[i] != 0.0:
            raise key_error(f"{where}.translation_mm", [t * 1e3 for t in translation],
                       f"the {ax} translation is force-loaded (force_n[{i}] != 0) and cannot also be prescribed")
    for i, ax in enumerate("xy"):
        if torque[i] != 0.0 and rotation[i] != 0.0:
            raise key_error(f"{where}.rotation_mrad", [a * 1e3 for a in rotation],
                       f"the {ax} rotation is torque-loaded and cannot also be prescribed")
    if rotation[2] != 0.0:
        raise key_error(f"{where}.rotation_mrad", [a * 1e3 for a in rotation],
                   "a static rotation about the roller axis (z) is meaningless; it is the drive/idle DOF")
    tilt = max(abs(a) for a in rotation)
    if tilt > ROTATION_REFUSE:
        raise key_error(f"{where}.rotation_mrad", [a * 1e3 for a in rotation],
                   f"beyond the model's range of {ROTATION_REFUSE * 1e3:g} mrad: its belt kinematics are linear in "
                   "the misalignment increments (3 % linearity error of the response at 50 mrad, "
                   "benchmarks/linearity_range.py)")
    if tilt > ROTATION_WARN:
        import warnings

        warnings.warn(f"{where}.rotation_mrad = {[a * 1e3 for a in rotation]}: above {ROTATION_WARN * 1e3:g} mrad "
                      f"the linearised response is off by more than ~0.6 % (benchmarks/linearity_range.py)",
                      MisalignmentWarning, stacklevel=2)
    if kind == "1d":
        # The 1D model (model specification §2) carries per roller only the x translation and the z rotation.
        if translation[1] != 0.0 or translation[2] != 0.0:
            raise key_error(f"{where}.translation_mm", [t * 1e3 for t in translation],
                       "the 1D model has only the x translation; use [model] kind = '2d'")
        if any(a != 0.0 for a in rotation):
            raise key_error(f"{where}.rotation_mrad", [a * 1e3 for a in rotation],
                       "the 1D model has no roller tilt; use [model] kind = '2d'")
        if force[1] != 0.0 or force[2] != 0.0 or any(t != 0.0 for t in torque):
            raise key_error(f"{where}.force_n", list(force), "the 1D model takes a force along x only")
    return RollerSpec(
        name=name,
        center=tuple(x * 1e-3 for x in vector(r, "center_mm", where, 2)),
        radius=number(r, "radius_mm", where, positive=True) * 1e-3,
        width=number(r, "width_mm", where, positive=True) * 1e-3,
        mass=float(number(r, "mass_kg", where, positive=True)),
        external=side == "external",
        role=role,
        speed=float(speed),
        translation=translation,
        rotation=rotation,
        force=force,
        torque=torque,
    )


def _check_rollers(rollers, belt: BeltSpec):
    names = [r.name for r in rollers]
    if len(set(names)) != len(names):
        raise key_error("roller.name", names, "roller names must be unique")
    if not any(r.role == "drive" for r in rollers):
        raise key_error("roller.role", [r.role for r in rollers], "at least one roller must be the drive")
    drives = [r for r in rollers if r.role == "drive"]
    speeds = [r.speed for r in drives]
    if max(speeds) - min(speeds) > 1e-9 * max(speeds):
        # the belt sticks to every roller it wraps: two prescribed surface speeds would stretch the
        # span between them without bound (a real belt slips on one of them, which this model has no law for)
        raise key_error("roller.speed_m_s", {r.name: r.speed for r in drives},
                   "every drive roller must run at the same surface speed: the belt does not slip on a roller, "
                   "so two drive speeds would stretch it without bound")
    for j, r in enumerate(rollers):
        if belt.width > r.width * (1 + 1e-12):
            raise key_error(f"roller[{j}].width_mm", r.width * 1e3,
                       f"narrower than the belt (belt.width_mm = {belt.width * 1e3:g}); the belt must fit on every roller")
    for a in range(len(rollers)):
        for b in range(a + 1, len(rollers)):
            ra, rb = rollers[a], rollers[b]
            dist = float(np.hypot(ra.center[0] - rb.center[0], ra.center[1] - rb.center[1]))
            if dist < ra.radius + rb.radius:
                raise key_error(f"roller[{b}].center_mm", [c * 1e3 for c in rb.center],
                           f"{rb.name!r} overlaps {ra.name!r} (centre distance {dist * 1e3:.3f} mm < "
                           f"sum of radii {(ra.radius + rb.radius) * 1e3:.3f} mm)")
            # the same with the static translations applied: the misaligned rollers must not overlap either
            moved = float(np.hypot(ra.center[0] + ra.translation[0] - rb.center[0] - rb.translation[0],
                                   ra.center[1] + ra.translation[1] - rb.center[1] - rb.translation[1]))
            if moved < ra.radius + rb.radius:
                raise key_error(f"roller[{b}].translation_mm", [t * 1e3 for t in rb.translation],
                           f"with the static translations {rb.name!r} overlaps {ra.name!r} (centre distance "
                           f"{moved * 1e3:.3f} mm < sum of radii {(ra.radius + rb.radius) * 1e3:.3f} mm)")


# ---------------------------------------------------------------------------- loading


def builtin_scene_names() -> list[str]:
    files = resources.files("jaxbelt") / "scenes"
    return sorted(p.name[:-5] for p in files.iterdir() if p.name.endswith(".toml"))


def load_scene(source: str | Path) -> Scene:
    """Load a scene from a TOML file path or a built-in scene name (see ``jaxbelt scenes``)."""
    s = str(source)
    if not s.strip():
        raise SceneError("no scene given: a TOML path or a built-in scene name (see `jaxbelt scenes`)")
    path = Path(s)
    if path.suffix == ".toml" or path.exists():
        if not path.exists():
            raise SceneError(f"scene file {s!r} does not exist")
        if not path.is_file():
            raise SceneError(f"scene {s!r} is a folder, not a scene file")
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError as e:
            raise SceneError(f"scene file {s!r} is not UTF-8 text (TOML is UTF-8): {e.reason} at byte {e.start}") from None
        except OSError as e:
            raise SceneError(f"scene file {s!r} cannot be read: {e.strerror}") from None
        name = path.stem
    else:
        res = resources.files("jaxbelt") / "scenes" / f"{s}.toml"
        if not res.is_file():
            raise SceneError(f"unknown scene {s!r}: not a file and not a built-in scene "
                             f"({', '.join(builtin_scene_names())})")
        text = res.read_text()
        name = s
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise SceneError(f"{s}: not valid TOML: {e}") from None
    return scene_from_dict(data, name=name)


def _extend(data: dict, source: str) -> dict:
    """A variant scene: ``extends = "base"`` plus tables merged key by key into the base, and
    ``[variant."roller name"]`` tables merged into that roller."""
    base_name = data.pop("extends")
    if not isinstance(base_name, str) or base_name not in builtin_scene_names():
        raise key_error("extends", base_name, f"not a built-in scene ({', '.join(builtin_scene_names())})")
    base = tomllib.loads((resources.files("jaxbelt") / "scenes" / f"{base_name}.toml").read_text())
    if "extends" in base:
        base = _extend(base, base_name)
    variant = data.pop("variant", {})
    for table, values in data.items():
        if table == "control":  # steering loops replace the base's as a whole
            base["control"] = values
            continue
        if table == "roller":
            raise key_error("roller", "…", "a variant changes rollers through [variant.\"name\"] tables")
        if not isinstance(values, dict):
            raise key_error(table, values, "must be a table")
        base.setdefault(table, {}).update(values)
    names = [r.get("name") for r in base.get("roller", [])]
    for rname, values in variant.items():
        if rname not in names:
            raise key_error(f"variant.{rname}", "…", f"no roller of that name in {base_name!r} ({', '.join(map(str, names))})")
        base["roller"][names.index(rname)].update(values)
    return base
