"""The counting of ``benchmarks/call_path.py`` (how a sweep's study travels through the design
package): stops join consecutive calls in one module, a return is a stop in a module the path had
left, and only a stop whose first call comes from outside its module enters it."""

import sys

from helpers import REPO

sys.path.insert(0, str(REPO / "benchmarks"))
from call_path import _counts, _has_cycle, _on_stack, _stops  # noqa: E402


def _event(module, function, entered=True, traced=False):
    return {"module": module, "function": function, "entered": entered, "traced": traced, "sweep": True}


def test_stops_returns_and_entries():
    events = [_event("sweep", "run_sweep"), _event("sampling", "draw"), _event("sampling", "check"),
              _event("sweep", "_helper", entered=False),  # the sweep's own helper: it continues
              _event("study", "evaluate", traced=True), _event("metrics", "response", traced=True),
              _event("sampling", "statistics"), _event("sweep", "_result", entered=False)]
    stops = _stops(events)
    assert [s["module"] for s in stops] == ["sweep", "sampling", "sweep", "study", "metrics", "sampling", "sweep"]
    assert stops[1]["functions"] == ["draw", "check"]
    c = _counts(stops)
    assert (c["stops"], c["modules"], c["returns_to_a_module_left"]) == (7, 4, 3)
    assert c["entries_per_module"] == {"sampling": 2, "sweep": 1, "study": 1, "metrics": 1}
    assert c["most_entries"] == 2
    untraced = _counts(_stops([e for e in events if not e["traced"]]))
    # outside tracing: the program's study and metrics stops are gone, the orchestration's remain
    assert untraced["stops"] == 5 and untraced["entries_per_module"] == {"sampling": 2, "sweep": 1}


def test_a_module_on_the_stack_is_continued_not_entered():
    here = sys._getframe()
    assert _on_stack(here, __name__) and not _on_stack(here, "jaxbelt.design.nowhere")


def test_cycle_in_the_module_call_graph():
    assert not _has_cycle({("sweep", "sampling"): 3, ("sampling", "study"): 1})
    assert _has_cycle({("sweep", "sampling"): 1, ("sampling", "sweep"): 1})
