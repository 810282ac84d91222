"""Run life cycle, windows and chunks through the repo functions."""

from __future__ import annotations

import pytest
import sqlalchemy as sa
from sqlalchemy.exc import IntegrityError

from db.models import Run, RunState, Unit
from db.repo import progress, runs, units
from tests.db._factories import make_run


def test_get_or_create_unit_is_idempotent_and_fills_unknown_fields(db_session_factory):
    with db_session_factory.begin() as s:
        a = units.get_or_create_unit(s, "SN-9")
        b = units.get_or_create_unit(s, "SN-9", model="QA-3000", channel_unit="V")
        c = units.get_or_create_unit(s, "SN-9", model="other")
        assert a.id == b.id == c.id
    with db_session_factory() as s:
        u = s.scalars(sa.select(Unit)).one()
        assert (u.model, u.channel_unit) == ("QA-3000", "V")


def test_empty_names_refused(db_session_factory):
    with db_session_factory.begin() as s:
        with pytest.raises(ValueError, match="serial"):
            units.get_or_create_unit(s, "  ")
        with pytest.raises(ValueError, match="bench name"):
            units.get_or_create_bench(s, "")


def test_life_cycle_transitions_are_conditional(db_session_factory):
    with db_session_factory.begin() as s:
        make_run(s, "R-1", state=RunState.QUEUED)
        assert runs.start_run(s, "R-1", owner_pid=11, owner_host="h")
        assert not runs.start_run(s, "R-1", owner_pid=12, owner_host="h")  # already running
        assert runs.heartbeat(s, "R-1", progress=0.5)
        assert runs.set_live_state(s, "R-1", RunState.PAUSED)
        assert runs.finish_run(s, "R-1", RunState.COMPLETED, outcome="PASS")
        assert not runs.finish_run(s, "R-1", RunState.ERROR, error="late")  # final is final
        assert not runs.heartbeat(s, "R-1")
    with db_session_factory() as s:
        run = s.get(Run, "R-1")
        assert run.state is RunState.COMPLETED and run.outcome == "PASS" and run.progress == 1.0
        assert run.owner_pid == 11 and run.error is None and run.finished_at is not None


def test_bad_transitions_refused(db_session_factory):
    with db_session_factory.begin() as s:
        make_run(s, "R-1")
        with pytest.raises(ValueError, match="not a final state"):
            runs.finish_run(s, "R-1", RunState.RUNNING)
        with pytest.raises(ValueError, match=r"outside 0\.\.1"):
            runs.heartbeat(s, "R-1", progress=float("nan"))
        with pytest.raises(ValueError, match="not a live state"):
            runs.set_live_state(s, "R-1", RunState.INTERRUPTED)


def test_duplicate_run_id_refused(db_session_factory):
    with db_session_factory.begin() as s:
        make_run(s, "R-1")
    with pytest.raises(IntegrityError), db_session_factory.begin() as s:
        make_run(s, "R-1")


def test_list_runs_newest_first_with_filters(db_session_factory):
    with db_session_factory.begin() as s:
        make_run(s, "R-1", "SN-1")
        make_run(s, "R-2", "SN-2", state=RunState.QUEUED)
        make_run(s, "R-3", "SN-1", state=RunState.QUEUED)
    with db_session_factory() as s:
        assert [r.id for r in runs.list_runs(s)] == ["R-3", "R-2", "R-1"]
        assert [r.id for r in runs.list_runs(s, unit_serial="SN-1")] == ["R-3", "R-1"]
        assert [r.id for r in runs.list_runs(s, states=[RunState.QUEUED], limit=1)] == ["R-3"]
        assert runs.list_runs(s)[0].unit.serial == "SN-1"  # loaded eagerly


def test_merge_params_keeps_existing_keys(db_session_factory):
    with db_session_factory.begin() as s:
        make_run(s, "R-1")
        runs.merge_params(s, "R-1", {"dwell": {"dwell_s": 55.0}, "n_windows": 12})
    with db_session_factory() as s:
        assert s.get(Run, "R-1").params == {"dwell": {"dwell_s": 55.0}, "n_windows": 12}
    with pytest.raises(LookupError), db_session_factory.begin() as s:
        runs.merge_params(s, "nope", {})


def test_last_complete_window_only_moves_forward(db_session_factory):
    with db_session_factory.begin() as s:
        make_run(s, "R-1")
        for i in (0, 2, 1):  # out of order: 1 arrives after 2
            progress.record_window(s, "R-1", i, start_s=10.0 * i, end_s=10.0 * i + 5, n_samples=500)
    with db_session_factory() as s:
        assert s.get(Run, "R-1").last_complete_window == 2
        assert [w.index for w in progress.list_windows(s, "R-1")] == [0, 1, 2]


def test_duplicate_window_or_chunk_refused(db_session_factory):
    with db_session_factory.begin() as s:
        make_run(s, "R-1")
        progress.record_window(s, "R-1", 0, start_s=0, end_s=1, n_samples=10)
        progress.record_chunk(s, "R-1", 0, first_sample=0, n_samples=10, last_t_s=1.0, end_byte=100)
    with pytest.raises(IntegrityError), db_session_factory.begin() as s:
        progress.record_window(s, "R-1", 0, start_s=0, end_s=1, n_samples=10)
    with pytest.raises(IntegrityError), db_session_factory.begin() as s:
        progress.record_chunk(s, "R-1", 0, first_sample=0, n_samples=10, last_t_s=1.0, end_byte=100)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"start_s": float("nan"), "end_s": 1.0, "n_samples": 1}, "start_s"),
        ({"start_s": 2.0, "end_s": 1.0, "n_samples": 1}, "before start_s"),
        ({"start_s": 0.0, "end_s": 1.0, "n_samples": -1}, "n_samples"),
        ({"start_s": 0.0, "end_s": 1.0, "n_samples": 1, "means": {"temp_c": float("inf")}}, "temp_c"),
        ({"start_s": 0.0, "end_s": 1.0, "n_samples": 1, "pose_deg": [0.0, float("nan")]}, r"pose_deg\[1\]"),
    ],
)
def test_bad_window_refused_naming_run_and_field(db_session_factory, kwargs, match):
    with db_session_factory.begin() as s:
        make_run(s, "R-1")
        with pytest.raises(ValueError, match=match) as info:
            progress.record_window(s, "R-1", 4, **kwargs)
        assert "run R-1 window 4" in str(info.value)


def test_window_for_unknown_run_refused(db_session_factory):
    with pytest.raises(IntegrityError), db_session_factory.begin() as s:
        progress.record_window(s, "no-such-run", 0, start_s=0, end_s=1, n_samples=1)


def test_last_chunk(db_session_factory):
    with db_session_factory.begin() as s:
        make_run(s, "R-1")
        assert progress.last_chunk(s, "R-1") is None
        for seq in range(3):
            progress.record_chunk(
                s,
                "R-1",
                seq,
                first_sample=100 * seq,
                n_samples=100,
                last_t_s=seq + 0.99,
                end_byte=1000 * (seq + 1),
            )
        assert progress.last_chunk(s, "R-1").seq == 2
