"""Nightly drift check: a unit calibrated, aged 30 simulated days, flagged by the scheduler.

The simulated unit's ageing is known (``SensorTruth.aged``), so the check must also see the
bias move by the injected amount, within the combined uncertainty.
"""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient

from api.main import create_app
from drivers.factory import simulated_unit
from station.drift import DriftScheduler, compare, parse_time_of_day
from tests.support.fits import stored_fit
from tests.support.service_helpers import OP, VIEW, MovableClock, service_settings, wait_final

pytestmark = [pytest.mark.slow, pytest.mark.timeout(600)]  # whole simulated drift-check runs

SERIAL = "SN-AGE-195"
"""A simulated unit whose bias walks far in 30 days: truth shift of the z bias ≈ -1.0e-4 V."""


def test_unit_aged_30_days_is_flagged(tmp_path: Path) -> None:
    clock = MovableClock()
    settings = service_settings(tmp_path, drift_time="02:00", run_dwell_s=4.0, drift_dwell_s=4.0)
    with TestClient(create_app(settings, clock=clock, start_scheduler=False)) as client:
        services = client.app.state.services  # type: ignore[attr-defined]
        r = client.post("/api/runs", json={"unit_serial": SERIAL, "procedure": "static-12"}, headers=OP)
        cal = wait_final(client, r.json()["id"])
        assert cal["state"] == "completed", cal["error"]

        scheduler: DriftScheduler = services.drift
        assert scheduler.tick() is None  # not yet night: nothing queued
        clock.advance(30)
        check_id = scheduler.tick()  # the night has come (30 days of them): the unit is checked
        assert check_id is not None
        check = wait_final(client, check_id)
        assert check["state"] == "completed" and check["kind"] == "drift_check"

        flagged = client.get("/api/drift/checks?flagged=true", headers=VIEW).json()
        assert [c["unit_serial"] for c in flagged] == [SERIAL]
        result = flagged[0]["result"]
        assert result["reference_number"] == cal["certificate_number"]
        rows = {row["name"]: row for row in result["coefficients"]}

        age_days = services.runner.age_days(SERIAL)
        truth_shift = simulated_unit(SERIAL, age_days).bias - simulated_unit(SERIAL, 0).bias
        for i in range(3):
            row = rows[f"bias[{i}]"]
            u = np.hypot(row["u_reference"], row["u_check"])
            assert abs(row["delta"] - truth_shift[i]) < 4 * u + 1e-6, (i, row, truth_shift)
        assert rows["bias[2]"]["exceeded"]
        units = {u["serial"]: u for u in client.get("/api/units", headers=VIEW).json()}
        assert units[SERIAL]["last_drift_flagged"] is True


def _cert(value: list[float], u_expanded: list[float]) -> dict[str, object]:
    q = {"value": value, "expanded_uncertainty": u_expanded, "unit": "V", "k": 2.0}
    u_m = np.full((3, 3), 2e-6).tolist()
    m = {"value": np.eye(3).tolist(), "expanded_uncertainty": u_m, "unit": "V", "k": 2.0}
    return {"results": {"bias": q, "scale_matrix": m}}


def test_compare_uses_both_uncertainties() -> None:
    cert = _cert([1.0, 1.0, 1.0], [2e-5, 2e-5, 2e-5])  # u_cert = 1e-5
    check = {
        "bias": [1.0 + 4.9e-5, 1.0 - 5.1e-5, 1.0],
        "bias_sigma": [1e-5] * 3,
        "scale_matrix": np.eye(3).tolist(),
        "scale_matrix_sigma": np.full((3, 3), 1e-6).tolist(),
    }
    out = compare(cert, stored_fit(**check), k=3.0)  # limit = 3·sqrt(2)·1e-5 = 4.243e-5
    rows = {r["name"]: r for r in out["coefficients"]}
    assert rows["bias[0]"]["limit"] == pytest.approx(3 * np.sqrt(2) * 1e-5)
    assert rows["bias[0]"]["exceeded"] and rows["bias[1]"]["exceeded"] and not rows["bias[2]"]["exceeded"]
    assert out["flagged"] and len(rows) == 12
    assert out["false_alarm_probability"] == pytest.approx(1 - (1 - 0.0026998) ** 12, rel=1e-3)
    quiet = compare(cert, stored_fit(**{**check, "bias": [1.0, 1.0, 1.0]}), k=3.0)
    assert not quiet["flagged"]


def test_time_of_day_setting() -> None:
    assert parse_time_of_day("02:30") == dt.time(2, 30)
    assert parse_time_of_day("") is None
    for bad in ("25:00", "2", "ab:cd"):
        with pytest.raises(ValueError, match="CALBENCH_DRIFT_TIME"):
            parse_time_of_day(bad)
