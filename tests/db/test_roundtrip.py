"""Every model written and read back field by field, on SQLite and PostgreSQL."""

from __future__ import annotations

import dataclasses
import datetime as dt
import math

import numpy as np
import pytest
import sqlalchemy as sa
from sqlalchemy.exc import IntegrityError, InvalidRequestError

from bench.diagnosis.stored import StoredDiagnosis
from bench.fit_kind import FitKind
from db.models import (
    ApiToken,
    Bench,
    Certificate,
    DriftCheck,
    Finding,
    FitModel,
    Run,
    RunState,
    RunWindow,
    SampleChunk,
    TokenRole,
    Unit,
)
from db.repo import certificates, drift, progress, results, tokens, units
from tests.db._factories import make_run

T0 = dt.datetime(2025, 6, 1, 8, 0, tzinfo=dt.UTC)


def test_bench_and_unit(db_session_factory):
    with db_session_factory.begin() as s:
        b = units.get_or_create_bench(
            s, "bench-a", table_url="socket://127.0.0.1:7000", daq_url="modbus-tcp://x"
        )
        units.get_or_create_unit(s, "SN-1", model="QA-3000", channel_unit="V", bench_id=b.id)
    with db_session_factory() as s:
        bench = s.scalars(sa.select(Bench)).one()
        unit = s.scalars(sa.select(Unit)).one()
        assert (bench.name, bench.table_url, bench.daq_url) == (
            "bench-a",
            "socket://127.0.0.1:7000",
            "modbus-tcp://x",
        )
        assert (unit.serial, unit.model, unit.channel_unit, unit.bench_id) == (
            "SN-1",
            "QA-3000",
            "V",
            bench.id,
        )
        assert unit.created_at.tzinfo is not None


def test_run_with_every_field(db_session_factory):
    with db_session_factory.begin() as s:
        run = make_run(s, "R-1", state=RunState.RUNNING, owner_pid=4242, owner_host="lab-pc-3")
        run.outcome, run.progress, run.error = "PASS", 0.25, "text with ünïcode"
        run.last_complete_window, run.n_samples = 3, 10**10
        run.limit_checks = [
            {"name": "bias_x", "unit": "V", "value": 1.5, "low": None, "high": 2.0, "passed": True}
        ]
        run.finished_at = T0
    with db_session_factory() as s:
        got = s.get(Run, "R-1")
        assert got is not None
        assert got.state is RunState.RUNNING and got.outcome == "PASS" and got.progress == 0.25
        assert (got.owner_pid, got.owner_host, got.error) == (4242, "lab-pc-3", "text with ünïcode")
        assert got.last_complete_window == 3 and got.n_samples == 10**10
        assert got.params == {"dwell": {"dwell_s": 40.0, "source": "fixed", "reason": "given"}}
        assert got.limit_checks[0]["high"] == 2.0 and got.limit_checks[0]["low"] is None
        assert got.finished_at == T0 and got.recording_path == "/data/R-1.csv"


def test_run_progress_outside_0_1_refused_by_the_database(db_session_factory):
    with pytest.raises(IntegrityError), db_session_factory.begin() as s:
        make_run(s).progress = 1.5


def test_unknown_state_string_refused(db_session_factory):
    with db_session_factory.begin() as s:
        make_run(s, "R-1")
    with pytest.raises(IntegrityError), db_session_factory.begin() as s:
        s.execute(sa.text("UPDATE run SET state = 'exploded' WHERE id = 'R-1'"))


def test_relationships_do_not_load_implicitly(db_session_factory):
    with db_session_factory.begin() as s:
        make_run(s, "R-1")
    with db_session_factory() as s:
        run = s.get(Run, "R-1")
        with pytest.raises(InvalidRequestError):
            _ = run.unit  # lazy="raise": no hidden queries


def test_window_and_chunk(db_session_factory):
    with db_session_factory.begin() as s:
        make_run(s, "R-1")
        progress.record_window(
            s,
            "R-1",
            0,
            start_s=10.0,
            end_s=50.0,
            n_samples=4000,
            label="pos01",
            kind="static",
            pose_deg=[0.0, 90.0, 180.0],
            means={"table_deg": [0.0, 90.0, float("nan")], "temp_c": 24.5},
            step_index=2,
        )
        progress.record_chunk(
            s,
            "R-1",
            0,
            first_sample=0,
            n_samples=1000,
            last_t_s=9.99,
            end_byte=65536,
            daq_seq=999,
            window_index=None,
        )
    with db_session_factory() as s:
        w = s.scalars(sa.select(RunWindow)).one()
        assert (w.index, w.label, w.kind, w.start_s, w.end_s, w.n_samples, w.step_index) == (
            0,
            "pos01",
            "static",
            10.0,
            50.0,
            4000,
            2,
        )
        assert w.pose_deg == [0.0, 90.0, 180.0]
        assert w.means == {"table_deg": [0.0, 90.0, None], "temp_c": 24.5}
        c = s.scalars(sa.select(SampleChunk)).one()
        assert (c.seq, c.first_sample, c.n_samples, c.last_t_s, c.end_byte, c.daq_seq, c.window_index) == (
            0,
            0,
            1000,
            9.99,
            65536,
            999,
            None,
        )


def test_fit_with_covariance(db_session_factory):
    rng = np.random.default_rng(7)
    a = rng.normal(size=(12, 12))
    cov = a @ a.T * 1e-10
    contract = {"unit": "SN-0001", "bias": [1.5, 1.5, 1.5], "terms": ["bias", "scale_matrix"], "extra": {}}
    names = [f"p{i}" for i in range(12)]
    with db_session_factory.begin() as s:
        make_run(s, "R-1")
        results.add_fit(s, "R-1", "static", contract, covariance=cov, param_names=names)
    with db_session_factory() as s:
        f = s.scalars(sa.select(FitModel)).one()
        assert f.kind is FitKind.STATIC and f.contract == contract and f.param_names == names
        np.testing.assert_array_equal(f.covariance, cov)  # bit-exact, not a float-text round trip


@pytest.mark.parametrize(
    ("cov", "names", "match"),
    [
        (np.ones((2, 3)), ["a", "b"], "square"),
        (np.array([[1.0, np.nan], [np.nan, 1.0]]), ["a", "b"], "non-finite"),
        (np.array([[1.0, 0.5], [0.4, 1.0]]), ["a", "b"], "symmetric"),
        (np.eye(2), ["a"], "names"),
    ],
)
def test_bad_covariance_refused(db_session_factory, cov, names, match):
    with pytest.raises(ValueError, match=match), db_session_factory.begin() as s:
        make_run(s, "R-1")
        results.add_fit(s, "R-1", "static", {}, covariance=cov, param_names=names)


def test_findings(db_session_factory):
    finding = {
        "effect": "nonlinearity_quadratic",
        "summary": "z channel: k2 1.5e-3 per g",
        "parameters": {"k2_per_g": [0.0, 0.0, 0.0015]},
        "sigma": {"k2_per_g": [0.0, 0.0, 4e-5]},
        "delta_bic": -1068.8,
        "residual_rms_after": 3.2e-6,
    }
    with db_session_factory.begin() as s:
        make_run(s, "R-1")
        results.add_findings(s, "R-1", StoredDiagnosis.from_contract({"findings": [finding]}).findings)
    with db_session_factory() as s:
        f = s.scalars(sa.select(Finding)).one()
        assert (f.effect, f.summary, f.parameters, f.sigma) == (
            finding["effect"],
            finding["summary"],
            finding["parameters"],
            finding["sigma"],
        )
        assert f.delta_bic == -1068.8 and f.residual_rms_after == 3.2e-6
    (stored,) = StoredDiagnosis.from_contract({"findings": [finding]}).findings
    nan = dataclasses.replace(stored, delta_bic=math.nan)
    with (
        pytest.raises(ValueError, match="run R-1 finding 0: delta_bic = nan is not finite"),
        db_session_factory.begin() as s,
    ):
        results.add_findings(s, "R-1", [nan])


def test_certificate_and_drift_check(db_session_factory):
    content = {"unit": "SN-0001", "bias": [1.5, 1.5, 1.5], "expanded_uncertainty_k2": [2e-5, 2e-5, 2e-5]}
    with db_session_factory.begin() as s:
        run = make_run(s, "R-1")
        cert = certificates.issue_certificate(s, "R-1", content, pdf=b"%PDF-1.7\x00\xff", now=T0)
        drift.add_drift_check(
            s,
            run.unit_id,
            {"bias_x": {"delta": 1e-4, "u": 3e-5}},
            True,
            run_id="R-1",
            reference_certificate_id=cert.id,
            checked_at=T0,
        )
    with db_session_factory() as s:
        c = s.scalars(sa.select(Certificate)).one()
        assert (c.number, c.year, c.serial, c.content, c.pdf, c.issued_at) == (
            "CB-2025-00001",
            2025,
            1,
            content,
            b"%PDF-1.7\x00\xff",
            T0,
        )
        d = s.scalars(sa.select(DriftCheck)).one()
        assert d.flagged is True and d.reference_certificate_id == c.id and d.run_id == "R-1"
        assert d.result == {"bias_x": {"delta": 1e-4, "u": 3e-5}} and d.checked_at == T0


def test_api_token(db_session_factory):
    with db_session_factory.begin() as s:
        _token, secret = tokens.create_token(s, TokenRole.OPERATOR, "bench-a operator")
    with db_session_factory() as s:
        row = s.scalars(sa.select(ApiToken)).one()
        assert row.role is TokenRole.OPERATOR and row.label == "bench-a operator"
        assert secret not in row.token_hash and len(row.token_hash) == 64
