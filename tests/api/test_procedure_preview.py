"""The start form's preview: every pose the procedure commands, and which model terms its
motion determines (the rest named with the reason)."""

from __future__ import annotations

from pathlib import Path

from fastapi.testclient import TestClient

from api.main import create_app
from bench.estimation.dynamic_model import TERM_ORDER
from bench.procedures import build_procedure
from bench.procedures.steps import MoveTo
from tests.support.service_helpers import VIEW, service_settings


def test_the_preview_lists_the_poses_and_the_observable_terms(tmp_path: Path) -> None:
    app = create_app(service_settings(tmp_path, agent="external"), start_scheduler=False)
    with TestClient(app) as client:
        for name in ("static-12", "oscillation-2axis"):
            r = client.get(f"/api/procedures/{name}/preview", headers=VIEW)
            assert r.status_code == 200, r.text
            body = r.json()
            moves = [
                list(s.angles_deg) for s in build_procedure(name, dwell_s=3.0).steps if isinstance(s, MoveTo)
            ]
            assert body["poses_deg"] == moves and body["n_poses"] == len(moves)
            terms = {"bias", "scale_matrix", *TERM_ORDER}
            assert set(body["observable"]) | set(body["not_observable"]) == terms
            assert not set(body["observable"]) & set(body["not_observable"])
            assert {"bias", "scale_matrix"} <= set(body["observable"]), body
            assert all(why for why in body["not_observable"].values())
        # the oscillation turns the sensor fast enough to show the lever arm
        assert "lever_arm" in body["observable"]


def test_an_unknown_procedure_is_404_listing_the_known_ones(tmp_path: Path) -> None:
    app = create_app(service_settings(tmp_path, agent="external"), start_scheduler=False)
    with TestClient(app) as client:
        r = client.get("/api/procedures/static-99/preview", headers=VIEW)
    assert r.status_code == 404
    assert r.json()["detail"] == (
        "unknown procedure 'static-99'; known: "
        "oscillation-2axis, planned-static, planned-tumble, rate-1axis, static-12"
    )
