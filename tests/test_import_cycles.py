"""No import cycles between the modules of one package, lazy and TYPE_CHECKING imports included.

A cycle hidden behind an import inside a function or ``if TYPE_CHECKING:`` is still a cycle of
concepts: two modules that each need the other are one concept split for size. The graph is
read from the source (``ast``), so nothing is imported to build it.
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("api", "station", "db", "bench", "drivers")
TYPE_ONLY_ALLOWED = ("db.models",)
"""Packages whose ``if TYPE_CHECKING:`` imports are not counted: SQLAlchemy models with
relationships in both directions name each other's classes in their annotations."""


def _type_checking_nodes(tree: ast.AST) -> set[int]:
    """ids of the import nodes inside ``if TYPE_CHECKING:`` blocks."""
    out: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            out |= {id(n) for b in node.body for n in ast.walk(b)}
    return out


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports(path: Path, name: str, modules: set[str]) -> set[str]:
    """Modules of ours that ``path`` imports anywhere in its body (resolved to existing modules)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    is_pkg = path.name == "__init__.py"
    skip = _type_checking_nodes(tree) if name.startswith(TYPE_ONLY_ALLOWED) else set()
    out: set[str] = set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                pkg = name.split(".") if is_pkg else name.split(".")[:-1]
                pkg = pkg[: len(pkg) - (node.level - 1)]
                base = ".".join([*pkg, base] if base else pkg)
            targets = [f"{base}.{a.name}" for a in node.names] + [base]
        for t in targets:
            while t and t not in modules:
                t = t.rpartition(".")[0]
            if t and t != name:
                out.add(t)
    return out


def _graph() -> dict[str, set[str]]:
    files = [p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")]
    names = {p: _module_name(p) for p in files}
    modules = set(names.values())
    return {names[p]: _imports(p, names[p], modules) for p in files}


def _parent(m: str) -> str:
    return m.rpartition(".")[0]


def _cycles_within_packages(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components (Tarjan) of the graph restricted to sibling modules."""
    sib: dict[str, set[str]] = defaultdict(set)
    for m, deps in graph.items():
        sib[m] = {d for d in deps if _parent(d) == _parent(m) and not m.startswith(d + ".")}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sib[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in list(sib):
        if v not in index:
            visit(v)
    return out


def test_the_cycle_finder_finds_a_known_cycle() -> None:
    graph = {"p.a": {"p.b"}, "p.b": {"p.c"}, "p.c": {"p.a"}, "p.d": {"p.a"}, "q.e": set()}
    assert _cycles_within_packages(graph) == [["p.a", "p.b", "p.c"]]


def test_no_import_cycles_between_modules_of_one_package() -> None:
    cycles = _cycles_within_packages(_graph())
    assert cycles == [], f"import cycles between sibling modules: {cycles}"
