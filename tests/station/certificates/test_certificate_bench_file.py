"""A certificate made from a run on a bench file: its conditions name the file, and the
uncertainty budget takes u(g) from the file, not from the settings."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np

from api.simulated_recording import write_simulated
from bench.calibration import calibrate_recording
from bench.calibration.analysis import analyse
from bench.fitted_model import FittedModel
from bench.recording import read_recording
from db.engine import make_session_factory
from db.migrate import open_database
from db.models import RunState
from db.repo.results import add_fit
from db.repo.runs import create_run
from db.repo.units import get_or_create_unit
from drivers.sim.offline import DEFAULT_AXES, simulate_static, static12_poses_deg
from drivers.sim.physics import SensorPhysics, SensorTruth
from station.certificates.budget import TypeBSettings, certificate_budget
from station.certificates.issue import issue_for_run
from station.settings import Settings

G = 9.81535
U_G_FILE = 3e-4  # thirty times the settings' default, so it shows in K


def test_the_budget_takes_u_g_from_the_bench_file_and_the_conditions_name_it(tmp_path: Path) -> None:
    physics = SensorPhysics(SensorTruth.typical("V", seed=4), DEFAULT_AXES, None, G, seed=5)
    path = tmp_path / "run.csv"
    write_simulated(path, simulate_static(static12_poses_deg(), 5.0, physics, 100.0), serial="SN-BF", seed=5)
    rec = read_recording(path)
    cal = calibrate_recording(rec).to_contract()
    identity = {
        "name": "bench-b",
        "version": 4,
        "sha256": "ab" * 32,
        "path": "/etc/calbench/bench-b.toml",
        "g_local_m_s2": G,
        "g_local_u_m_s2": U_G_FILE,
        "g_local_source": "survey 2023",
    }
    settings = Settings(data_dir=tmp_path, database_url=f"sqlite:///{tmp_path / 'c.db'}")
    engine = open_database(settings.effective_database_url)
    with make_session_factory(engine).begin() as s:
        unit = get_or_create_unit(s, "SN-BF", channel_unit="V")
        run = create_run(
            s,
            "run-bf",
            unit.id,
            "static-12",
            state=RunState.COMPLETED,
            recording_path=str(path),
            params={"bench_config": identity, "sim": True},
        )
        add_fit(s, "run-bf", "static", cal)
        run.started_at = run.finished_at = dt.datetime(2025, 1, 1, tzinfo=dt.UTC)
        content = issue_for_run(s, settings, "run-bf").content
    engine.dispose()
    assert "'bench-b' version 4 (SHA-256 abababababab…)" in content["conditions"]["bench_configuration"]
    assert "u = 0.0003 m/s², survey 2023" in content["conditions"]["bench_configuration"]
    expected = certificate_budget(
        analyse(rec),
        FittedModel.from_contract(cal),
        TypeBSettings.of(settings.model_copy(update={"g_local_u_m_s2": U_G_FILE})),
    )
    default = certificate_budget(analyse(rec), FittedModel.from_contract(cal), TypeBSettings.of(settings))
    stated = content["results"]["uncertainty_budget"]
    assert stated == expected.to_content()
    (gravity,) = [i for i in stated["inputs"] if i["group"] == "local gravity"]
    assert gravity["u"] == U_G_FILE
    u_c, u_c_default = stated["quantities"]["K_xx"]["u_c"], default.budget.by_name("K_xx").u_c
    assert not np.isclose(u_c, u_c_default, rtol=0.01), (u_c, u_c_default)
