"""Benches and units: race-free get-or-create, look-ups by name and serial."""

from __future__ import annotations

import sqlalchemy as sa
from sqlalchemy.orm import Session

from db.models import Bench, Unit
from db.repo._search import contains_any
from db.repo._upsert import insert_or_ignore
from db.types import utc_now


def get_or_create_bench(
    session: Session, name: str, *, table_url: str | None = None, daq_url: str | None = None
) -> Bench:
    """The bench called ``name``, created if new; device URLs are updated when given."""
    if not name.strip():
        raise ValueError("bench name must not be empty")
    insert_or_ignore(
        session,
        Bench,
        {"name": name, "table_url": table_url, "daq_url": daq_url, "created_at": utc_now()},
        ["name"],
    )
    bench = session.scalars(sa.select(Bench).where(Bench.name == name)).one()
    if table_url is not None and bench.table_url != table_url:
        bench.table_url = table_url
    if daq_url is not None and bench.daq_url != daq_url:
        bench.daq_url = daq_url
    session.flush()
    return bench


def get_or_create_unit(
    session: Session,
    serial: str,
    *,
    model: str | None = None,
    channel_unit: str | None = None,
    bench_id: int | None = None,
) -> Unit:
    """The unit with ``serial``, created if new.

    Safe when two benches register the same serial at once. Fields given here fill in
    unknown ones; a ``bench_id`` given moves the unit to that bench.
    """
    if not serial.strip():
        raise ValueError("unit serial must not be empty")
    insert_or_ignore(
        session,
        Unit,
        {
            "serial": serial,
            "model": model,
            "channel_unit": channel_unit,
            "bench_id": bench_id,
            "created_at": utc_now(),
        },
        ["serial"],
    )
    unit = session.scalars(sa.select(Unit).where(Unit.serial == serial)).one()
    if model is not None and unit.model is None:
        unit.model = model
    if channel_unit is not None and unit.channel_unit is None:
        unit.channel_unit = channel_unit
    if bench_id is not None and unit.bench_id != bench_id:
        unit.bench_id = bench_id
    session.flush()
    return unit


def get_unit_by_serial(session: Session, serial: str) -> Unit | None:
    """The unit with ``serial`` or ``None``."""
    return session.scalars(sa.select(Unit).where(Unit.serial == serial)).one_or_none()


def get_bench_by_name(session: Session, name: str) -> Bench | None:
    """The bench called ``name`` or ``None``."""
    return session.scalars(sa.select(Bench).where(Bench.name == name)).one_or_none()


def list_units(
    session: Session, *, search: str | None = None, limit: int | None = None, offset: int = 0
) -> list[Unit]:
    """Units by serial; ``search``: only those whose serial, model or customer contains it
    (case-insensitive); ``offset`` and ``limit`` page the list."""
    stmt = sa.select(Unit).order_by(Unit.serial)
    if search:
        stmt = stmt.where(contains_any(search, Unit.serial, Unit.model, Unit.customer_name))
    if offset:
        stmt = stmt.offset(offset)
    if limit is not None:
        stmt = stmt.limit(limit)
    return list(session.scalars(stmt))
