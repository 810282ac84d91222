"""The data sets in tests/data: every file the README's folder holds is what its SHA256SUMS
says (the originals, byte for byte), nothing is unlisted, each real data set carries its
licence, and nothing in the repository reads the team's reference folder beside it."""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

import pytest

from tests.conftest import INDEPENDENT, REAL_DATA, REPO_ROOT

DATA_SETS = [*sorted(p for p in REAL_DATA.iterdir() if p.is_dir()), INDEPENDENT]
NOT_LISTED = {"README.md", "SHA256SUMS"}


def _sums(folder: Path) -> dict[str, str]:
    """``SHA256SUMS`` of ``folder`` (``sha256sum`` output: hex digest, two spaces, relative path)."""
    out = {}
    for n, line in enumerate((folder / "SHA256SUMS").read_text().splitlines(), 1):
        m = re.fullmatch(r"([0-9a-f]{64})  (\S+)", line)
        assert m, f"{folder}/SHA256SUMS line {n}: not '<sha256>  <path>': {line!r}"
        out[m.group(2)] = m.group(1)
    return out


def test_the_real_data_sets_are_the_three_the_docs_describe() -> None:
    assert sorted(p.name for p in REAL_DATA.iterdir()) == [
        "imu_tk-xsens",
        "imu_utils-allan",
        "imucal-ferraris",
    ]


@pytest.mark.parametrize("folder", DATA_SETS, ids=lambda p: p.name)
def test_every_file_is_listed_and_matches_its_checksum(folder: Path) -> None:
    sums = _sums(folder)
    present = {p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file()}
    assert present - NOT_LISTED == set(sums), f"{folder}: files and SHA256SUMS differ"
    assert (folder / "README.md").is_file()
    for name, digest in sums.items():
        assert hashlib.sha256((folder / name).read_bytes()).hexdigest() == digest, f"{folder / name} changed"


@pytest.mark.parametrize("folder", DATA_SETS[:-1], ids=lambda p: p.name)
def test_each_real_data_set_carries_its_licence(folder: Path) -> None:
    licences = [name for name in _sums(folder) if name.startswith("LICENSE")]
    assert len(licences) == 1, folder
    text = (folder / licences[0]).read_text()
    assert "Permission is hereby granted" in text or "Redistribution and use" in text  # MIT / BSD
    assert f"`{licences[0]}`" in (folder / "README.md").read_text()  # the README names it


def test_nothing_reads_the_reference_folder_beside_the_repository() -> None:
    """Tests, benchmarks, product code and docs name no reference folder beside the repository
    (the team's references are not there in a clean clone; the data sets they need are in
    tests/data): the pattern below is the only place that spells its path."""
    beside = re.compile(r"\.\./shared\b|parents?(\[\d\])?\s*/\s*[\"']shared[\"']")
    here = Path(__file__).resolve()
    hits = []
    for top in ("api", "bench", "station", "drivers", "db", "tests", "benchmarks", "docs", "examples"):
        for path in (REPO_ROOT / top).rglob("*"):
            if path.suffix in {".py", ".md", ".toml", ".cfg", ".ini", ".yml", ".yaml"} and path != here:
                text = path.read_text(errors="replace")
                hits += [f"{path.relative_to(REPO_ROOT)}: {m.group(0)}" for m in beside.finditer(text)]
    assert not hits, hits
