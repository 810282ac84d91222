"""Shared fixtures: the example recordings shipped in ``examples/``, and ``../shared`` (the
independent simulator's example recordings and the real data sets, kept beside the repository)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = REPO_ROOT / "examples"
SHARED = REPO_ROOT.parent / "shared"
STATIC_EXAMPLE = "static12_nonlinearity"
"""The shipped static-12 example (a z nonlinearity concealed; ``examples/README.md``)."""
MOVING_EXAMPLE = "oscillation_lever_arm"
"""The shipped oscillation-2axis example (a lever arm the sidecar does not state)."""


@pytest.fixture(scope="session")
def examples_dir() -> Path:
    """``examples/`` of the repository: recordings made by ``calbench simulate`` with their truth."""
    return EXAMPLES


def copy_example(stem: str, dst: Path, name: str = "rec") -> Path:
    """Copy the shipped example ``stem`` (CSV and sidecar) to ``dst/name.*``; the CSV's path."""
    for ext in ("csv", "json"):
        shutil.copy(EXAMPLES / f"{stem}.{ext}", dst / f"{name}.{ext}")
    return dst / f"{name}.csv"


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """``../shared`` beside the project root: the independent simulator's example recordings
    (``data/examples``) and the real data sets (``data/real``), which the repository does not ship."""
    if not SHARED.is_dir():
        pytest.skip(
            f"{SHARED} not found: the independent simulator's recordings and the real data sets are "
            "not part of the repository (tests on the shipped examples/ run without them)"
        )
    return SHARED
