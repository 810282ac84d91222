"""Wire models of the REST API (pydantic), never ORM classes.

Request bodies forbid unknown fields, so a misspelt key is a 422 naming it rather than a
silently ignored option. Text a request stores passes the text rules of :mod:`bench.inputs`
(no NUL, control or bidi-control characters, bounded length); numbers are finite.
Times are ISO 8601 UTC; numbers are SI unless the field name
says otherwise (``*_deg``, ``channel_unit``).
"""

from __future__ import annotations

import datetime as dt
import math
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from bench.inputs import InputError, check_text
from bench.procedures import PROCEDURES

RunStateName = Literal[
    "queued", "running", "paused", "suspended", "completed", "failed", "error", "aborted", "interrupted"
]
SERIAL_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$"
MIN_DWELL_S = 0.5
"""Shortest static dwell a run may ask for (s): shorter windows hold too few samples to fit."""
LINK_PATH_PATTERN = r"^/api/runs/[A-Za-z0-9._~%-]{1,200}/(events|certificate\.pdf|export/[a-z-]{1,20})$"


def _stored_text(value: str | None, *, multiline: bool = False) -> str | None:
    if value is None:
        return None
    try:
        return check_text(value, multiline=multiline)
    except InputError as exc:
        raise ValueError(str(exc)) from None


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
        ge=MIN_DWELL_S,
        le=3600.0,
        description="static dwell per pose (s), 0.5..3600; default: the service's setting or a noise window",
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


class SampleGapOut(BaseModel):
    """Samples the DAQ produced that the recording does not hold (``bench.records.GapRecord``)."""

    first_lost_seq: int | None = Field(description="DAQ sequence number of the first lost sample")
    n_lost: int | None = Field(description="samples lost; null: unknown")
    cause: str = Field(description="dropped, overflow, restart or unknown")
    after_row: int = Field(description="rows of the recording before the gap")
    t_last_s: float | None = Field(description="time of the last row before the gap (recording clock, s)")
    t_resume_s: float = Field(description="time of the next row (recording clock, s)")
    window_index: int | None = Field(description="window being recorded, null between windows")
    window_label: str = ""
    action: str = Field(description="the rule applied: `window re-measured` or `between windows`")
    daq_epoch: int = 0


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
    n_samples_lost: int | None = Field(
        default=None, description="samples the DAQ produced that the recording lacks (sum over `gaps`)"
    )
    gaps: list[SampleGapOut] | None = Field(
        default=None,
        description="every sample gap: where it is, what was done (in `GET /api/runs/{id}`; null in lists)",
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

    @field_validator("model", "description", "customer_name", "condition")
    @classmethod
    def _plain_text(cls, value: str | None) -> str | None:
        return _stored_text(value)

    @field_validator("customer_address")
    @classmethod
    def _address_text(cls, value: str | None) -> str | None:
        return _stored_text(value, multiline=True)

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
    """Liveness and what the service is connected to (the database only by its kind: the
    endpoint needs no token, so it shows no path or host)."""

    status: Literal["ok", "degraded"]
    version: str
    bench: str
    simulated: bool
    database: str = Field(description="the database's kind: sqlite or postgresql")
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

    @field_validator("label")
    @classmethod
    def _plain_text(cls, value: str) -> str:
        return _stored_text(value) or ""


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


class LinkRequest(BaseModel):
    """Ask for a signed link to a resource a browser opens directly."""

    model_config = ConfigDict(extra="forbid")

    path: str = Field(
        pattern=LINK_PATH_PATTERN,
        max_length=300,
        description="/api/runs/{id}/certificate.pdf, /api/runs/{id}/events or /api/runs/{id}/export/{format}",
        examples=["/api/runs/R-20250101-0001/certificate.pdf"],
    )


class LinkOut(BaseModel):
    """A link that works without a token until ``expires_at`` (and while the token it was made
    for is live)."""

    url: str
    expires_at: dt.datetime
