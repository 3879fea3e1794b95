"""How a sweep's study travels through the design package: the module stops of ``jaxbelt sweep``.

Runs ``jaxbelt sweep`` in-process on a small scene (the three-roller machine with two element rows,
24 Monte-Carlo samples, FORM and the error bar as by default) under a profiler that records every Python call into a module of
``jaxbelt.design`` (tracing included: it is the code a reader follows). Consecutive calls within
one module are one *stop*; a stop in a module the path had already left is a *return* (a property
read on the study, ``study.steered``, is a stop in ``study`` too). Every stop is listed with the
functions it entered and whether JAX was tracing when it was entered (``traced``: the stop is
part of building a compiled program — the Monte-Carlo batch, FORM's limit state and its gradient,
the linear response, the finer grid's batch — each of which reads the study's evaluation,
``study`` → ``metrics``, once); the counts are given for the whole path and for the part outside
tracing (the orchestration a reader follows from ``run_sweep``). The program store is switched off
(``JAXBELT_PROGRAM_STORE=0``), so every program is traced whatever earlier runs left on disk. Beside
the stops, the module call graph: every call from one ``jaxbelt.design`` module into another (caller
→ callee, with its count), whether that graph has a cycle (a module calling back into one that
called it), and per module the modules it is called from. Writes ``results/call_path.json``.

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

os.environ["JAXBELT_PROGRAM_STORE"] = "0"  # trace every program (module docstring)

from jax._src.core import trace_state_clean  # noqa: E402  (whether JAX is tracing: no public name)

from jaxbelt.cli import main as cli  # noqa: E402

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
    stops = []  # {"module", "functions", "traced"}

    edges = collections.Counter()

    def profile(frame, event, arg):
        if event != "call":
            return
        module = frame.f_globals.get("__name__", "")
        if module.startswith(PACKAGE):
            if not stops or stops[-1]["module"] != module:
                stops.append({"module": module, "functions": [], "traced": not trace_state_clean()})
            if frame.f_code.co_name not in stops[-1]["functions"]:
                stops[-1]["functions"].append(frame.f_code.co_name)
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
    modules = [s["module"] for s in stops]
    outside = _merged([s for s in stops if not s["traced"]])
    callers = collections.defaultdict(set)
    for a, b in edges:
        callers[b].add(a)
    whole, orchestration = _counts(modules), _counts([s["module"] for s in outside])
    write("call_path", {"command": "jaxbelt sweep SMALL --dist DIST --samples 24 --solver reuse",
                        **whole, "outside_tracing": orchestration,
                        "calls_between_modules": [{"caller": a, "callee": b, "calls": n}
                                                  for (a, b), n in edges.most_common()],
                        "call_graph_has_a_cycle": _has_cycle(edges),
                        "called_from": {m: sorted(c) for m, c in sorted(callers.items())}, "path": stops})
    print(f"{whole['stops']} stops in {whole['modules']} modules, {whole['returns_to_a_module_left']} returns "
          f"(outside tracing: {orchestration['stops']} stops, {orchestration['returns_to_a_module_left']} returns); "
          f"{len(edges)} caller-callee module pairs, cycle: {_has_cycle(edges)}")


def _merged(stops):
    """``stops`` with consecutive ones in one module joined (a traced stop left out between them)."""
    out = []
    for s in stops:
        if out and out[-1]["module"] == s["module"]:
            out[-1] = {**out[-1], "functions": out[-1]["functions"] + [f for f in s["functions"]
                                                                        if f not in out[-1]["functions"]]}
        else:
            out.append(s)
    return out


def _counts(modules) -> dict:
    """Stops, modules, returns (a stop in a module the path had left) and stops per module of a path."""
    seen, returns = set(), 0
    for m in modules:
        returns += m in seen
        seen.add(m)
    return {"stops": len(modules), "modules": len(seen), "returns_to_a_module_left": returns,
            "stops_per_module": dict(collections.Counter(modules).most_common())}


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
