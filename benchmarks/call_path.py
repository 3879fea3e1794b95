"""How a sweep's study travels through the design package: the module stops of ``jaxbelt sweep``.

Runs ``jaxbelt sweep`` in-process on a small scene (the three-roller machine with two element rows,
24 Monte-Carlo samples, FORM and the error bar as by default) under a profiler that records every Python call into a module of
``jaxbelt.design`` (tracing included: it is the code a reader follows). Consecutive calls within
one module are one *stop*; a stop in a module the path had already left is a *return* (a property
read on the study, ``study.steered``, is a stop in ``study`` too). A stop *enters* its module when
its first call comes from outside it — not a module's own helper called after a callee returned,
nor a callback it handed to a library (``jax.tree.map``'s function): those continue it. Every stop
is listed with the functions it entered, whether it entered, and whether JAX was tracing
(``traced``: the stop is part of building a compiled program — the Monte-Carlo batch, FORM's limit
state and its gradient, the linear response, the finer grid's batch — each of which reads the
study's evaluation, ``study`` → ``metrics``, once). The counts are given in four views: the whole
command and the sweep itself (from ``run_sweep`` on, the error bar included; the command first
parses the distribution and builds the study), each with and without the stops under tracing (the
orchestration a reader follows). The program store is switched off (``JAXBELT_PROGRAM_STORE=0``),
so every program is traced whatever earlier runs left on disk. Beside the stops, the module call
graph: every call from one ``jaxbelt.design`` module into another (caller → callee, with its count),
whether that graph has a cycle (a module calling back into one that called it), and per module the
modules it is called from. Writes ``results/call_path.json``.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/call_path.py``.
"""

import collections
import contextlib
import io
import os
import sys
import tempfile
from pathlib import Path

from _common import write

from jax._src.core import trace_state_clean  # whether JAX is tracing (no public name)

from jaxbelt.cli import main as cli

SMALL = """extends = "three-roller-tolerance"
[mesh]
n_eta = 2
[time]
t_end_s = 0.24
"""
DIST = """[roller."roller 2"]
rotation_mrad = {dist = "normal", sigma = [0.05, 0.05, 0.0]}
"""
PACKAGE = "jaxbelt.design"
SWEEP = ("jaxbelt.design.sweep", "run_sweep")  # where the sweep itself starts


def main():
    os.environ["JAXBELT_PROGRAM_STORE"] = "0"  # trace every program (module docstring)
    events = []  # every call into the package: {"module", "function", "traced", "entered", "sweep"}
    edges = collections.Counter()
    in_sweep = [False]

    def profile(frame, event, arg):
        if event != "call":
            return
        module = frame.f_globals.get("__name__", "")
        if not module.startswith(PACKAGE):
            return
        if module == SWEEP[0] and frame.f_code.co_name == SWEEP[1]:
            in_sweep[0] = True
        events.append({"module": module, "function": frame.f_code.co_name, "traced": not trace_state_clean(),
                       "entered": not _on_stack(frame.f_back, module), "sweep": in_sweep[0]})
        caller = frame.f_back.f_globals.get("__name__", "") if frame.f_back is not None else ""
        if caller.startswith(PACKAGE) and caller != module:
            edges[(caller, module)] += 1

    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        (d / "small.toml").write_text(SMALL)
        (d / "dist.toml").write_text(DIST)
        argv = ["sweep", str(d / "small.toml"), "--dist", str(d / "dist.toml"), "--samples", "24",
                "--solver", "reuse", "--json"]
        sys.setprofile(profile)
        try:
            with contextlib.redirect_stdout(io.StringIO()):
                rc = cli(argv)
        finally:
            sys.setprofile(None)
    if rc != 0:
        raise SystemExit(f"jaxbelt {' '.join(argv)}: exit code {rc}")
    views = {"command": events, "command_outside_tracing": [e for e in events if not e["traced"]],
             "sweep": [e for e in events if e["sweep"]],
             "sweep_outside_tracing": [e for e in events if e["sweep"] and not e["traced"]]}
    counts = {name: _counts(_stops(v)) for name, v in views.items()}
    callers = collections.defaultdict(set)
    for a, b in edges:
        callers[b].add(a)
    write("call_path", {"command": "jaxbelt sweep SMALL --dist DIST --samples 24 --solver reuse",
                        **{k: v for k, v in counts["command"].items()}, "views": counts,
                        "calls_between_modules": [{"caller": a, "callee": b, "calls": n}
                                                  for (a, b), n in edges.most_common()],
                        "call_graph_has_a_cycle": _has_cycle(edges),
                        "called_from": {m: sorted(c) for m, c in sorted(callers.items())},
                        "path": _stops(events)})
    for name, c in counts.items():
        print(f"{name}: {c['stops']} stops in {c['modules']} modules, {c['returns_to_a_module_left']} returns; "
              f"entries per module at most {c['most_entries']} ({c['entries_per_module']})")
    print(f"{len(edges)} caller-callee module pairs, cycle: {_has_cycle(edges)}")


def _on_stack(frame, module: str) -> bool:
    """Whether a frame of ``module`` is among ``frame`` and its callers: a call into ``module`` then
    continues it (its own helper, a callback it handed to a library), it does not enter it."""
    while frame is not None:
        if frame.f_globals.get("__name__", "") == module:
            return True
        frame = frame.f_back
    return False


def _stops(events) -> list[dict]:
    """Consecutive ``events`` in one module joined into stops: ``{"module", "functions", "traced",
    "entered"}``, the last two those of the stop's first call."""
    out = []
    for e in events:
        if not out or out[-1]["module"] != e["module"]:
            out.append({"module": e["module"], "functions": [], "traced": e["traced"], "entered": e["entered"]})
        if e["function"] not in out[-1]["functions"]:
            out[-1]["functions"].append(e["function"])
    return out


def _counts(stops) -> dict:
    """A path's stops, modules, returns (a stop in a module the path had left), stops per module,
    and entries per module (stops whose first call came from outside the module: not a call of
    its own helper or callback after a callee returned)."""
    modules = [s["module"] for s in stops]
    seen, returns = set(), 0
    for m in modules:
        returns += m in seen
        seen.add(m)
    entries = collections.Counter(s["module"] for s in stops if s["entered"])
    return {"stops": len(modules), "modules": len(seen), "returns_to_a_module_left": returns,
            "stops_per_module": dict(collections.Counter(modules).most_common()),
            "entries_per_module": dict(entries.most_common()), "most_entries": max(entries.values(), default=0)}


def _has_cycle(edges) -> bool:
    """Whether the module call graph ``{(caller, callee): calls}`` has a directed cycle."""
    graph = collections.defaultdict(set)
    for a, b in edges:
        graph[a].add(b)
    state = {}

    def visit(m):
        state[m] = "open"
        for n in graph[m]:
            if state.get(n) == "open" or (n not in state and visit(n)):
                return True
        state[m] = "done"
        return False

    return any(m not in state and visit(m) for m in list(graph))


if __name__ == "__main__":
    main()
