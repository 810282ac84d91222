"""Certificate numbering and content hash; API tokens; drift look-ups."""

from __future__ import annotations

import datetime as dt
import hashlib

import pytest

from db.models import TokenRole
from db.repo import certificates, drift, tokens
from tests.db._factories import make_run


def test_numbers_count_up_per_year(db_session_factory):
    with db_session_factory.begin() as s:
        make_run(s, "R-1")
        y25 = dt.datetime(2025, 12, 31, 23, 0, tzinfo=dt.UTC)
        y26 = dt.datetime(2026, 1, 1, 0, 30, tzinfo=dt.timezone(dt.timedelta(hours=2)))  # still 2025 in UTC
        y26b = dt.datetime(2026, 1, 1, 8, 0, tzinfo=dt.UTC)
        numbers = [
            certificates.issue_certificate(s, "R-1", {"n": i}, now=t).number
            for i, t in enumerate([y25, y25, y26, y26b])
        ]
    assert numbers == ["CB-2025-00001", "CB-2025-00002", "CB-2025-00003", "CB-2026-00001"]


def test_sha256_is_of_canonical_json(db_session_factory):
    content = {"b": [1.5, 2], "a": "ü"}
    expected = hashlib.sha256('{"a":"ü","b":[1.5,2]}'.encode()).hexdigest()
    with db_session_factory.begin() as s:
        make_run(s, "R-1")
        cert = certificates.issue_certificate(s, "R-1", content)
        assert cert.sha256 == expected
        assert certificates.get_certificate_by_number(s, cert.number).id == cert.id
        assert certificates.latest_certificate(s, cert.unit_id).id == cert.id


def test_certificate_refuses_nan_and_unknown_run(db_session_factory):
    with db_session_factory.begin() as s:
        make_run(s, "R-1")
        with pytest.raises(ValueError):
            certificates.issue_certificate(s, "R-1", {"bias": float("nan")})
        with pytest.raises(LookupError, match="R-404"):
            certificates.issue_certificate(s, "R-404", {})


def test_latest_certificate_and_flagged_drift(db_session_factory):
    t = [dt.datetime(2025, 1, d, tzinfo=dt.UTC) for d in (1, 2, 3)]
    with db_session_factory.begin() as s:
        unit_id = make_run(s, "R-1").unit_id
        c1 = certificates.issue_certificate(s, "R-1", {"v": 1}, now=t[0])
        c2 = certificates.issue_certificate(s, "R-1", {"v": 2}, now=t[1])
        assert certificates.latest_certificate(s, unit_id).id == c2.id
        assert [c.id for c in certificates.list_certificates(s, unit_id)] == [c1.id, c2.id]
        drift.add_drift_check(s, unit_id, {}, False, checked_at=t[1])
        drift.add_drift_check(
            s, unit_id, {"bias_x": 4.1}, True, reference_certificate_id=c2.id, checked_at=t[2]
        )
        assert [d.flagged for d in drift.list_drift_checks(s, unit_id)] == [False, True]
        assert [d.result for d in drift.list_drift_checks(s, unit_id, flagged_only=True)] == [{"bias_x": 4.1}]


def test_token_found_by_secret_until_revoked(db_session_factory):
    with db_session_factory.begin() as s:
        token, secret = tokens.create_token(s, "viewer", "dashboard")
        token_id = token.id
    with db_session_factory.begin() as s:
        found = tokens.find_token(s, secret)
        assert found is not None and found.role is TokenRole.VIEWER and found.last_used_at is not None
        assert found.token_hash == hashlib.sha256(secret.encode()).hexdigest()
        assert tokens.find_token(s, secret + "x") is None
        assert tokens.revoke_token(s, token_id)
        assert not tokens.revoke_token(s, token_id)
    with db_session_factory() as s:
        assert tokens.find_token(s, secret) is None
        assert len(tokens.list_tokens(s)) == 1
    with pytest.raises(ValueError), db_session_factory.begin() as s:
        tokens.create_token(s, "superuser")
