"""The package's import layout (docs/architecture.md): no import cycle, the stages of ``fe/`` import
only down (continuation < axisym < stability < branch < solve), nothing in ``fe/`` imports
``sweep/``, and no name with a leading underscore is imported from another package (nor, in
``fe/``, from another module).

Read from the sources (ast), deferred imports inside functions included; imports under
``if TYPE_CHECKING:`` (annotations only) are not imports at run time and are left out.
"""
from __future__ import annotations

import ast
from pathlib import Path

import snapjump_cli

ROOT = Path(snapjump_cli.__file__).resolve().parent
PKG = "snapjump_cli"

#: The stages of fe/, bottom first; a module may import from its own stage or one below.
FE_ORDER = ("limits", "continuation", "axisym", "stability", "branch", "solve", "precompile")


def _modules() -> dict[str, Path]:
    out = {}
    for f in sorted(ROOT.rglob("*.py")):
        rel = f.relative_to(ROOT.parent).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = f
    return out


def _type_checking(node: ast.AST) -> bool:
    t = node.test if isinstance(node, ast.If) else None
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
        isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING")


def _imports(tree: ast.AST):
    """``(module, [names])`` of every import statement, outside ``if TYPE_CHECKING:`` blocks."""
    stack = [tree]
    while stack:
        node = stack.pop()
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _type_checking(child):
                stack.extend(child.orelse)
                continue
            if isinstance(child, ast.Import):
                for a in child.names:
                    yield a.name, []
            elif isinstance(child, ast.ImportFrom) and child.level == 0 and child.module:
                yield child.module, [a.name for a in child.names]
            stack.append(child)


def _private_crosses(mod: str, target: str, modules: dict[str, Path]) -> bool:
    """Whether importing a private name of ``target`` into ``mod`` breaks the rule: from another
    package, or from another module when either is in fe/ (whose stages share nothing private)."""
    if mod == target:
        return False
    if mod.startswith(f"{PKG}.fe") or target.startswith(f"{PKG}.fe"):
        return True

    def package(m: str) -> str:
        return m if modules.get(m, Path()).name == "__init__.py" else m.rpartition(".")[0]

    return package(mod) != package(target)


def import_graph(modules: dict[str, Path]) -> tuple[dict[str, set[str]], dict[str, set[str]], list[str]]:
    """Module -> the package modules it names in its imports; the same with the packages whose
    ``__init__`` such an import runs; and the private names imported from another module."""
    graph: dict[str, set[str]] = {m: set() for m in modules}
    named: dict[str, set[str]] = {m: set() for m in modules}
    private = []
    for mod, f in modules.items():
        for target, names in _imports(ast.parse(f.read_text(), str(f))):
            if not target.startswith(PKG):
                continue
            found = {target} if target in modules else set()
            for n in names:
                if f"{target}.{n}" in modules:
                    found.add(f"{target}.{n}")
                elif n.startswith("_") and not n.startswith("__") and _private_crosses(mod, target, modules):
                    private.append(f"{mod}: from {target} import {n}")
            named[mod] |= found - {mod}
            parts = target.split(".")
            found |= {".".join(parts[:i]) for i in range(1, len(parts)) if ".".join(parts[:i]) in modules}
            graph[mod] |= found - {mod, PKG}
    return graph, named, private


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle of ``graph`` (its modules, the first repeated at the end), or ``None``."""
    state: dict[str, int] = {}
    path: list[str] = []

    def visit(m: str) -> list[str] | None:
        state[m] = 1
        path.append(m)
        for n in sorted(graph.get(m, ())):
            # a package's __init__ importing its own modules is no cycle with them
            if m.startswith(n + "."):
                continue
            if state.get(n) == 1:
                return path[path.index(n):] + [n]
            if n not in state:
                found = visit(n)
                if found:
                    return found
        path.pop()
        state[m] = 2
        return None

    for m in sorted(graph):
        if m not in state:
            found = visit(m)
            if found:
                return found
    return None


def fe_stage(mod: str) -> int | None:
    parts = mod.split(".")
    if len(parts) < 3 or parts[1] != "fe":
        return None
    return FE_ORDER.index(parts[2]) if parts[2] in FE_ORDER else None


def layout_problems(modules: dict[str, Path] | None = None) -> list[str]:
    """Every breach of the layout, one line each."""
    modules = _modules() if modules is None else modules
    graph, named, private = import_graph(modules)
    out = [f"private name imported across modules: {p}" for p in private]
    cycle = find_cycle(graph)
    if cycle:
        out.append("import cycle: " + " -> ".join(cycle))
    for mod, targets in sorted(named.items()):
        a = fe_stage(mod)
        for t in sorted(targets):
            if mod.startswith(f"{PKG}.fe") and t.startswith(f"{PKG}.sweep"):
                out.append(f"fe imports sweep: {mod} -> {t}")
            b = fe_stage(t)
            if a is not None and b is not None and b > a:
                out.append(f"upward import between the stages of fe/: {mod} -> {t}")
    return out


def test_the_package_has_no_cycle_no_upward_import_and_no_private_import():
    assert layout_problems() == []


def test_every_fe_module_belongs_to_a_stage():
    """A new module of fe/ is placed in one of the stages (or the check above would not see it)."""
    mods = [m for m in _modules() if m.startswith(f"{PKG}.fe.")]
    assert mods and all(fe_stage(m) is not None for m in mods), [m for m in mods if fe_stage(m) is None]


def test_the_check_finds_a_cycle_an_upward_import_and_fe_importing_sweep(tmp_path):
    """The check itself: a small package with each breach is refused, each named."""
    files = {
        "snapjump_cli/__init__.py": "",
        "snapjump_cli/sweep/__init__.py": "",
        "snapjump_cli/sweep/rows.py": "KEYS = ()\n",
        "snapjump_cli/fe/__init__.py": "",
        "snapjump_cli/fe/axisym/__init__.py": "",
        "snapjump_cli/fe/axisym/model.py": "def f():\n    from snapjump_cli.fe.branch.trace import g\n",
        "snapjump_cli/fe/branch/__init__.py": "",
        "snapjump_cli/fe/branch/trace.py": ("from snapjump_cli.fe.axisym.model import f\n"
                                            "from snapjump_cli.sweep.rows import KEYS\n"
                                            "from snapjump_cli.fe.branch.secondary import _h\n"),
        "snapjump_cli/fe/branch/secondary.py": ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                                                "    from snapjump_cli.fe.branch.trace import g\n_h = 1\n"),
    }
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    mods = {}
    for f in sorted((tmp_path / "snapjump_cli").rglob("*.py")):
        parts = list(f.relative_to(tmp_path).with_suffix("").parts)
        mods[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = f
    problems = layout_problems(mods)
    assert any(p.startswith("import cycle: ") and "fe.axisym.model" in p and "fe.branch.trace" in p for p in problems)
    assert "upward import between the stages of fe/: snapjump_cli.fe.axisym.model -> snapjump_cli.fe.branch.trace" in problems
    assert "fe imports sweep: snapjump_cli.fe.branch.trace -> snapjump_cli.sweep.rows" in problems
    assert ("private name imported across modules: snapjump_cli.fe.branch.trace: from "
            "snapjump_cli.fe.branch.secondary import _h") in problems
    assert len(problems) == 4  # (the TYPE_CHECKING import is no cycle)
