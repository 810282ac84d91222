"""Two benches at once writing to one PostgreSQL database (the lab set-up of docs/service.md)."""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest
import sqlalchemy as sa

from bench.records import RunRecord
from bench.run_state import Outcome
from drivers.sim.physics import SensorTruth
from station.execution.session import start_run
from tests.e2e.helpers import SIM_SPEED, settings_for, z_scores
from tests.pg import pg_database, pg_unreachable_reason

pytestmark = [pytest.mark.slow, pytest.mark.postgres]


def test_two_simulated_benches_share_one_postgresql_database(tmp_path: Path) -> None:
    reason = pg_unreachable_reason()
    if reason:
        pytest.skip(reason)
    with pg_database() as url:
        results: dict[str, RunRecord] = {}
        errors: list[BaseException] = []

        def bench(name: str, seed: int) -> None:
            try:
                settings = settings_for(tmp_path / name, database_url=url, bench_name=name)
                results[name] = start_run(
                    settings, "static-12", f"SN-{name}", sim=True, sim_speed=SIM_SPEED, seed=seed, dwell_s=5.0
                )
            except BaseException as exc:
                errors.append(exc)

        threads = [threading.Thread(target=bench, args=(n, s)) for n, s in (("bench-a", 21), ("bench-b", 22))]
        for t in threads:
            t.start()
        for t in threads:
            t.join(600)
        assert not errors, errors
        for name, seed in (("bench-a", 21), ("bench-b", 22)):
            rec = results[name]
            assert rec.outcome is Outcome.PASS, rec.error
            assert rec.calibration is not None
            assert (
                np.max(np.abs(z_scores(rec.calibration.fitted_model(), SensorTruth.typical("V", seed)))) < 4.5
            )
        engine = sa.create_engine(url)
        try:
            with engine.connect() as conn:
                rows = conn.execute(
                    sa.text(
                        "SELECT b.name, r.state, r.last_complete_window, "
                        "(SELECT count(*) FROM run_window w WHERE w.run_id = r.id) "
                        "FROM run r JOIN bench b ON b.id = r.bench_id ORDER BY b.name"
                    )
                ).all()
        finally:
            engine.dispose()
        expected = [("bench-a", "completed", 11, 12), ("bench-b", "completed", 11, 12)]
        assert [tuple(r) for r in rows] == expected
