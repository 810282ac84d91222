"""POST /api/recordings: an independent simulator's recording calibrated through the API,
against its truth file; a broken file answered with 422 naming the row."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient

from api.main import create_app
from tests.support.service_helpers import OP, VIEW, service_settings

# calibration and diagnosis of uploaded recordings in a worker process
pytestmark = [pytest.mark.slow, pytest.mark.timeout(300)]


def test_upload_calibrates_and_diagnoses(tmp_path: Path, shared_dir: Path) -> None:
    ex = shared_dir / "data" / "examples"
    csv, sidecar = (ex / "example_static12.csv").read_bytes(), (ex / "example_static12.json").read_bytes()
    truth = json.loads((ex / "example_static12.truth.json").read_text())
    settings = service_settings(tmp_path, upload_workers=1)  # the service's default: a worker process
    with TestClient(create_app(settings, start_scheduler=False)) as client:
        files = {"recording": ("example_static12.csv", csv), "sidecar": ("example_static12.json", sidecar)}
        assert client.post("/api/recordings", files=files, headers=VIEW).status_code == 403
        r = client.post("/api/recordings", files=files, headers=OP)
        assert r.status_code == 200, r.text
        cal = r.json()["calibration"]
        k_truth = np.asarray(truth["K_v_per_m_s2"], dtype=float)
        z = (np.asarray(cal["scale_matrix"]) - k_truth) / np.asarray(cal["scale_matrix_sigma"])
        assert np.all(np.abs(z) < 5), z
        assert r.json()["diagnosis"] is not None or r.json()["diagnosis_error"]

        broken = csv.replace(b"\n", b"\nnot,a,number,row\n", 1)
        files = {"recording": ("broken.csv", broken), "sidecar": ("broken.json", sidecar)}
        r = client.post("/api/recordings", files=files, headers=OP)
        assert r.status_code == 422 and "broken.csv" in r.json()["detail"], r.text
