"""One ``Thresholds`` holds every knob of the diagnosis; the stages take it as an argument."""

from __future__ import annotations

import ast
import re
from dataclasses import fields, replace
from pathlib import Path

import numpy as np
import pytest

import bench.diagnosis
from bench.diagnosis import StaticEvidence, diagnose
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds, table

PACKAGE = Path(bench.diagnosis.__file__).parent
DEFINITIONS = {"REFERENCE_TEMP_C", "KEEP_VALUES_BYTES", "SERIES_BELOW"}
"""Module-level numbers that judge no evidence: a contract parameter (the temperature
coefficient is referred to 25 °C, cli-contract.md), a memory budget (the moving library's kept
monomial values, which changes no result) and a numerical switch (where the slow-noise cap's
g(h, T_c) is summed as its series, the two forms agreeing to about 1e-7 there)."""


def _numeric(node: ast.expr) -> bool:
    """Whether an expression is one number built from literals (1e-3, 0.05 / 1e-4, math.log(2));
    tuples of indices (channel pairs) are structure, not a knob."""
    if isinstance(node, ast.Tuple | ast.List | ast.Set | ast.Dict):
        return False
    consts = [n for n in ast.walk(node) if isinstance(n, ast.Constant)]
    names = [n for n in ast.walk(node) if isinstance(n, ast.Name) and n.id != "math"]
    return bool(consts) and all(isinstance(c.value, (int, float)) for c in consts) and not names


def _module_numbers(path: Path) -> list[str]:
    out = []
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Assign | ast.AnnAssign) and node.value is not None and _numeric(node.value):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            out += [t.id for t in targets if isinstance(t, ast.Name) and t.id not in DEFINITIONS]
    return out


def test_the_checker_sees_a_module_threshold(tmp_path: Path) -> None:
    src = tmp_path / "m.py"
    src.write_text(
        'X = 1e-3\nY: float = 0.05 / 1e-4\nZ = math.log(2.0)\nN = ("ax", "ay")\nW = f(3)\nP = ((0, 1),)\n'
    )
    assert _module_numbers(src) == ["X", "Y", "Z"]


def test_no_module_level_threshold_in_the_diagnosis() -> None:
    found = {
        str(p.relative_to(PACKAGE)): names
        for p in sorted(PACKAGE.rglob("*.py"))
        if p.name != "thresholds.py" and (names := _module_numbers(p))
    }
    assert found == {}


def test_every_knob_has_a_default_and_a_reason() -> None:
    rows = table()
    assert [r[0] for r in rows] == [f.name for f in fields(Thresholds)]
    assert len(rows) >= 28
    assert all(len(reason.split()) >= 6 for _, _, reason in rows)
    assert Thresholds() == THRESHOLDS


def _quadratic_z(k2: float, seed: int = 3) -> StaticEvidence:
    """Window means of an ideal triad at 18 directions, white noise 1e-5 V, a z nonlinearity."""
    rng = np.random.default_rng(seed)
    g = 9.81
    u = np.array(
        [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1],
         [1, 1, 0], [1, 0, 1], [0, 1, 1], [-1, 1, 0], [-1, 0, -1], [0, -1, 1],
         [1, 1, 1], [-1, -1, 1], [1, -1, -1], [-1, 1, -1], [1, 0, -1], [0, 1, -1]],
        dtype=float,
    )  # fmt: skip
    f = g * u / np.linalg.norm(u, axis=1, keepdims=True)
    K = np.diag([0.0177, 0.0175, 0.0178])
    y = np.array([1.5, 1.49, 1.51]) + f @ K.T
    y[:, 2] += K[2, 2] * k2 * f[:, 2] ** 2 / 9.80665
    y += rng.normal(0, 1e-5, y.shape)
    m = f.shape[0]
    V = np.broadcast_to(np.eye(3) * 1e-10, (m, 3, 3)).copy()
    return StaticEvidence(
        y=y, V=V, f_m_s2=f, mid_s=np.arange(m) * 40.0, labels=tuple(f"w{i}" for i in range(m)), g_local_m_s2=g
    )


def test_the_knobs_reach_the_selection() -> None:
    """A z-channel mismatch with a likelihood ratio of ~36 (6 sigma) passes the default gate
    (chi2_1 at 0.01 / 21 candidates: 12) and not the gate at 1e-30 per step (chi2_1 at
    ~1e-31: 135): the knob given is the knob used."""
    ev = _quadratic_z(3e-4)
    found = [f.effect for f in diagnose(ev, use_library=False).findings]
    strict = [
        f.effect
        for f in diagnose(ev, use_library=False, thresholds=replace(THRESHOLDS, false_alarm=1e-30)).findings
    ]
    assert len(found) == 1 and strict == []


def test_docs_table_lists_every_knob_with_its_default() -> None:
    """docs/diagnose.md's Thresholds table: one row per field, the default as the code has it
    (printed to 6 significant digits)."""
    doc = (PACKAGE.parents[1] / "docs" / "diagnose.md").read_text(encoding="utf-8")
    rows = dict(re.findall(r"^\| `(\w+)` \| ([^|]+) \|", doc, flags=re.M))
    for name, value, _ in table():
        assert name in rows, name
        assert float(rows[name]) == pytest.approx(float(value), rel=1e-5), name  # type: ignore[arg-type]
