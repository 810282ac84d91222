"""The start form's preview: every pose the procedure commands, and which model terms its
motion determines (the rest named with the reason)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient

from api.main import create_app
from bench.estimation.dynamic_model import TERM_ORDER
from bench.procedures import build_procedure
from bench.procedures.planned import planned_poses_deg
from bench.procedures.steps import MoveTo
from station.execution.devices import table_limits
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


def test_a_planned_procedure_is_previewed_with_its_parameters(tmp_path: Path) -> None:
    """A plan's design (GET /api/plan's ``start``) previews every pass it will run, not one."""
    settings = service_settings(tmp_path, agent="external")
    app = create_app(settings, start_scheduler=False)
    with TestClient(app) as client:
        one = client.get("/api/procedures/planned-tumble/preview", params={"dwell_s": 4}, headers=VIEW).json()
        params = {"repeats": 3, "settle_s": 1.5}
        r = client.get(
            "/api/procedures/planned-tumble/preview",
            params={"dwell_s": 4, "parameters": json.dumps(params)},
            headers=VIEW,
        )
        assert r.status_code == 200, r.text
        body = r.json()
        # three passes of the twelve directions, forwards, backwards, forwards
        assert body["poses_deg"] == [list(p) for p in planned_poses_deg(3)]
        assert body["n_poses"] == 36 and body["n_windows"] == 36 and one["n_windows"] == 12
        # each visit: the slowest axis's move from the pose before (the shorter way round on a
        # continuous axis; trapezoidal, t = d/v + v/a, or triangular, t = 2·sqrt(d/a)), the
        # settling and the dwell
        limits = table_limits(settings)  # the service's table (its bench file's, else the default)

        def move_s(d: float, v: float, a: float) -> float:
            return 2.0 * math.sqrt(d / a) if d < v * v / a else d / v + v / a

        pos, expected_s = np.zeros(3), 0.0
        for pose in planned_poses_deg(3):
            d = np.array(pose) - pos
            d = np.where(limits.continuous, (d + 180.0) % 360.0 - 180.0, d)
            rate, acc = limits.max_rate_deg_s, limits.max_acc_deg_s2
            expected_s += max(move_s(abs(d[a]), rate[a], acc[a]) for a in range(3)) + 1.5 + 4.0
            pos = pos + d
        assert body["duration_s"] == pytest.approx(expected_s, rel=1e-9)
        for bad in (
            '{"repeats": 2.5}',
            '{"laps": 2}',
            "[3]",
            '{"repeats": "3"}',
            "{",
            '{"repeats": 1%s}' % ("0" * 400),
        ):
            r = client.get("/api/procedures/planned-static/preview", params={"parameters": bad}, headers=VIEW)
            assert r.status_code == 422, (bad, r.text)
        r = client.get(
            "/api/procedures/static-12/preview", params={"parameters": '{"repeats": 3}'}, headers=VIEW
        )
        assert r.status_code == 422 and "repeats" in r.json()["detail"]
