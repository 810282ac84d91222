"""Shared fixtures: paths to the team's shared data."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED = REPO_ROOT.parent / "shared"


@pytest.fixture(scope="session")
def shared_dir() -> Path:
    """``../shared`` beside the project root (the team's data and specs)."""
    if not SHARED.is_dir():
        pytest.skip(f"shared data directory not found at {SHARED}")
    return SHARED
