"""PASS and FAIL end to end: a simulated unit with an out-of-spec bias fails its model's limits."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from bench.limits import load_limits
from bench.run_state import Outcome
from db.engine import make_session_factory
from db.migrate import open_database
from db.models import Run
from db.repo.results import list_fits
from drivers.sim.physics import SensorTruth
from station.certificates.issue import issue_for_run
from station.execution.session import start_run
from tests.e2e.helpers import SIM_SPEED, settings_for

pytestmark = pytest.mark.slow


def test_a_unit_with_its_x_bias_outside_the_limits_fails(tmp_path: Path) -> None:
    limits = load_limits()["ADXL325"]
    bias_x = next(lim for lim in limits.limits if lim.name == "bias_x")
    assert bias_x.high is not None
    truth = SensorTruth.typical("V", 5)
    bad = dataclasses.replace(truth, bias=truth.bias + np.array([bias_x.high - truth.bias[0] + 0.03, 0, 0]))
    settings = settings_for(tmp_path)
    record = start_run(
        settings, "static-12", "SN-OUT", sim=True, sim_speed=SIM_SPEED, seed=5, dwell_s=6.0, truth=bad
    )
    assert record.outcome is Outcome.FAIL, record.error
    assert record.error is not None and record.error.startswith("outside limits: bias_x = ")
    failed = [c.name for c in record.limit_checks if not c.passed]
    assert failed == ["bias_x"]  # the fit finds the shifted bias, and nothing else is out
    check = record.limit_checks[0]
    assert record.calibration is not None
    sigma = record.calibration.bias_sigma[0]
    assert abs(check.value - bad.bias[0]) < 5 * sigma
    engine = open_database(settings.effective_database_url)
    with make_session_factory(engine).begin() as s:
        run = s.get(Run, record.run_id)
        assert run is not None
        assert (run.state.value, run.outcome, run.n_samples) == ("failed", "FAIL", record.n_samples)
        assert [c["name"] for c in run.limit_checks if not c["passed"]] == ["bias_x"]
        assert len(list_fits(s, record.run_id)) == 1  # a failed unit's fit is kept
    engine.dispose()


def test_the_typical_unit_passes_its_limits_and_the_same_unit_without_limits_has_no_verdict(
    tmp_path: Path,
) -> None:
    settings = settings_for(tmp_path)
    record = start_run(settings, "static-12", "SN-IN", sim=True, sim_speed=SIM_SPEED, seed=5, dwell_s=6.0)
    assert record.outcome is Outcome.PASS, record.error
    assert len(record.limit_checks) == 13 and all(c.passed for c in record.limit_checks)
    # the certificate states the run's verdict, each check with the U of its own results table
    engine = open_database(settings.effective_database_url)
    with make_session_factory(engine).begin() as s:
        cert = issue_for_run(s, settings, record.run_id)
        conf, res = cert.content["conformity"], cert.content["results"]
    engine.dispose()
    assert conf["outcome"] == "PASS" and len(conf["checks"]) == 13
    assert "simple acceptance" in conf["decision_rule"]
    by_name = {r["quantity"]: r for r in conf["checks"]}
    assert by_name["bias_x"]["expanded_uncertainty"] == res["bias"]["expanded_uncertainty"][0]
    assert by_name["scale_z"]["expanded_uncertainty"] == res["scale_matrix"]["expanded_uncertainty"][2][2]
    assert by_name["g_error_after"]["expanded_uncertainty"] > 0
    unlimited = settings.model_copy(update={"limits_model": ""})
    truth = SensorTruth.typical("V", 5)
    bad = dataclasses.replace(truth, bias=truth.bias + np.array([0.2, 0.0, 0.0]))
    free = start_run(
        unlimited, "static-12", "SN-FREE", sim=True, sim_speed=SIM_SPEED, seed=5, dwell_s=3.0, truth=bad
    )
    # 0.2 V off in bias would fail; without limits nothing is judged and the record says why
    assert free.outcome is None and free.limit_checks == (), free.error
    assert free.conformity_note.startswith("no conformity statement"), free.conformity_note
