"""Wire models of units and what the service keeps about them: registration, certificates,
drift checks and the drift scheduler, a unit's history."""

from __future__ import annotations

import datetime as dt
import math
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from api.schemas.common import SERIAL_PATTERN, stored_text
from api.schemas.runs import RunOut


class UnitRegistration(BaseModel):
    """What the laboratory states about a unit (ISO/IEC 17025 7.8.2.1 e, g, h). Fields not sent
    keep their value; ``null`` clears one."""

    model_config = ConfigDict(extra="forbid")

    model: str | None = Field(default=None, max_length=200, examples=["ADXL335"])
    description: str | None = Field(default=None, max_length=200, examples=["triaxial MEMS accelerometer"])
    channel_unit: Literal["V", "count", "m/s2", "g"] | None = None
    customer_name: str | None = Field(default=None, max_length=200)
    customer_address: str | None = Field(default=None, max_length=500)
    received_on: dt.date | None = Field(default=None, description="date the unit was received")
    nominal_scale: float | None = Field(
        default=None, description="nominal scale factor, channel unit per m/s² (non-zero)"
    )
    nominal_bias: float | None = Field(default=None, description="nominal zero-g output, channel unit")
    condition: str | None = Field(default=None, max_length=500, examples=["as received, no damage"])

    @field_validator("model", "description", "customer_name", "condition")
    @classmethod
    def _plain_text(cls, value: str | None) -> str | None:
        return stored_text(value)

    @field_validator("customer_address")
    @classmethod
    def _address_text(cls, value: str | None) -> str | None:
        return stored_text(value, multiline=True)

    @field_validator("nominal_scale", "nominal_bias")
    @classmethod
    def _finite_number(cls, value: float | None) -> float | None:
        if value is not None and not math.isfinite(value):
            raise ValueError("must be a finite number")
        return value

    @field_validator("nominal_scale")
    @classmethod
    def _non_zero(cls, value: float | None) -> float | None:
        if value is not None and (value == 0.0 or abs(value) > 1e9):
            raise ValueError("nominal_scale must be non-zero and below 1e9 (channel unit per m/s²)")
        return value


class UnitOut(BaseModel):
    """A unit (sensor) known to the service."""

    serial: str
    model: str | None = None
    channel_unit: str | None = None
    description: str | None = None
    customer_name: str | None = None
    customer_address: str | None = None
    received_on: dt.date | None = None
    nominal_scale: float | None = None
    nominal_bias: float | None = None
    condition: str | None = None
    bench: str | None = None
    n_runs: int = 0
    last_certificate: str | None = None
    last_drift_flagged: bool | None = None


class CertificateOut(BaseModel):
    """An issued certificate: number, hash of the canonical JSON content, and the content."""

    number: str
    run_id: str
    unit_serial: str
    issued_at: dt.datetime
    sha256: str
    content: dict[str, Any]
    conformity_withdrawn: str | None = Field(
        default=None,
        description="why the statement of conformity in `content` no longer stands (the run's verdict "
        "was withdrawn; the issued document is kept unchanged), null when it stands or none is made",
    )


class DriftCheckOut(BaseModel):
    """A nightly re-measurement compared with the unit's last certificate."""

    id: int
    unit_serial: str
    checked_at: dt.datetime
    flagged: bool
    run_id: str | None = None
    reference_certificate: str | None = None
    result: dict[str, Any]


class UnitHistory(BaseModel):
    """Everything the service knows about one unit, oldest first."""

    unit: UnitOut
    runs: list[RunOut]
    certificates: list[CertificateOut]
    drift_checks: list[DriftCheckOut]


class DriftRequest(BaseModel):
    """Run the drift check now (all registered units, or one)."""

    model_config = ConfigDict(extra="forbid")

    unit_serial: str | None = Field(default=None, pattern=SERIAL_PATTERN)


class DriftNotChecked(BaseModel):
    """A unit whose drift check was not queued: its bench (if known) and why."""

    unit_serial: str
    bench: str | None
    reason: str


class DriftStatus(BaseModel):
    """The drift scheduler: when it runs next and what it did last.

    :param running: a drift check holds a bench now; :param pending_units: the units whose check
        waits in a bench's queue; :param not_checked: the units its last queueing (in this API
        process) left unchecked, and why.
    """

    enabled: bool
    time_of_day: str | None
    next_run_at: dt.datetime | None
    last_run_at: dt.datetime | None
    procedure: str
    dwell_s: float
    k: float
    running: bool
    pending_units: list[str]
    not_checked: list[DriftNotChecked] = []
