"""rate-1axis and oscillation-2axis end to end on the simulated bench over the real drivers,
calibrated by the dynamic (moving-table) model; the fit recovers the simulated unit."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bench.recording.reader import read_recording
from bench.records import WindowKind
from bench.run_state import Outcome
from drivers.sim.physics import SensorTruth
from station.execution.session import start_run
from tests.e2e.helpers import SIM_SPEED, settings_for, z_scores

pytestmark = pytest.mark.slow


@pytest.mark.parametrize(
    ("procedure", "kw", "moving", "n_windows"),
    [
        ("rate-1axis", {"rates_deg_s": (100.0, -100.0, 200.0, -200.0), "window_s": 5.0}, WindowKind.RATE, 30),
        ("oscillation-2axis", {"duration_s": 60.0}, WindowKind.OSCILLATION, 3),
    ],
)
def test_moving_table_procedure_is_calibrated_by_the_dynamic_model(
    tmp_path: Path, procedure: str, kw: dict[str, Any], moving: WindowKind, n_windows: int
) -> None:
    seed = 4
    record = start_run(
        settings_for(tmp_path),
        procedure,
        "SN-DYN",
        sim=True,
        sim_speed=SIM_SPEED,
        seed=seed,
        dwell_s=5.0,
        procedure_kw=kw,
    )
    assert record.outcome is Outcome.PASS, record.error
    assert len(record.windows) == n_windows
    assert sum(w.kind is moving for w in record.windows) == n_windows - (
        6 if moving is WindowKind.RATE else 2
    )
    assert record.calibration is not None
    cal = record.calibration.to_contract()
    assert cal["method"] == "dynamic-batch"
    # The terms are the ones the recording's evidence supports, and the result says so.
    assert cal["model_selection"]["rule"] == "evidence", cal["model_selection"]
    z = z_scores(record.calibration.fitted_model(), SensorTruth.typical("V", seed))
    assert np.max(np.abs(z)) < 4.5, z
    # The simulated unit has its sensor on the axes (no lever arm): either the evidence leaves
    # the lever arm out (with its reason), or the fitted one is zero within its uncertainty.
    if "lever_arm" in cal["terms"]:
        r = np.asarray(cal["extra"]["lever_arm"]["r_m"])  # type: ignore[index]
        r_sigma = np.asarray(cal["extra_sigma"]["lever_arm"]["r_m"])  # type: ignore[index]
        assert np.max(np.abs(r / r_sigma)) < 4.5, (r, r_sigma)
    else:
        assert "lever_arm" in cal["not_fitted"], cal["not_fitted"]
    rec = read_recording(record.start.recording_path)
    assert rec.n_samples == record.n_samples and rec.sidecar.procedure == procedure
    assert record.fit_param_names and len(record.fit_covariance or ()) == len(record.fit_param_names)
