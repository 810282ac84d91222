"""POST /api/recordings: the shipped static-12 example calibrated and diagnosed through the API,
against its truth file; a broken file answered with 422 naming the row."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient

from api.main import create_app
from tests.conftest import EXAMPLES, STATIC_EXAMPLE
from tests.support.service_helpers import OP, VIEW, service_settings

# calibration and diagnosis of uploaded recordings in a worker process
pytestmark = [pytest.mark.slow, pytest.mark.timeout(300)]


def test_upload_calibrates_and_diagnoses(tmp_path: Path) -> None:
    ex = EXAMPLES / STATIC_EXAMPLE
    csv, sidecar = ex.with_suffix(".csv").read_bytes(), ex.with_suffix(".json").read_bytes()
    truth = json.loads(ex.with_suffix(".truth.json").read_text())
    settings = service_settings(tmp_path, upload_workers=1)  # the service's default: a worker process
    with TestClient(create_app(settings, start_scheduler=False)) as client:
        files = {"recording": ("rec.csv", csv), "sidecar": ("rec.json", sidecar)}
        assert client.post("/api/recordings", files=files, headers=VIEW).status_code == 403
        r = client.post("/api/recordings", files=files, headers=OP)
        assert r.status_code == 200, r.text
        cal = r.json()["calibration"]
        k_truth = np.asarray(truth["scale_matrix"], dtype=float)
        z = (np.asarray(cal["scale_matrix"]) - k_truth) / np.asarray(cal["scale_matrix_sigma"])
        assert np.all(np.abs(z) < 5), z
        # the concealed z nonlinearity is found, and its size agrees with the truth
        found = {f["effect"]: f for f in r.json()["diagnosis"]["findings"]}
        k2 = found["nonlinearity_quadratic"]
        k2_truth = truth["effects"]["nonlinearity_quadratic"]["k2_per_g"][2]
        assert abs(k2["parameters"]["k2_per_g"][2] - k2_truth) < 3 * k2["sigma"]["k2_per_g"][2], k2

        broken = csv.replace(b"\n", b"\nnot,a,number,row\n", 1)
        files = {"recording": ("broken.csv", broken), "sidecar": ("broken.json", sidecar)}
        r = client.post("/api/recordings", files=files, headers=OP)
        assert r.status_code == 422 and "broken.csv" in r.json()["detail"], r.text
