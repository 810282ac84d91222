"""No import cycles between the modules or subpackages of one package, at any depth, lazy and
TYPE_CHECKING imports included.

A cycle hidden behind an import inside a function or ``if TYPE_CHECKING:`` is still a cycle of
concepts: two modules that each need the other are one concept split for size. Two subpackages
are tied the same way when a module of one imports a module of the other and back (``a.b.x ->
a.c.y`` and ``a.c.z -> a.b.w`` make ``a.b`` and ``a.c`` one concept). The graph is read from the
source (``ast``), so nothing is imported to build it. import-linter's ``acyclic_siblings``
contract (pyproject.toml) checks the same on its own graph.
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


def _sibling_edge(importer: str, imported: str) -> tuple[str, str] | None:
    """The import ``importer -> imported`` as an edge between the two children of their nearest
    common package (``a.b.x.m -> a.c.n`` is ``a.b -> a.c``); ``None`` when one module is the
    other's package or inside it."""
    mp, dp = importer.split("."), imported.split(".")
    i = 0
    while i < min(len(mp), len(dp)) and mp[i] == dp[i]:
        i += 1
    if i == len(mp) or i == len(dp):
        return None
    return ".".join(mp[: i + 1]), ".".join(dp[: i + 1])


def _cycles_within_packages(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components (Tarjan) of the graph of siblings: every import seen between
    the children of the nearest package that holds both ends (modules or subpackages)."""
    sib: dict[str, set[str]] = defaultdict(set)
    for m, deps in graph.items():
        for d in deps:
            edge = _sibling_edge(m, d)
            if edge is not None:
                sib[edge[0]].add(edge[1])
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


def test_the_cycle_finder_finds_a_cycle_between_subpackages() -> None:
    """``p.a`` and ``p.b`` need each other through different modules: no two modules form a
    cycle, the two subpackages do."""
    graph = {"p.a.x": {"p.b.y"}, "p.b.z": {"p.a.w"}, "p.a.w": set(), "p.b.y": set(), "p.c": {"p.a.x"}}
    assert _cycles_within_packages(graph) == [["p.a", "p.b"]]


def test_a_package_importing_its_own_modules_is_no_cycle() -> None:
    graph = {"p.a": {"p.a.x"}, "p.a.x": {"p.a"}, "p.a.y": {"p.a.x"}}
    assert _cycles_within_packages(graph) == []


def test_no_import_cycles_between_modules_or_subpackages_of_one_package() -> None:
    cycles = _cycles_within_packages(_graph())
    assert cycles == [], f"import cycles between siblings: {cycles}"
