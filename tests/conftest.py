"""Shared fixtures: the example recordings shipped in ``examples/``, the independent simulator's
recordings in ``tests/data/independent/`` and the real data sets in ``tests/data/real/`` (each
folder's README says where its files come from, SHA256SUMS what they are)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = REPO_ROOT / "examples"
REAL_DATA = REPO_ROOT / "tests" / "data" / "real"
"""Real recordings of other people's tools, one folder per data set with its licence."""
INDEPENDENT = REPO_ROOT / "tests" / "data" / "independent"
"""Recordings of a simulator written separately from calbench, with their truth."""
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
def real_dir() -> Path:
    """``tests/data/real/``: the real data sets (imu_tk-xsens, imucal-ferraris, imu_utils-allan)."""
    return REAL_DATA


@pytest.fixture(scope="session")
def independent_dir() -> Path:
    """``tests/data/independent/``: the independent simulator's recordings and their truth."""
    return INDEPENDENT
