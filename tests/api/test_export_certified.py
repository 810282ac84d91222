"""A certified run's exports state its certificate: number, date of issue and the expanded
uncertainties of b and K exactly as the certificate gives them."""

from __future__ import annotations

import json
from pathlib import Path

from fastapi.testclient import TestClient

from api.main import create_app
from db.models import RunState
from db.repo.results import add_fit
from db.repo.runs import merge_params
from station.certificates.issue import issue_for_run
from tests.db._factories import make_run
from tests.station.certificates.test_certificate_conformity import CAL
from tests.support.service_helpers import VIEW, service_settings


def test_the_export_of_a_certified_run_carries_the_certificates_number_date_and_u(tmp_path: Path) -> None:
    settings = service_settings(tmp_path)
    with TestClient(create_app(settings, start_scheduler=False)) as client:
        sessions = client.app.state.services.sessions  # type: ignore[attr-defined]
        with sessions.begin() as s:
            for run_id in ("r-cert", "r-plain"):
                run = make_run(s, run_id, state=RunState.COMPLETED)
                run.outcome = "PASS"
                merge_params(s, run_id, {"sim": {"seed": 1}})
                add_fit(s, run_id, "static", CAL)
            s.flush()
            cert = issue_for_run(s, settings, "r-cert")
            number, issued, results = cert.number, cert.issued_at.date().isoformat(), cert.content["results"]
        doc = json.loads(client.get("/api/runs/r-cert/export/json", headers=VIEW).text)["uncertainty"]
        assert doc["certificate"] == {"number": number, "issued_on": issued}
        assert doc["bias"]["uncertainty"] == results["bias"]["expanded_uncertainty"]
        assert doc["bias"]["k"] == results["bias"]["k"]
        assert doc["scale_matrix"]["uncertainty"] == results["scale_matrix"]["expanded_uncertainty"]
        header = client.get("/api/runs/r-cert/export/c-header", headers=VIEW).text
        assert f'#define CALBENCH_CERTIFICATE "{number}"' in header and issued in header
        plain = json.loads(client.get("/api/runs/r-plain/export/json", headers=VIEW).text)["uncertainty"]
        assert plain["certificate"] is None and plain["bias"]["uncertainty"] == CAL["bias_sigma"]
