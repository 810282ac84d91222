"""DbRunObserver: a run's events land in the database; a killed run resumes from the DB."""

from __future__ import annotations

import dataclasses
import datetime as dt
import json

import pytest
import sqlalchemy as sa
from sqlalchemy.exc import OperationalError

from bench import records as br
from bench import run_state as rs
from bench.fit_kind import FitKind
from bench.limit_check import LimitCheck
from bench.run_observer import RunObserver
from db.models import FitModel, Run, RunState, SampleChunk
from db.observer import DbRunObserver, final_state
from db.repo import progress, recovery
from db.repo.gaps import list_gaps
from db.repo.results import fit_contract
from tests.support.fits import calibration_result

T0 = dt.datetime(2025, 6, 1, 8, 0, tzinfo=dt.UTC)
FIT = calibration_result(serial="SN-7")


def _start(pid: int, resumed_from: int | None = None) -> br.RunStart:
    return br.RunStart(
        run_id="20250601T080000Z-SN-7-abcdef",
        unit_serial="SN-7",
        procedure="static-12",
        bench_name="bench-a",
        recording_path="/data/r.csv",
        sample_rate_hz=100.0,
        n_axes=2,
        n_windows=4,
        expected_duration_s=400.0,
        parameters={"poses": 4},
        started_at=T0,
        host="lab",
        pid=pid,
        resumed_from_window=resumed_from,
        dwell=br.DwellChoice(40.0, "fixed", "given on the command line"),
    )


def _window(i: int) -> br.WindowRecord:
    return br.WindowRecord(
        index=i,
        label=f"pos{i:02d}",
        kind=br.WindowKind.STATIC,
        start_s=100.0 * i + 10,
        end_s=100.0 * i + 50,
        n_samples=4000,
        pose_deg=(0.0, 90.0 * i),
        mean_table_deg=(0.001, 90.0 * i),
        temp_c_mean=float("nan"),
        step_index=2 * i + 1,
        means={"ax": 1.5, "ay": 1.49, "az": 1.51},
    )


def _chunk(seq: int, window_index: int | None) -> br.ChunkRecord:
    # one chunk per 50 s: chunk 2k covers 100k..100k+50 (the window ends at 50), 2k+1 the move
    return br.ChunkRecord(
        seq=seq,
        first_sample=5000 * seq,
        n_samples=5000,
        last_t_s=50.0 * (seq + 1),
        end_byte=400_000 * (seq + 1),
        window_index=window_index,
    )


def _play(obs: DbRunObserver, run_id: str, windows: range) -> None:
    for i in windows:
        obs.on_chunk(run_id, _chunk(2 * i, i))
        obs.on_window(run_id, _window(i))
        obs.on_chunk(run_id, _chunk(2 * i + 1, None))


def test_fresh_run_to_pass(db_session_factory):
    obs = DbRunObserver(db_session_factory)
    start = _start(pid=1234)
    obs.on_start(start)
    _play(obs, start.run_id, range(4))
    obs.on_dwell(
        start.run_id, br.DwellChoice(55.0, "noise_window", "Allan minimum at 55 s", {"tau_min_s": 55.0})
    )
    check = LimitCheck("bias_x", "V", 1.5, 1.4, 1.6, True)
    obs.on_finish(
        br.RunRecord(
            start,
            rs.RunState.COMPLETED,
            rs.Outcome.PASS,
            tuple(_window(i) for i in range(4)),
            ended_at=T0 + dt.timedelta(minutes=7),
            calibration=FIT,
            limit_checks=(check,),
            n_samples=40_000,
        )
    )
    with db_session_factory() as s:
        run = s.get(Run, start.run_id)
        assert (run.state, run.outcome, run.progress, run.last_complete_window, run.n_samples) == (
            RunState.COMPLETED,
            "PASS",
            1.0,
            3,
            40_000,
        )
        assert (run.owner_pid, run.owner_host, run.started_at, run.finished_at) == (
            1234,
            "lab",
            T0,
            T0 + dt.timedelta(minutes=7),
        )
        assert run.params["dwell"] == {
            "dwell_s": 55.0,
            "source": "noise_window",
            "reason": "Allan minimum at 55 s",
            "details": {"tau_min_s": 55.0},
        }
        assert run.params["poses"] == 4 and run.params["sample_rate_hz"] == 100.0
        assert run.limit_checks == [
            {
                "name": "bias_x",
                "unit": "V",
                "value": 1.5,
                "low": 1.4,
                "high": 1.6,
                "passed": True,
                "expanded_uncertainty": None,
                "acceptance_low": None,
                "acceptance_high": None,
                "rule": "simple-acceptance",
            }
        ]
        w = progress.list_windows(s, start.run_id)
        assert [x.label for x in w] == ["pos00", "pos01", "pos02", "pos03"]
        assert w[1].means == {"ax": 1.5, "ay": 1.49, "az": 1.51, "table_deg": [0.001, 90.0], "temp_c": None}
        assert w[1].pose_deg == [0.0, 90.0] and w[1].step_index == 3 and w[1].kind == "static"
        assert s.scalar(sa.select(sa.func.count()).select_from(SampleChunk)) == 8
        fit = s.scalars(sa.select(FitModel)).one()
        assert fit.kind is FitKind.STATIC and fit.contract == json.loads(json.dumps(FIT.to_contract()))
        # the fit has one home: its row (params keeps the procedure's parameters only)
        assert fit_contract(s, run.id) == fit.contract and fit.contract["unit"] == "SN-7"
        assert "calibration" not in run.params


def test_killed_run_is_interrupted_then_resumed_from_its_next_window(db_session_factory):
    start = _start(pid=1234)
    first = DbRunObserver(db_session_factory)
    first.on_start(start)
    _play(first, start.run_id, range(2))  # windows 0, 1 complete, chunks 0..3
    first.on_chunk(start.run_id, _chunk(4, 2))  # window 2 in flight when the process is killed
    with db_session_factory.begin() as s:
        assert recovery.mark_interrupted_runs(s, "lab", lambda pid: pid != 1234) == [start.run_id]
    with db_session_factory() as s:
        point = recovery.resume_point(s, start.run_id)
    # window 1 ends at 150 s; chunk 2 (last sample at 150 s) completes it: keep chunks 0..2
    assert (point.next_window_index, point.keep_until_s, point.keep_chunks, point.keep_end_byte) == (
        2,
        150.0,
        3,
        1_200_000,
    )

    second = DbRunObserver(db_session_factory)
    resumed = _start(pid=5678, resumed_from=point.next_window_index)
    second.on_start(resumed)
    second.on_chunk(start.run_id, _chunk(point.keep_chunks, None))  # seq 3 written again by the new writer
    _play(second, start.run_id, range(2, 4))
    second.on_finish(
        br.RunRecord(
            resumed, rs.RunState.FAILED, rs.Outcome.FAIL, tuple(_window(i) for i in range(4)), error=None
        )
    )
    with db_session_factory() as s:
        run = s.get(Run, start.run_id)
        assert (run.state, run.outcome, run.owner_pid, run.resume_count) == (RunState.FAILED, "FAIL", 5678, 1)
        assert [w.index for w in progress.list_windows(s, start.run_id)] == [0, 1, 2, 3]
        seqs = s.scalars(sa.select(SampleChunk.seq).order_by(SampleChunk.seq)).all()
        assert seqs == list(range(8))  # the first life's chunks 3 and 4 were replaced, not duplicated


def test_finished_run_cannot_start_again(db_session_factory):
    obs = DbRunObserver(db_session_factory)
    start = _start(pid=1)
    obs.on_start(start)
    obs.on_finish(br.RunRecord(start, rs.RunState.ABORTED, rs.Outcome.ABORTED, (), error="operator stop"))
    with pytest.raises(ValueError, match="aborted"):
        obs.on_start(start)


@pytest.mark.parametrize(
    ("outcome", "state"),
    [
        (rs.Outcome.PASS, "completed"),
        (None, "completed"),
        (rs.Outcome.FAIL, "failed"),
        (rs.Outcome.ERROR, "error"),
        (rs.Outcome.ABORTED, "aborted"),
    ],
)
def test_outcome_to_state(outcome, state):
    assert final_state(outcome).value == state


def test_state_changes_and_unfinished_record(db_session_factory):
    obs = DbRunObserver(db_session_factory)
    start = _start(pid=1)
    obs.on_start(start)
    obs.on_state(start.run_id, br.StateChange(rs.RunState.SUSPENDED, "interlock open"))
    with db_session_factory() as s:
        assert s.get(Run, start.run_id).state is RunState.SUSPENDED
    obs.on_state(start.run_id, br.StateChange(rs.RunState.RUNNING, "interlock closed"))
    obs.on_finish(br.RunRecord(start, rs.RunState.INTERRUPTED, None, (), error="DAQ link lost"))
    with db_session_factory() as s:
        run = s.get(Run, start.run_id)
        assert run.state is RunState.INTERRUPTED and "DAQ link lost" in run.error


def test_progress_is_throttled(db_session_factory):
    now = [0.0]
    obs = DbRunObserver(db_session_factory, min_progress_interval_s=1.0, clock=lambda: now[0])
    start = _start(pid=1)
    obs.on_start(start)

    def progress_at(elapsed_s: float) -> br.Progress:
        return br.Progress(0, 10, "move", None, 4, elapsed_s, 400.0, (0.0, 0.0), rs.RunState.RUNNING)

    def stored() -> float:
        with db_session_factory() as s:
            return s.get(Run, start.run_id).progress

    obs.on_progress(start.run_id, progress_at(100.0))
    assert stored() == 0.25
    now[0] = 0.5
    obs.on_progress(start.run_id, progress_at(200.0))
    assert stored() == 0.25  # within the interval: skipped
    now[0] = 1.2
    obs.on_progress(start.run_id, progress_at(200.0))
    assert stored() == 0.5


def test_transient_database_error_is_retried(db_session_factory):
    failures = [1]

    class Flaky:
        def begin(self):
            if failures[0]:
                failures[0] -= 1
                raise OperationalError("BEGIN", {}, Exception("database is locked"))
            return db_session_factory.begin()

    obs = DbRunObserver(Flaky(), retry_wait_s=0.0)  # type: ignore[arg-type]
    obs.on_start(_start(pid=1))
    with db_session_factory() as s:
        assert s.get(Run, _start(pid=1).run_id) is not None
    failures[0] = 5
    with pytest.raises(OperationalError):
        obs.on_dwell(_start(pid=1).run_id, br.DwellChoice(1.0, "fixed", "x"))


def test_observer_satisfies_the_protocol(db_session_factory):
    assert isinstance(DbRunObserver(db_session_factory), RunObserver)


@pytest.mark.parametrize(
    ("procedure", "kind", "stored"),
    [
        ("static-12", FitKind.STATIC, "static"),
        ("static-12", FitKind.ORIENTATION_FREE, "scalar"),
        # the fit's own kind decides, never the procedure's name
        ("oscillation-2axis", FitKind.STATIC, "static"),
    ],
)
def test_the_stored_kind_is_the_kind_the_fit_chose(db_session_factory, procedure, kind, stored):
    start = dataclasses.replace(_start(pid=1), procedure=procedure)
    obs = DbRunObserver(db_session_factory)
    obs.on_start(start)
    fit = calibration_result(kind, serial="SN-7")
    cov, names = fit.covariance_rows()
    obs.on_finish(
        br.RunRecord(start, rs.RunState.COMPLETED, rs.Outcome.PASS, (), calibration=fit,
                     fit_covariance=cov, fit_param_names=names)
    )  # fmt: skip
    with db_session_factory() as s:
        row = s.scalars(sa.select(FitModel)).one()
        assert row.kind is kind and list(row.param_names) == list(names)
        # the column holds the names databases have stored since migration 0001
        assert s.scalar(sa.text("SELECT kind FROM fit_model")) == stored
        assert (
            fit_contract(s, start.run_id) == row.contract
            and "calibration" not in s.get(Run, start.run_id).params
        )


def _gap(after_row: int, n_lost: int, window: int | None) -> br.GapRecord:
    return br.GapRecord(
        first_lost_seq=after_row + 7,
        n_lost=n_lost,
        cause="overflow",
        after_row=after_row,
        t_last_s=after_row / 100.0,
        t_resume_s=(after_row + n_lost + 1) / 100.0,
        window_index=window,
        window_label="" if window is None else f"pos{window:02d}",
        action="between windows" if window is None else "window re-measured",
    )


def test_sample_gaps_are_stored_as_they_happen_and_the_finished_list_replaces_them(db_session_factory):
    obs = DbRunObserver(db_session_factory)
    start = _start(pid=1234)
    obs.on_start(start)
    obs.on_gap(start.run_id, _gap(500, 40, 1))
    obs.on_gap(start.run_id, _gap(900, 3, None))
    with db_session_factory() as s:
        live = list_gaps(s, start.run_id)
        assert "sample_gaps" not in s.get(Run, start.run_id).params
    assert [(g.after_row, g.n_lost, g.action) for g in live] == [
        (500, 40, "window re-measured"),
        (900, 3, "between windows"),
    ]
    # A resume cut the rows after 800: the run's final list is the recording's, not the union.
    kept = (_gap(500, 40, 1),)
    obs.on_finish(
        br.RunRecord(start, rs.RunState.COMPLETED, rs.Outcome.PASS, (), n_samples=40_000, gaps=kept)
    )
    with db_session_factory() as s:
        final = list_gaps(s, start.run_id)
    assert final == list(kept)
