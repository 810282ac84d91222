"""Certificates: numbering that two benches can use at once, and look-ups.

Numbers are ``CB-<year>-<serial:05d>``. The next serial is ``max + 1`` for the year,
inserted inside a SAVEPOINT; the unique constraint on ``(year, serial)`` turns a race
into an ``IntegrityError``, and the issuer tries the next number.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
from collections.abc import Mapping
from typing import Any

import sqlalchemy as sa
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from db.models import Certificate, Run
from db.types import utc_now

NUMBER_PREFIX = "CB"
MAX_ATTEMPTS = 50


def canonical_sha256(content: Mapping[str, Any]) -> str:
    """Hex SHA-256 of ``content`` as canonical JSON (sorted keys, no spaces, UTF-8)."""
    text = json.dumps(content, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def format_number(year: int, serial: int) -> str:
    """``CB-2025-00042``."""
    return f"{NUMBER_PREFIX}-{year:04d}-{serial:05d}"


def issue_certificate(
    session: Session,
    run_id: str,
    content: Mapping[str, Any],
    *,
    pdf: bytes | None = None,
    now: dt.datetime | None = None,
) -> Certificate:
    """Issue the next certificate number of the year for ``run_id``.

    :raises LookupError: no such run. :raises ValueError: content not JSON-able (NaN etc.).
    :raises RuntimeError: no free number after ``MAX_ATTEMPTS`` tries.
    """
    unit_id = session.scalar(sa.select(Run.unit_id).where(Run.id == run_id))
    if unit_id is None:
        raise LookupError(f"run {run_id} not found")
    now = now or utc_now()
    year = now.astimezone(dt.UTC).year
    digest = canonical_sha256(content)
    for _ in range(MAX_ATTEMPTS):
        serial = 1 + (
            session.scalar(sa.select(sa.func.max(Certificate.serial)).where(Certificate.year == year)) or 0
        )
        cert = Certificate(
            run_id=run_id,
            unit_id=unit_id,
            year=year,
            serial=serial,
            number=format_number(year, serial),
            content=dict(content),
            sha256=digest,
            pdf=pdf,
            issued_at=now,
        )
        try:
            with session.begin_nested():
                session.add(cert)
        except IntegrityError:
            continue
        return cert
    raise RuntimeError(f"run {run_id}: no free certificate number for {year} after {MAX_ATTEMPTS} attempts")


def get_certificate_by_number(session: Session, number: str) -> Certificate | None:
    """The certificate with ``number`` or ``None``."""
    return session.scalars(sa.select(Certificate).where(Certificate.number == number)).one_or_none()


def certificate_of_run(session: Session, run_id: str) -> Certificate | None:
    """The certificate issued for run ``run_id``, if any."""
    return session.scalars(sa.select(Certificate).where(Certificate.run_id == run_id)).first()


def latest_certificate(session: Session, unit_id: int) -> Certificate | None:
    """The unit's most recently issued certificate, or ``None``."""
    return session.scalars(
        sa.select(Certificate)
        .where(Certificate.unit_id == unit_id)
        .order_by(Certificate.issued_at.desc(), Certificate.id.desc())
        .limit(1)
    ).one_or_none()


def list_certificates(session: Session, unit_id: int) -> list[Certificate]:
    """The unit's certificates, oldest first."""
    return list(
        session.scalars(sa.select(Certificate).where(Certificate.unit_id == unit_id).order_by(Certificate.id))
    )
