"""How a sweep's study travels through the design package: the module stops of ``jaxbelt sweep``.

Runs ``jaxbelt sweep`` in-process on a small scene (the three-roller machine with two element rows,
24 Monte-Carlo samples, FORM and the error bar as by default) under a profiler that records every Python call into a module of
``jaxbelt.design`` (tracing included: it is the code a reader follows). Consecutive calls within
one module are one *stop*; a stop in a module the path had already left is a *return* (a property
read on the study, ``study.steered``, is a stop in ``study`` too). Beside the stops, the module
call graph: every call from one ``jaxbelt.design`` module into another (caller → callee, with
its count), whether that graph has a cycle (a module calling back into one that called it),
and per module the modules it is called from. Writes ``results/call_path.json``: the stops in
order, their count, the modules entered, the returns, the stops per module, and the call graph.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/call_path.py``.
"""

import collections
import contextlib
import io
import sys
import tempfile
from pathlib import Path

from _common import write

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


def main():
    stops = []

    edges = collections.Counter()

    def profile(frame, event, arg):
        if event != "call":
            return
        module = frame.f_globals.get("__name__", "")
        if module.startswith(PACKAGE) and (not stops or stops[-1] != module):
            stops.append(module)
        caller = frame.f_back.f_globals.get("__name__", "") if frame.f_back is not None else ""
        if module.startswith(PACKAGE) and caller.startswith(PACKAGE) and caller != module:
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
    seen, returns = set(), 0
    for i, m in enumerate(stops):
        returns += m in seen
        seen.add(m)
    callers = collections.defaultdict(set)
    for a, b in edges:
        callers[b].add(a)
    write("call_path", {"command": "jaxbelt sweep SMALL --dist DIST --samples 24 --solver reuse",
                        "stops": len(stops), "modules": len(seen), "returns_to_a_module_left": returns,
                        "stops_per_module": dict(collections.Counter(stops).most_common()),
                        "calls_between_modules": [{"caller": a, "callee": b, "calls": n}
                                                  for (a, b), n in edges.most_common()],
                        "call_graph_has_a_cycle": _has_cycle(edges),
                        "called_from": {m: sorted(c) for m, c in sorted(callers.items())}, "path": stops})
    print(f"{len(stops)} stops in {len(seen)} modules, {returns} returns; "
          f"{len(edges)} caller-callee module pairs, cycle: {_has_cycle(edges)}")


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
