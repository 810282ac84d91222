"""A full static-12 run on the simulated bench over the real drivers and protocols, stored in SQLite.

The simulated unit is ``SensorTruth.typical("V", seed)`` (what ``sim://?seed=`` builds),
so the fit can be compared with the truth within its own stated uncertainty.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import sqlalchemy as sa

from bench.estimation.static_design import PARAMETER_NAMES as STATIC_NAMES
from bench.recording.reader import read_recording
from bench.records import Progress, RunRecord, WindowKind
from bench.run_observer import NullObserver
from bench.run_state import Outcome
from db.engine import make_session_factory
from db.models import Run
from db.repo.results import list_fits
from drivers.sim.physics import SensorTruth
from station.execution.session import start_run
from tests.e2e.helpers import SIM_SPEED, settings_for, z_scores

pytestmark = pytest.mark.slow


class Collect(NullObserver):
    def __init__(self) -> None:
        self.progress: list[Progress] = []
        self.finished: list[RunRecord] = []

    def on_progress(self, run_id: str, progress: Progress) -> None:
        self.progress.append(progress)

    def on_finish(self, record: RunRecord) -> None:
        self.finished.append(record)


def test_static12_on_the_simulated_bench_recovers_the_unit(tmp_path: Path) -> None:
    settings = settings_for(tmp_path)
    seen = Collect()
    record = start_run(
        settings,
        "static-12",
        "SN-E2E-1",
        sim=True,
        sim_speed=SIM_SPEED,
        seed=3,
        dwell_s=8.0,
        observers=[seen],
    )
    assert record.outcome is Outcome.PASS, record.error
    assert len(record.windows) == 12 and all(w.kind is WindowKind.STATIC for w in record.windows)
    assert seen.finished == [record]
    fractions = [p.fraction for p in seen.progress]
    assert fractions == sorted(fractions) or max(fractions) <= 1.0
    assert record.calibration is not None
    z = z_scores(record.calibration.fitted_model(), SensorTruth.typical("V", 3))
    assert np.max(np.abs(z)) < 4.5, z
    assert float(np.mean(z**2)) < 4.0, z  # honest sigmas: z² averages about 1
    rec = read_recording(record.start.recording_path)
    assert rec.n_samples == record.n_samples and len(rec.sidecar.segments or ()) == 12
    assert rec.sidecar.extra["calbench_run"]["dwell"]["source"] == "fixed"  # type: ignore[index]
    engine = sa.create_engine(settings.effective_database_url)
    with engine.connect() as conn:
        state, outcome, last, n_rows = conn.execute(
            sa.text("SELECT state, outcome, last_complete_window, n_samples FROM run WHERE id = :i"),
            {"i": record.run_id},
        ).one()
        n_windows = conn.execute(
            sa.text("SELECT count(*) FROM run_window WHERE run_id = :i"), {"i": record.run_id}
        ).scalar()
        samples = conn.execute(
            sa.text("SELECT sum(n_samples) FROM sample_chunk WHERE run_id = :i"), {"i": record.run_id}
        ).scalar()
    with make_session_factory(engine).begin() as s:
        fits = [
            (f.kind.value, np.asarray(f.covariance), list(f.param_names), f.contract)
            for f in list_fits(s, record.run_id)
        ]
        checks = s.get(Run, record.run_id).limit_checks  # type: ignore[union-attr]
    engine.dispose()
    assert (state, outcome, last, n_windows) == ("completed", "PASS", 11, 12)
    assert samples == rec.n_samples == n_rows
    assert len(fits) == 1  # stored once, with its covariance in parameter order
    kind, cov, names, contract = fits[0]
    assert kind == "static" and names == list(STATIC_NAMES) and cov.shape == (12, 12)
    sigma = np.sqrt(np.diag(cov))
    np.testing.assert_allclose(sigma[:3], contract["bias_sigma"], rtol=1e-12)
    np.testing.assert_allclose(sigma[3:], np.ravel(contract["scale_matrix_sigma"]), rtol=1e-12)
    assert [c["name"] for c in checks][:3] == ["bias_x", "bias_y", "bias_z"]
    assert all(c["passed"] for c in checks)
