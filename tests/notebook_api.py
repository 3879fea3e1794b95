"""A static check of the notebooks' use of the jaxbelt API, for the default test run (the
notebooks' execution is slow: tests/unit/test_notebooks.py).

Without running a cell, it checks what breaks a notebook when the library changes under it:
every code cell compiles; every name a notebook imports from ``jaxbelt`` exists; every attribute
chain rooted at an imported jaxbelt module or object (``jb.simulate``, ``plot.plot_fields``,
``design.sampling.X``) resolves; every call of a jaxbelt function or class passes only keywords
its signature takes, no more positional arguments than it has and — unless it unpacks ``*args``
or ``**options`` — every argument it requires (``jb.simulate(model, n_steps=10)`` lacks ``dt``);
and every option (``--x``) of a ``jaxbelt`` command-line call written as a literal list is one
that command's parser knows. Calls on values the notebook computes (``study.space.labels()``,
``fit.predict(...)``) cannot be resolved without running it and are left to the execution test."""

import argparse
import ast
import importlib
import inspect
import types


def _import_bindings(tree: ast.Module) -> dict:
    """``{local name: object}`` for the notebook's ``import jaxbelt…`` / ``from jaxbelt… import``
    statements; an import that fails (a missing module or name) raises ``AssertionError``."""
    bound = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "jaxbelt":
                    module = importlib.import_module(alias.name)
                    if alias.asname:
                        bound[alias.asname] = module
                    else:
                        bound["jaxbelt"] = importlib.import_module("jaxbelt")
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "jaxbelt":
            module = importlib.import_module(node.module)
            for alias in node.names:
                if hasattr(module, alias.name):
                    obj = getattr(module, alias.name)
                else:  # a submodule imported by name
                    try:
                        obj = importlib.import_module(f"{node.module}.{alias.name}")
                    except ModuleNotFoundError:
                        raise AssertionError(f"line {node.lineno}: {node.module} has no {alias.name!r}") from None
                bound[alias.asname or alias.name] = obj
    return bound


def _chain(node):
    """``["jb", "rom", "fit_dmd"]`` for ``jb.rom.fit_dmd``; None if not a name chain."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name):
        return [node.id, *reversed(parts)]
    return None


def _resolve(parts, bound, lineno):
    """The object a chain names, or None where it leaves what can be resolved statically."""
    obj = bound[parts[0]]
    for i, name in enumerate(parts[1:], 1):
        if not isinstance(obj, (types.ModuleType, type)):
            return None  # an attribute of a value (a dataclass instance, a function): not checked
        if not hasattr(obj, name):
            if isinstance(obj, types.ModuleType):
                try:
                    obj = importlib.import_module(f"{obj.__name__}.{name}")
                    continue
                except ModuleNotFoundError:
                    pass
            raise AssertionError(f"line {lineno}: {'.'.join(parts[:i])} has no attribute {name!r}")
        obj = getattr(obj, name)
    return obj


def _check_call(call: ast.Call, fn, label, lineno):
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):
        return
    params = list(sig.parameters.values())
    if not any(p.kind is p.VAR_KEYWORD for p in params):
        names = {p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)}
        for kw in call.keywords:
            if kw.arg is not None and kw.arg not in names:
                raise AssertionError(f"line {lineno}: {label}() takes no keyword {kw.arg!r}")
    starred = any(isinstance(a, ast.Starred) for a in call.args)
    if not any(p.kind is p.VAR_POSITIONAL for p in params) and not starred:
        n_pos = sum(p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) for p in params)
        if len(call.args) > n_pos:
            raise AssertionError(f"line {lineno}: {label}() takes at most {n_pos} positional arguments, "
                                 f"the notebook passes {len(call.args)}")
    if starred or any(kw.arg is None for kw in call.keywords):
        return  # what *args / **options hold is known only when the cell runs
    positional = [p for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    given = {p.name for p in positional[:len(call.args)]} | {kw.arg for kw in call.keywords}
    for p in params:
        if p.default is p.empty and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD) and p.name not in given:
            raise AssertionError(f"line {lineno}: {label}() is missing its required argument {p.name!r}")


def _cli_options(command: str) -> set[str]:
    from jaxbelt.cli import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    if command not in sub.choices:
        raise AssertionError(f"jaxbelt has no command {command!r}")
    return {opt for a in sub.choices[command]._actions for opt in a.option_strings}


def check_notebook_api(source: str, name: str = "<notebook>") -> int:
    """Check ``source`` (a notebook's code cells joined) as the module docstring says; returns
    the number of jaxbelt references checked, raises ``AssertionError`` naming the line."""
    tree = ast.parse(source, name)
    bound = _import_bindings(tree)
    cli_names = {k for k, v in bound.items() if getattr(v, "__module__", "") == "jaxbelt.cli" and k != "jaxbelt"}
    checked = 0
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute):
            parts = _chain(node)
            if parts and parts[0] in bound:
                _resolve(parts, bound, node.lineno)
                checked += 1
        elif isinstance(node, ast.Call):
            parts = _chain(node.func)
            if parts and parts[0] in bound:
                fn = _resolve(parts, bound, node.lineno)
                if callable(fn):
                    _check_call(node, fn, ".".join(parts), node.lineno)
                    checked += 1
                if parts[0] in cli_names and node.args and isinstance(node.args[0], ast.List):
                    items = node.args[0].elts
                    if items and isinstance(items[0], ast.Constant) and isinstance(items[0].value, str):
                        known = _cli_options(items[0].value)
                        for item in items[1:]:
                            if isinstance(item, ast.Constant) and isinstance(item.value, str) and item.value.startswith("--"):
                                if item.value.split("=")[0] not in known:
                                    raise AssertionError(f"line {node.lineno}: jaxbelt {items[0].value} has no option "
                                                         f"{item.value!r}")
                                checked += 1
    return checked
