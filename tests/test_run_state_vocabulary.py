"""One run-state vocabulary: ``bench.run_state.RunState``.

The bench, the database, the REST schema and the live state all name a run's state with that
enum. This test reads the source of every package and fails on a second vocabulary: another
``Enum`` with run-state members, a ``Literal`` of state names, a collection of state-name
strings, or a comparison of something with a state-name string (a state read by string).
Historic migrations are frozen text and are not read.
"""

from __future__ import annotations

import ast
from pathlib import Path

from bench.run_state import RunState

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("api", "bench", "db", "drivers")
HOME = ROOT / "bench" / "run_state.py"
STATE_NAMES = frozenset(s.value for s in RunState) | {"pending", "finished"}
"""The values of the enum and the names the bench's former vocabulary used."""
# "error" and "running" are ordinary words of other vocabularies (a log level, a bench's
# process); they count only beside another state name.
DISTINCT = STATE_NAMES - {"error", "running"}


def _sources() -> list[Path]:
    files = [p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")]
    return [p for p in files if "migrations" not in p.parts]


def _strings(nodes: list[ast.expr]) -> set[str]:
    return {n.value for n in nodes if isinstance(n, ast.Constant) and isinstance(n.value, str)}


def _is_enum_class(node: ast.ClassDef) -> bool:
    names = {
        b.id if isinstance(b, ast.Name) else b.attr if isinstance(b, ast.Attribute) else ""
        for b in node.bases
    }
    return any(n.endswith("Enum") for n in names)


def second_vocabularies(tree: ast.AST) -> list[tuple[int, str]]:
    """Where ``tree`` names run states other than through the enum: (line, what)."""
    found: list[tuple[int, str]] = []
    literal_args: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef) and _is_enum_class(node):
            values = _strings([s.value for s in node.body if isinstance(s, ast.Assign)])
            if len(values & STATE_NAMES) >= 2:
                found.append((node.lineno, f"enum {node.name} of run states"))
        elif (
            isinstance(node, ast.Subscript)
            and getattr(node.value, "id", getattr(node.value, "attr", "")) == "Literal"
        ):
            literal_args.add(id(node.slice))
            elts = node.slice.elts if isinstance(node.slice, ast.Tuple) else [node.slice]
            if len(_strings(elts) & STATE_NAMES) >= 2:
                found.append((node.lineno, "Literal of run states"))
        elif isinstance(node, ast.Tuple | ast.List | ast.Set) and id(node) not in literal_args:
            if len(_strings(node.elts) & STATE_NAMES) >= 2:
                found.append((node.lineno, "collection of run-state strings"))
        elif isinstance(node, ast.Dict):
            keys = [k for k in node.keys if k is not None]
            if len((_strings(keys) | _strings(node.values)) & STATE_NAMES) >= 2:
                found.append((node.lineno, "mapping of run-state strings"))
        elif isinstance(node, ast.AnnAssign) and getattr(node.target, "id", "") == "state":
            if "str" in ast.unparse(node.annotation).replace("'", "").split(" | "):
                found.append((node.lineno, "state held as a str"))
        elif isinstance(node, ast.Compare) and _strings([node.left, *node.comparators]) & DISTINCT:
            found.append((node.lineno, "state compared with a string"))
    return found


def test_the_detector_finds_each_kind_of_second_vocabulary() -> None:
    sample = (
        "import enum\n"
        "from typing import Literal\n"
        "class S(enum.Enum):\n    A = 'queued'\n    B = 'paused'\n"
        "Name = Literal['running', 'completed']\n"
        "LIVE = ('queued', 'running')\n"
        "WIRE = {'pending': 'queued'}\n"
        "ok = state == 'interrupted'\n"
        "fine = level == 'error'\n"
        "X = ('idle', 'busy', 'offline')\n"
        "class Live:\n    state: str = 'queued'\n"
    )
    lines = [line for line, _ in second_vocabularies(ast.parse(sample))]
    assert sorted(lines) == [3, 6, 7, 8, 9, 13]


def test_one_run_state_vocabulary_remains() -> None:
    problems = []
    for path in _sources():
        if path == HOME:
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        problems += [f"{path.relative_to(ROOT)}:{line}: {what}" for line, what in second_vocabularies(tree)]
    hint = "a second run-state vocabulary (use bench.run_state.RunState):\n"
    assert not problems, hint + "\n".join(problems)


def test_the_home_defines_the_enum_once() -> None:
    tree = ast.parse(HOME.read_text(encoding="utf-8"))
    assert [what for _, what in second_vocabularies(tree)] == ["enum RunState of run states"]
