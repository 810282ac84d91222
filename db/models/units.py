"""Benches and the units (sensors) they calibrate."""

from __future__ import annotations

import datetime as dt
from typing import TYPE_CHECKING, Any

import sqlalchemy as sa
from sqlalchemy.orm import Mapped, mapped_column, relationship

from db.base import Base, IntId

if TYPE_CHECKING:
    from db.models.runs import Run


class Bench(IntId, Base):
    """One calibration station: a rotary table and a DAQ, addressed by URL.

    ``name`` is unique across the lab, so several benches can share one PostgreSQL database.

    :param agent_seen_at: when the bench's agent last said it was alive (UTC; ``None``: no agent
        runs, or it stopped cleanly).
    :param agent_pid, agent_host: that agent's process.
    :param info: what the agent tells of its bench (JSON): ``procedures`` (the names its table can
        run) and ``bench_file`` (the bench file's identity: name, version, sha256, path).
    """

    __tablename__ = "bench"

    name: Mapped[str] = mapped_column(sa.String(100), unique=True)
    table_url: Mapped[str | None] = mapped_column(sa.String(500))
    daq_url: Mapped[str | None] = mapped_column(sa.String(500))
    agent_seen_at: Mapped[dt.datetime | None]
    agent_pid: Mapped[int | None]
    agent_host: Mapped[str | None] = mapped_column(sa.String(255))
    info: Mapped[dict[str, Any] | None]

    units: Mapped[list[Unit]] = relationship(back_populates="bench", lazy="raise")


class Unit(IntId, Base):
    """A sensor under calibration, identified by its serial number.

    :param channel_unit: unit of the raw channels (``V``, ``count``, ``m/s2``, ``g``).
    :param bench_id: the bench it was last calibrated on, if known.
    :param description: what the item is (e.g. ``triaxial MEMS accelerometer``).
    :param customer_name, customer_address: who the unit is calibrated for (ISO/IEC 17025
        7.8.2.1 e); ``None``: not stated by the laboratory.
    :param received_on: date the unit was received (7.8.2.1 h).
    :param nominal_scale: the manufacturer's nominal scale factor, in ``channel_unit`` per m/s².
    :param nominal_bias: the nominal zero-g output of each axis, in ``channel_unit``.
    :param condition: condition as received (7.8.2.1 g).
    """

    __tablename__ = "unit"

    serial: Mapped[str] = mapped_column(sa.String(100), unique=True)
    model: Mapped[str | None] = mapped_column(sa.String(200))
    channel_unit: Mapped[str | None] = mapped_column(sa.String(16))
    bench_id: Mapped[int | None] = mapped_column(sa.ForeignKey("bench.id", ondelete="SET NULL"), index=True)
    description: Mapped[str | None] = mapped_column(sa.String(200))
    customer_name: Mapped[str | None] = mapped_column(sa.String(200))
    customer_address: Mapped[str | None] = mapped_column(sa.String(500))
    received_on: Mapped[dt.date | None] = mapped_column(sa.Date)
    nominal_scale: Mapped[float | None] = mapped_column(sa.Float)
    nominal_bias: Mapped[float | None] = mapped_column(sa.Float)
    condition: Mapped[str | None] = mapped_column(sa.String(500))

    bench: Mapped[Bench | None] = relationship(back_populates="units", lazy="raise")
    runs: Mapped[list[Run]] = relationship(back_populates="unit", lazy="raise")
