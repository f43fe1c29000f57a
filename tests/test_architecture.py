"""The package's shape: layers that only import downwards, no cycles, imports at the top, small
modules. Read from the source files (``ast``), so nothing is imported to check it."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).parents[1] / "sswjax"

LAYERS = (
    ("sswjax._checks", "sswjax._files", "sswjax._version"),
    ("sswjax.stages",),
    ("sswjax.config",),
    ("sswjax.graph",),
    ("sswjax.runtime",),
    ("sswjax.api",),
    ("sswjax.data",),
    ("sswjax.cluster",),
    ("sswjax.evaluation",),
    ("sswjax.search",),
    ("sswjax.cli",),
)
"""The layers, lowest first: a module imports only from its own layer and those before it."""

OPTIONAL = ("cv2", "pandora", "pandora_plugin_libsgm", "xarray", "matplotlib", "plyfile", "py7zr",
            "tifffile", "open3d", "dask", "distributed", "zstandard", "fcntl")
"""Optional dependencies, and modules of some systems only (``fcntl``: not on Windows): the only
imports allowed inside functions or blocks (they may be absent)."""

MAX_LINES = 400


def _modules() -> dict[str, Path]:
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        found[".".join(parts)] = path
    return found


MODULES = _modules()


def _layer(module: str) -> int:
    for index, prefixes in enumerate(LAYERS):
        if any(module == p or module.startswith(p + ".") for p in prefixes):
            return index
    if module == "sswjax":
        return len(LAYERS)  # the public aliases, above everything
    raise AssertionError(f"{module} is in no layer of tests/test_architecture.py")


def _imports(module: str, source: str | None = None) -> list[tuple[str, ast.stmt, bool]]:
    """``(imported sswjax module, node, at the top)`` of a module's imports of the package."""
    tree = ast.parse(MODULES[module].read_text() if source is None else source)
    top = {id(node) for node in tree.body}
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            base = node.module
            names = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in MODULES else base
                     for alias in node.names]
        else:
            continue
        out += [(name, node, id(node) in top) for name in names if name.split(".")[0] == "sswjax"]
    return out


def test_every_module_is_in_a_layer():
    for module in MODULES:
        _layer(module)


@pytest.mark.parametrize("module", sorted(MODULES))
def test_imports_only_go_down(module):
    for target, node, _ in _imports(module):
        assert target in MODULES, f"{module}:{node.lineno} imports {target}, which does not exist"
        if module != "sswjax":
            assert target != "sswjax", (f"{module}:{node.lineno} imports the package itself; "
                                        "import the submodule")
        assert _layer(target) <= _layer(module), (
            f"{module}:{node.lineno} imports {target}, a layer above it")


def _cycle(graph: dict[str, list[str]]) -> list[str] | None:
    """A cycle of a directed graph (module -> the modules it imports), or None."""
    state: dict[str, int] = {}  # 1: on the stack, 2: done
    stack: list[str] = []

    def visit(module):
        state[module] = 1
        stack.append(module)
        for target in graph.get(module, ()):
            if state.get(target) == 1:
                return stack[stack.index(target):] + [target]
            if target not in state:
                found = visit(target)
                if found:
                    return found
        stack.pop()
        state[module] = 2
        return None

    for module in graph:
        if module not in state:
            found = visit(module)
            if found:
                return found
    return None


def _named_commands() -> list[str]:
    """``sswjax.cli.app.COMMANDS``, read from its source: the command modules it imports by name
    (only the chosen one is imported, to keep a command's start-up short)."""
    for node in ast.parse(MODULES["sswjax.cli.app"].read_text()).body:
        if (isinstance(node, ast.Assign) and len(node.targets) == 1
                and getattr(node.targets[0], "id", None) == "COMMANDS"):
            return list(ast.literal_eval(node.value))
    raise AssertionError("sswjax.cli.app has no COMMANDS")


def test_each_named_command_is_a_cli_module_that_adds_its_parser():
    for name in _named_commands():
        module = f"sswjax.cli.{name}"
        assert module in MODULES, f"sswjax.cli.app names the command {name}; {module} is missing"
        functions = {node.name for node in ast.parse(MODULES[module].read_text()).body
                     if isinstance(node, ast.FunctionDef)}
        assert f"add_{name}_command" in functions, f"{module} has no add_{name}_command"


def test_no_import_cycle():
    graph = {module: sorted({target for target, _, _ in _imports(module)}) for module in MODULES}
    graph["sswjax.cli.app"] += [f"sswjax.cli.{name}" for name in _named_commands()]
    cycle = _cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def _inner_imports(source: str) -> list[tuple[str, int]]:
    """``(imported module, line)`` of the imports that are not at a module's top level and not
    of an optional dependency."""
    tree = ast.parse(source)
    top = {id(node) for node in tree.body}
    found = []
    for node in ast.walk(tree):
        if not isinstance(node, (ast.Import, ast.ImportFrom)) or id(node) in top:
            continue
        names = ([alias.name for alias in node.names] if isinstance(node, ast.Import)
                 else [node.module or ""])
        found += [(name, node.lineno) for name in names if name.split(".")[0] not in OPTIONAL]
    return found


@pytest.mark.parametrize("module", sorted(MODULES))
def test_imports_are_at_the_top(module):
    inner = _inner_imports(MODULES[module].read_text())
    assert not inner, (f"{module} imports {inner} inside a function or block; only optional "
                       f"dependencies ({', '.join(OPTIONAL)}) may be")


@pytest.mark.parametrize("module", sorted(MODULES))
def test_modules_are_small(module):
    lines = len(MODULES[module].read_text().splitlines())
    assert lines <= MAX_LINES, f"{module} has {lines} lines (at most {MAX_LINES})"


def test_the_checks_see_what_they_forbid():
    """The walkers above find an inner import, an upward import and a cycle when there is one."""
    source = ("import os\nfrom sswjax.cli import main\n\n\ndef f():\n    import json\n"
              "    import cv2\n    from sswjax.graph import ssw_disparity\n")
    assert _inner_imports(source) == [("json", 6), ("sswjax.graph", 8)]
    imported = _imports("sswjax.stages.cost", source)
    assert [(target, top) for target, _, top in imported] == [("sswjax.cli", True),
                                                             ("sswjax.graph", False)]
    assert _layer("sswjax.cli") > _layer("sswjax.stages.cost")
    assert _cycle({"a": ["b"], "b": ["c"], "c": ["a"]}) == ["a", "b", "c", "a"]
    assert _cycle({"a": ["b", "c"], "b": ["c"], "c": []}) is None
