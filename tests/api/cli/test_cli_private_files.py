"""The commands that create the database, recordings and certificates create them readable by their
owner only: files 0600, directories 0700 (issue 24, item 8)."""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from pathlib import Path

import pytest

from api.cli import main


@pytest.fixture()
def restore_umask() -> Iterator[None]:
    saved = os.umask(0o022)  # what a shell usually gives: world-readable files
    yield
    os.umask(saved)


def test_db_upgrade_creates_a_private_data_directory_and_database(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, restore_umask: None
) -> None:
    data = tmp_path / "data"
    monkeypatch.setenv("CALBENCH_DATA_DIR", str(data))
    monkeypatch.delenv("CALBENCH_DATABASE_URL", raising=False)
    assert main(["db", "upgrade"]) == 0
    assert stat.S_IMODE(data.stat().st_mode) == 0o700
    created = list(data.iterdir())
    assert any(p.name == "calbench.db" for p in created)
    for p in created:
        assert stat.S_IMODE(p.stat().st_mode) & 0o077 == 0, (p, oct(p.stat().st_mode))
    # a recording written afterwards by the same process is private too
    (data / "recordings").mkdir()
    (data / "recordings" / "r.csv").write_text("t\n")
    assert stat.S_IMODE((data / "recordings").stat().st_mode) == 0o700
    assert stat.S_IMODE((data / "recordings" / "r.csv").stat().st_mode) == 0o600
