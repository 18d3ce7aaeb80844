"""The layers import only downward (analysis -> study -> app), modules import no circle, and
imports hidden inside functions stay few and each says why.

Every module under app/, study/ and analysis/ is parsed (not imported); every ``import`` and
``from ... import`` of a project module counts, at module level or inside a function.
``from package import name`` counts as an import of ``package.name`` when that is a module,
else of ``package`` (whose ``__init__`` runs). A function-level import is justified when its
line, or the line above it, carries a comment (the measured reason: start-up time, an optional
heavy dependency ...); an import circle is never a reason. Imports under ``if TYPE_CHECKING:``
count for the layers (a type names its layer too) but not for circles (they never run).
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ("app", "study", "analysis")
"""Lowest first: a package may import its own layer and those before it."""
MAX_FUNCTION_LEVEL_IMPORTS = 3
"""Function-level imports of project modules, intra-package ones included (one per statement
and imported module): the three left are analysis's study imports that pull in pinocchio
(+0.8-1.1 s measured) for commands that read exported files only. Add one only with a reason."""
MAX_UNEXPLAINED = 0
"""Of those, the ones without a comment giving the measured reason: none."""


@dataclass(frozen=True)
class Import:
    source: str  # importing module, dotted
    target: str  # imported project module, dotted
    path: Path
    line: int
    in_function: bool
    commented: bool
    type_only: bool = False  # under ``if TYPE_CHECKING:``: never runs

    def __str__(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}: {self.source} -> {self.target}"


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def project_modules() -> dict[str, Path]:
    return {
        module_name(p): p
        for layer in LAYERS
        for p in sorted((ROOT / layer).rglob("*.py"))
        if ".venv" not in p.parts
    }


def _resolve(name: str, modules: dict[str, Path]) -> str | None:
    """The longest prefix of dotted ``name`` that is a project module."""
    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        candidate = ".".join(parts[:k])
        if candidate in modules:
            return candidate
    return None


def _commented(lines: list[str], line: int) -> bool:
    here = lines[line - 1]
    above = lines[line - 2].strip() if line >= 2 else ""
    return "#" in here or above.startswith("#")


def imports_of(name: str, path: Path, modules: dict[str, Path]) -> list[Import]:
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines()
    tree = ast.parse(text, filename=str(path))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out: list[Import] = []

    def visit(node: ast.AST, in_function: bool, type_only: bool) -> None:
        for child in ast.iter_child_nodes(node):
            inner = in_function or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef)
            typing_block = type_only or (
                isinstance(child, ast.If) and "TYPE_CHECKING" in ast.unparse(child.test)
            )
            targets: list[str] = []
            if isinstance(child, ast.Import):
                targets = [a.name for a in child.names]
            elif isinstance(child, ast.ImportFrom):
                base = child.module or ""
                if child.level:
                    anchor = package.split(".")
                    anchor = anchor[: len(anchor) - (child.level - 1)]
                    base = ".".join([*anchor, base] if base else anchor)
                targets = [f"{base}.{a.name}" for a in child.names]
            for target in targets:
                resolved = _resolve(target, modules)
                if resolved is not None and resolved != name:
                    out.append(
                        Import(
                            name,
                            resolved,
                            path,
                            child.lineno,
                            in_function,
                            _commented(lines, child.lineno),
                            type_only,
                        )
                    )
            visit(child, inner, typing_block)

    visit(tree, False, False)
    return list(dict.fromkeys(out))  # one per statement and target


def all_imports() -> list[Import]:
    modules = project_modules()
    return [imp for name, path in modules.items() for imp in imports_of(name, path, modules)]


def _layer(module: str) -> int:
    return LAYERS.index(module.split(".")[0])


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import circle as a path ``[a, b, ..., a]``, or ``None``."""
    state: dict[str, int] = {}  # 1 on the stack, 2 done
    stack: list[str] = []

    def dfs(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return [*stack[stack.index(nxt) :], nxt]
            if nxt not in state and (found := dfs(nxt)) is not None:
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := dfs(node)) is not None:
            return found
    return None


def _package_edge(imp: Import) -> bool:
    """An import of a package's ``__init__`` by one of its own modules (the package re-exports
    the module: a circle by construction that Python resolves, not a design circle)."""
    return imp.source.startswith(imp.target + ".")


def test_layers_import_only_downward() -> None:
    upward = [str(i) for i in all_imports() if _layer(i.target) > _layer(i.source)]
    assert not upward, "upward imports (app <- study <- analysis):\n" + "\n".join(upward)


def test_modules_import_no_circle() -> None:
    graph: dict[str, set[str]] = {}
    for imp in all_imports():
        if not _package_edge(imp) and not imp.type_only:
            graph.setdefault(imp.source, set()).add(imp.target)
    cycle = find_cycle(graph)
    assert cycle is None, "import circle: " + " -> ".join(cycle or [])


def test_function_level_imports_are_few_and_say_why() -> None:
    hidden = [i for i in all_imports() if i.in_function]
    unexplained = [i for i in hidden if not i.commented]
    print(
        f"\n{len(hidden)} function-level project imports (ceiling {MAX_FUNCTION_LEVEL_IMPORTS}),"
        f" {len(unexplained)} without a reason (ceiling {MAX_UNEXPLAINED}):"
    )
    for imp in hidden:
        print(f"  {imp}{'' if imp.commented else '   (no reason given)'}")
    assert len(hidden) <= MAX_FUNCTION_LEVEL_IMPORTS
    assert len(unexplained) <= MAX_UNEXPLAINED


def test_the_checks_see_what_they_should(tmp_path: Path) -> None:
    """The walker finds a function-level import, resolves relative imports and names a circle."""
    modules = {"app.a": tmp_path / "a.py", "app.b": tmp_path / "b.py", "study.c": tmp_path / "c.py"}
    modules["app.a"].write_text("def f():\n    # measured: 0.4 s\n    from study.c import x\n")
    modules["app.b"].write_text("from . import a\n")
    found = imports_of("app.a", modules["app.a"], modules)
    assert [(i.target, i.in_function, i.commented) for i in found] == [("study.c", True, True)]
    assert [i.target for i in imports_of("app.b", modules["app.b"], modules)] == ["app.a"]
    assert find_cycle({"x": {"y"}, "y": {"z"}, "z": {"x"}}) == ["x", "y", "z", "x"]
    assert find_cycle({"x": {"y"}, "y": set()}) is None


def test_types_name_no_circle() -> None:
    """Even type-only imports (under ``if TYPE_CHECKING:``) form no circle: a type named from
    a module that imports back is a design circle that only the guard hides."""
    graph: dict[str, set[str]] = {}
    for imp in all_imports():
        if not _package_edge(imp):
            graph.setdefault(imp.source, set()).add(imp.target)
    cycle = find_cycle(graph)
    assert cycle is None, "import circle (type-only imports counted): " + " -> ".join(cycle or [])
