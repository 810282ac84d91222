"""Wire models of the REST API (pydantic), never ORM classes.

Request bodies forbid unknown fields, so a misspelt key is a 422 naming it rather than a
silently ignored option. Times are ISO 8601 UTC; numbers are SI unless the field name
says otherwise (``*_deg``, ``channel_unit``).
"""

from __future__ import annotations

import datetime as dt
import math
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from bench.procedures import PROCEDURES

RunStateName = Literal[
    "queued", "running", "paused", "suspended", "completed", "failed", "error", "aborted", "interrupted"
]
SERIAL_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$"


class RunCreate(BaseModel):
    """Start a procedure on the bench for one unit."""

    model_config = ConfigDict(extra="forbid")

    unit_serial: str = Field(
        pattern=SERIAL_PATTERN,
        description="serial of the unit under test: letters, digits, '.', '_', '-' (1..64 characters)",
        examples=["SN-0001"],
    )
    procedure: str = Field(description="registered procedure name", examples=["static-12"])
    dwell_s: float | None = Field(
        default=None,
        gt=0.0,
        le=3600.0,
        description="static dwell per pose (s); default: the service's setting or a noise window",
    )

    @field_validator("procedure")
    @classmethod
    def _known_procedure(cls, value: str) -> str:
        if value not in PROCEDURES:
            raise ValueError(f"unknown procedure {value!r}; known: {', '.join(sorted(PROCEDURES))}")
        return value

    @field_validator("dwell_s")
    @classmethod
    def _finite(cls, value: float | None) -> float | None:
        if value is not None and not math.isfinite(value):
            raise ValueError("dwell_s must be a finite number of seconds")
        return value


class RunCreated(BaseModel):
    """The id of the run just queued; follow it at ``/api/runs/{id}`` and ``/api/runs/{id}/events``."""

    id: str
    state: RunStateName = "queued"


class ProcedurePreviewOut(BaseModel):
    """A procedure before it is started: how long, how many poses and windows, with what dwell."""

    procedure: str
    duration_s: float = Field(description="expected duration on the bench clock (s)")
    wall_duration_s: float = Field(description="expected wall-clock duration (s); bench clock / sim speed")
    n_poses: int
    n_windows: int
    dwell_s: float | None = Field(description="static dwell per pose (s); null: decided by a noise window")
    dwell_source: Literal["given", "service setting", "provisional"]
    assumptions: list[str]
    problems: list[str] = Field(description="table-limit violations; empty when the procedure can run")


class LimitCheckOut(BaseModel):
    """One fitted value checked against its tolerance under the unit model's decision rule."""

    name: str
    unit: str
    value: float
    low: float | None = None
    high: float | None = None
    passed: bool
    expanded_uncertainty: float | None = Field(default=None, description="U of the value (k ≈ 2)")
    acceptance_low: float | None = None
    acceptance_high: float | None = None
    rule: str = "simple-acceptance"


class WindowOut(BaseModel):
    """One completed window of a run."""

    index: int
    label: str
    kind: str
    start_s: float
    end_s: float
    n_samples: int
    pose_deg: list[float] = Field(default_factory=list)


class RunOut(BaseModel):
    """One run as stored (or, before its first database write, as the bench's worker knows it)."""

    id: str
    unit_serial: str
    procedure: str
    kind: Literal["calibration", "drift_check", "other"] = "other"
    state: RunStateName
    progress: float = Field(ge=0.0, le=1.0)
    outcome: str | None = None
    error: str | None = None
    bench: str | None = None
    created_at: dt.datetime | None = None
    started_at: dt.datetime | None = None
    finished_at: dt.datetime | None = None
    n_samples: int | None = None
    last_complete_window: int | None = None
    calibration: dict[str, Any] | None = Field(
        default=None, description="the fit as `calbench calibrate --json` prints it"
    )
    certificate_number: str | None = None
    n_findings: int | None = Field(
        default=None, description="number of diagnosis findings; null while not diagnosed"
    )
    diagnosis: dict[str, Any] | None = Field(
        default=None,
        description="the `calbench diagnose --json` object of the run's recording (in `GET /api/runs/{id}`; "
        "null in lists, while running, or when not diagnosed)",
    )
    diagnosis_note: str | None = Field(
        default=None, description="why there is no diagnosis, when there is none"
    )
    limit_checks: list[LimitCheckOut] = Field(
        default_factory=list,
        description="the unit model's limits evaluated on the fit (empty: no limits applied or no fit yet)",
    )
    decision_rule: str | None = Field(
        default=None, description="the decision rule of the limit checks (ILAC-G8), null without checks"
    )
    certificate_note: str | None = Field(
        default=None, description="why a completed run has no certificate, when it has none"
    )
    windows: list[WindowOut] | None = Field(
        default=None, description="the completed windows (in `GET /api/runs/{id}`; null in lists)"
    )


class AbortOut(BaseModel):
    """Result of an abort request."""

    id: str
    abort_requested: bool
    state: RunStateName


class RunActionOut(BaseModel):
    """Result of a pause, continue or resume request."""

    id: str
    action: Literal["pause", "continue", "resume"] = Field(
        description="pause: the live run holds; continue: a paused or suspended run goes on; "
        "resume: an interrupted run continues on this bench from its next window"
    )
    state: RunStateName
    resumed_from_window: int | None = Field(
        default=None, description="resume: the index of the first window recorded again"
    )


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


class DriftStatus(BaseModel):
    """The drift scheduler: when it runs next and what it did last."""

    enabled: bool
    time_of_day: str | None
    next_run_at: dt.datetime | None
    last_run_at: dt.datetime | None
    procedure: str
    dwell_s: float
    k: float
    running: bool
    pending_units: list[str]


class RecordingResult(BaseModel):
    """Calibration and diagnosis of an uploaded recording."""

    calibration: dict[str, Any]
    diagnosis: dict[str, Any] | None = Field(
        default=None, description="the `calbench diagnose --json` object, or null when not available"
    )
    diagnosis_error: str | None = None


class Health(BaseModel):
    """Liveness and what the service is connected to."""

    status: Literal["ok", "degraded"]
    version: str
    bench: str
    simulated: bool
    database: str
    database_ok: bool
    busy_run: str | None
    public_read: bool
    certificate_problems: list[str] = Field(
        default_factory=list,
        description="what this bench's certificates lack (settings named); on a real bench the first "
        "three kinds (laboratory name, address, authorising person) stop certificates being issued",
    )
    certificates_blocked: bool = Field(
        default=False,
        description="a real bench that cannot issue certificates until its settings are completed",
    )


class WhoAmI(BaseModel):
    """The role of the presented token."""

    role: Literal["viewer", "operator", "admin", "anonymous"]


TokenRoleName = Literal["viewer", "operator", "admin"]


class TokenCreate(BaseModel):
    """A new API token: its role and a label saying whose it is."""

    model_config = ConfigDict(extra="forbid")

    role: TokenRoleName
    label: str = Field(default="", max_length=200, description="who or what uses it, e.g. 'wall screen'")


class TokenOut(BaseModel):
    """A stored API token (never its secret)."""

    id: int
    role: TokenRoleName
    label: str
    created_at: dt.datetime
    last_used_at: dt.datetime | None = None
    revoked_at: dt.datetime | None = None


class TokenCreated(TokenOut):
    """A token just created, with its secret: shown this once, only its SHA-256 is stored."""

    secret: str
