"""The plausibility findings of a recording reach every door: ``calibrate --json`` (``warnings``),
stderr, and the upload endpoint's answer (issue 24, item 5)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from api.cli import main
from api.main import create_app
from tests.support.service_helpers import OP, service_settings

pytestmark = pytest.mark.timeout(300)


@pytest.fixture(scope="module")
def mirrored(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A static-12 recording whose az channel has the wrong sign (a mirror image) and one spike on ay."""
    d = tmp_path_factory.mktemp("mirror")
    path = d / "mirror.csv"
    assert main(["simulate", "-o", str(path), "--dwell-s", "3", "--sample-rate-hz", "50", "--seed", "2"]) == 0
    lines = path.read_text().splitlines()
    head = lines[0].split(",")
    ay, az = head.index("ay"), head.index("az")
    rows = []
    for k, line in enumerate(lines[1:]):
        cells = line.split(",")
        cells[az] = repr(-float(cells[az]))
        if k == 400:
            cells[ay] = repr(float(cells[ay]) + 0.5)
        rows.append(",".join(cells))
    path.write_text("\n".join([lines[0], *rows]) + "\n")
    return path


def test_calibrate_json_and_stderr_carry_the_frame_and_spike_warnings(
    mirrored: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["calibrate", "--json", str(mirrored)]) == 0
    cap = capsys.readouterr()
    warnings = json.loads(cap.out)["warnings"]
    assert any("mirror image" in w for w in warnings), warnings
    assert any(w.startswith("channel ay: 1 spike(s)") for w in warnings), warnings
    for w in warnings:
        assert w in cap.err


def test_the_upload_answer_carries_them(mirrored: Path, tmp_path: Path) -> None:
    with TestClient(create_app(service_settings(tmp_path), start_scheduler=False)) as client:
        files = {
            "recording": ("mirror.csv", mirrored.read_bytes(), "text/csv"),
            "sidecar": ("mirror.json", mirrored.with_suffix(".json").read_bytes(), "application/json"),
        }
        r = client.post("/api/recordings", files=files, headers=OP)
    assert r.status_code == 200, r.text
    warnings = r.json()["calibration"]["warnings"]
    assert any("mirror image" in w for w in warnings) and any("spike" in w for w in warnings)
