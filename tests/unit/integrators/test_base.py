"""The integrator interface (:class:`jaxbelt.integrators.AbstractIntegrator`): the transport rule is a
keyword-only static field defaulting to :data:`jaxbelt.registry.DEFAULT_TRANSPORT`, a name outside
:data:`jaxbelt.registry.TRANSPORT_RULES` is refused with the rules listed (by every integrator, the
direct one's own checks included), ``step`` must be defined, and ``init`` keeps nothing by default."""

import jax
import pytest

import jaxbelt as jb
from jaxbelt.integrators import AbstractIntegrator, make_solver
from jaxbelt.registry import DEFAULT_TRANSPORT, INTEGRATORS, TRANSPORT_RULES


class StandStill(AbstractIntegrator):
    """An integrator whose step leaves the state as it is."""

    def step(self, model, state, dt, run_data):
        return state


def test_transport_defaults_to_the_registry_default_and_keeps_every_rule():
    assert DEFAULT_TRANSPORT == "shift"
    assert StandStill().transport == DEFAULT_TRANSPORT
    for rule in TRANSPORT_RULES:
        assert StandStill(transport=rule).transport == rule


def test_an_unknown_transport_rule_is_refused_with_the_rules_listed():
    with pytest.raises(ValueError, match=r"^transport = 'sideways': unknown rule \(one of shift, source\)$"):
        StandStill(transport="sideways")


@pytest.mark.parametrize("integrator", list(INTEGRATORS))
def test_every_integrator_refuses_an_unknown_transport_rule(integrator):
    assert isinstance(make_solver(integrator), AbstractIntegrator)
    cls = type(make_solver(integrator))
    args = (jb.Reuse(),) if cls is jb.DirectBackwardEuler else ()
    with pytest.raises(ValueError, match="transport = 'SHIFT': unknown rule"):
        cls(*args, transport="SHIFT")  # names are exact: no case folding


def test_the_direct_integrator_keeps_its_own_check_beside_the_transport_one():
    with pytest.raises(TypeError, match="linear_solver = 'reuse': a linear solver object"):
        jb.DirectBackwardEuler("reuse")
    assert jb.DirectBackwardEuler(jb.Reuse(), transport="source").transport == "source"


def test_transport_is_keyword_only_and_static():
    with pytest.raises(TypeError):
        StandStill("source")  # positional: refused
    a, b = StandStill(transport="shift"), StandStill(transport="source")
    assert jax.tree_util.tree_leaves(a) == [] and jax.tree_util.tree_leaves(b) == []  # no traced leaf
    assert jax.tree_util.tree_structure(a) != jax.tree_util.tree_structure(b)  # the rule is part of the structure


def test_step_is_abstract_and_init_keeps_nothing_by_default():
    class NoStep(AbstractIntegrator):
        pass

    with pytest.raises(TypeError, match="abstract"):
        NoStep()
    integrator, state = StandStill(), object()
    assert integrator.init(None, state, 0.01) is None
    assert integrator.step(None, state, 0.01, None) is state
