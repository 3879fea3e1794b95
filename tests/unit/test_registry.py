"""The solver-name tables of :mod:`jaxbelt.registry` against their two readers: every name a table offers
is accepted by the scene parser (:func:`jaxbelt.scene_from_dict`) and turned into the matching solver
by :func:`jaxbelt.make_solver`; a name outside the tables is refused by both with the table's choices
in the message; the defaults are names of their tables; the module imports nothing."""

import ast
import inspect

import pytest

import jaxbelt as jb
from jaxbelt import registry
from jaxbelt.integrators import solver_name
from jaxbelt.scene_values import SceneError
from helpers import scene_with

TABLES = {"integrator": registry.INTEGRATORS, "linear_solver": registry.LINEAR_SOLVERS,
          "transport": registry.TRANSPORT_RULES}


def test_defaults_are_names_of_their_tables_and_every_entry_is_a_one_line_description():
    assert registry.DEFAULT_INTEGRATOR in registry.INTEGRATORS
    assert registry.DEFAULT_LINEAR_SOLVER in registry.LINEAR_SOLVERS
    assert registry.DEFAULT_TRANSPORT in registry.TRANSPORT_RULES
    for table in (*TABLES.values(), registry.START_RULES):
        for name, text in table.items():
            assert name == name.strip().lower() and " " not in name
            assert isinstance(text, str) and text.strip() and "\n" not in text


def test_the_module_imports_nothing():
    tree = ast.parse(inspect.getsource(registry))
    assert not [n for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom))]


@pytest.mark.parametrize("key", list(TABLES))
def test_scene_parser_accepts_every_name_of_the_table_and_keeps_it(key):
    for name in TABLES[key]:
        scene = scene_with(lambda d: d.update(solver={key: name}))
        assert getattr(scene.solver, key) == name


@pytest.mark.parametrize("key", list(TABLES))
def test_scene_parser_refuses_an_unknown_name_listing_the_choices(key):
    with pytest.raises(SceneError, match=rf"solver\.{key} = 'nope': must be one of " + ", ".join(TABLES[key])):
        scene_with(lambda d: d.update(solver={key: "nope"}))


def test_scene_parser_refuses_an_unknown_start_rule_listing_the_choices():
    with pytest.raises(SceneError, match=r"time\.start = 'moving': one of " + ", ".join(registry.START_RULES)):
        scene_with(lambda d: d["time"].update(start="moving"))
    for rule in registry.START_RULES:
        assert scene_with(lambda d: d["time"].update(start=rule)).time.start == rule


def test_make_solver_builds_every_registered_combination_under_its_own_name():
    for integrator in registry.INTEGRATORS:
        for transport in registry.TRANSPORT_RULES:
            if integrator == "direct":
                for ls in registry.LINEAR_SOLVERS:
                    solver = jb.make_solver(integrator, ls, transport=transport)
                    assert solver_name(solver) == f"direct/{ls}" and solver.transport == transport
            else:
                solver = jb.make_solver(integrator, transport=transport)
                assert solver_name(solver) == integrator and solver.transport == transport
    assert solver_name(jb.make_solver()) == f"{registry.DEFAULT_INTEGRATOR}/{registry.DEFAULT_LINEAR_SOLVER}"


def test_make_solver_refuses_unknown_names_listing_the_choices():
    with pytest.raises(ValueError, match="unknown integrator 'rk4' \\(one of " + ", ".join(registry.INTEGRATORS)):
        jb.make_solver("rk4")
    with pytest.raises(ValueError, match="unknown linear solver 'cholesky' \\(one of "
                                         + ", ".join(registry.LINEAR_SOLVERS)):
        jb.make_solver("direct", "cholesky")
    with pytest.raises(ValueError, match="transport = 'drift': unknown rule \\(one of "
                                         + ", ".join(registry.TRANSPORT_RULES)):
        jb.make_solver("naive", transport="drift")
