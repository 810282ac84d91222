"""From a run's recording to its certificate the recording is read once and fitted once: the
verdict analyses it, and the stored fit, the nominal |g| check, the diagnosis, the certificate
and its budget all read that one analysis (a whole simulated run through the bench agent's
finish, with every reader and fit entry point counted wherever it is imported)."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest
import sqlalchemy as sa

import bench.calibration.recording
import bench.calibration.static
import bench.recording.reader
from bench.fit_kind import FitKind
from bench.run_state import RunState
from bench.sequencer.control import RunControl
from db.engine import make_session_factory
from db.migrate import open_database
from db.models import Certificate, Run, Unit
from db.repo.results import list_fits
from db.repo.units import get_or_create_unit
from station.agent.bench_agent import make_finisher
from station.certificates.results import two_digits
from station.execution.session import start_run
from station.runs.live import LiveRun
from station.settings import Settings
from tests.e2e.helpers import SIM_SPEED
from tests.support.counting import count_everywhere

pytestmark = [pytest.mark.slow, pytest.mark.timeout(600)]  # a whole simulated run


def test_a_run_is_read_once_and_fitted_once_to_its_certificate(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    settings = Settings(
        data_dir=tmp_path,
        database_url=f"sqlite:///{tmp_path / 'calbench.db'}",
        sim_sample_rate_hz=100.0,
        bench_name="bench-once",
        limits_model="",
    )
    engine = open_database(settings.effective_database_url)
    sessions = make_session_factory(engine)
    with sessions.begin() as s:  # a registered nominal: the |g| check before adjustment is formed too
        unit = get_or_create_unit(s, "SN-ONCE", channel_unit="V")
        unit.nominal_scale, unit.nominal_bias = 0.0306, 1.5
    calls: Counter[str] = Counter()
    count_everywhere(monkeypatch, calls, bench.recording.reader, "read_recording")
    count_everywhere(monkeypatch, calls, bench.calibration.recording, "calibrate_recording")
    count_everywhere(monkeypatch, calls, bench.calibration.static, "calibrate_static")
    assert calls == Counter()
    record = start_run(
        settings, "static-12", "SN-ONCE", sim=True, sim_speed=SIM_SPEED, seed=3, dwell_s=3.0,
        defer_final_state=True,
    )  # fmt: skip
    # no limits judge a unit without a model when no default is set: completed, no verdict
    assert record.outcome is None and record.state is RunState.COMPLETED, record.error
    live = LiveRun(record.run_id, "SN-ONCE", "static-12", "calibration", RunControl(), 0.0)
    make_finisher(settings, sessions, make_session_factory(engine, read_only=True))(live, record)
    assert calls == Counter(read_recording=1, calibrate_recording=1, calibrate_static=1)
    with sessions.begin() as s:
        run = s.get(Run, record.run_id)
        assert run is not None and run.state.value == "completed"
        (fit,) = list_fits(s, record.run_id)
        cert = s.scalars(sa.select(Certificate).where(Certificate.run_id == record.run_id)).one()
        unit_row = s.get(Unit, run.unit_id)
        assert unit_row is not None and unit_row.serial == "SN-ONCE"
        # one fit, stored once: its row, with no copy in the run's params
        assert fit.kind is FitKind.STATIC and "calibration" not in run.params
        before = fit.contract["g_check"]["before"]
        assert before["nominal"] == {"scale": 0.0306, "bias": 1.5, "source": "unit registration"}
        assert isinstance(run.diagnosis, dict) and run.diagnosis_error is None
        content = cert.content
    assert live.extra["certificate_number"] == cert.number
    budget = content["results"]["uncertainty_budget"]
    assert budget["quantities"]["b_x"]["value"] == fit.contract["bias"][0]
    assert content["g_check"]["before"]["mean_error_m_s2"] == two_digits(before["mean_error_m_s2"])
    engine.dispose()
