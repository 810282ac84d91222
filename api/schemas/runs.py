"""Wire models of runs: starting one, its state, windows, sample gaps, limit checks and control
actions, a procedure's preview, and an uploaded recording's result."""

from __future__ import annotations

import datetime as dt
import math
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from api.schemas.common import MIN_DWELL_S, SERIAL_PATTERN, RunStateName
from bench.inputs import InputError, check_text
from bench.procedures import PROCEDURES


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
    parameters: dict[str, float] | None = Field(
        default=None,
        max_length=8,
        description="the procedure's own parameters, by the names its factory takes (e.g. repeats and "
        "settle_s of planned-static, as GET /api/plan gives them); stored with the run",
        examples=[{"repeats": 3, "settle_s": 2.0}],
    )
    bench: str | None = Field(
        default=None,
        min_length=1,
        max_length=100,
        description="the bench to run on: its name (GET /api/benches) or its bench file's name; default: "
        "a free bench whose agent is running and can run the procedure, else the one with the shortest "
        "queue (ties: this service's own bench)",
        examples=["bench-a"],
    )

    @field_validator("bench")
    @classmethod
    def _bench_text(cls, value: str | None) -> str | None:
        if value is not None:
            try:
                check_text(value, max_chars=100)
            except InputError as exc:
                raise ValueError(f"bench: {exc}") from None
        return value

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
    state: RunStateName = RunStateName.QUEUED
    bench: str | None = Field(default=None, description="the bench the run is queued on")
    warnings: list[str] = Field(
        default_factory=list,
        description="what the operator should know before the run starts, e.g. that its certificate will "
        "make no statement of conformity (the unit's model has no limits)",
    )


class BenchOut(BaseModel):
    """A bench of the lab and its state (``db.repo.benches.BenchStatus``)."""

    name: str
    state: Literal["idle", "busy", "offline"] = Field(
        description="offline: no agent has reported for 30 s; busy: a run holds the table; idle: free"
    )
    agent_seen_at: dt.datetime | None = Field(description="when its agent last reported (UTC)")
    agent_host: str | None
    procedures: list[str] = Field(description="the procedures its table can run, as its agent reports")
    bench_file: dict[str, Any] | None = Field(description="its bench file: name, version, sha256, path")
    running_run: str | None = Field(description="the run holding the bench")
    n_queued: int = Field(description="runs queued for it")


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
    poses_deg: list[list[float]] = Field(
        default_factory=list,
        description="every commanded pose in order: table angles (deg, outermost axis first)",
    )
    n_windows: int
    observable: list[str] = Field(
        default_factory=list,
        description="model terms the planned motion determines (Fisher information of the dynamic model "
        "for a nominal unit, bench.procedures.observability)",
    )
    not_observable: dict[str, str] = Field(
        default_factory=dict, description="model terms it does not determine well enough to fit, and why"
    )
    dwell_s: float | None = Field(description="static dwell per pose (s); null: decided by a noise window")
    dwell_source: Literal["given", "service setting", "provisional"]
    assumptions: list[str]
    problems: list[str] = Field(description="table-limit violations; empty when the procedure can run")
    warnings: list[str] = Field(
        default_factory=list,
        description="for the unit named by unit_serial: e.g. that its certificate will make no statement of "
        "conformity (its model has no limits)",
    )


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
    means: dict[str, float] = Field(
        default_factory=dict, description="per-channel means over the window (recording units)"
    )


class AuditEntryOut(BaseModel):
    """One action on a run (``run_audit``): who took it, when, and what it did."""

    at: dt.datetime = Field(description="when (UTC)")
    actor: str = Field(description="the operator's name (from the token), `agent` or `system`")
    action: Literal["start", "pause", "continue", "abort", "resume", "state", "withdraw"] = Field(
        description="an operator's request, `state`: the run's state changed (to `state`), or "
        "`withdraw`: a stored PASS or FAIL was withdrawn (the detail says which and why)"
    )
    state: RunStateName | None = Field(default=None, description="the new state of a `state` action")
    detail: str = Field(default="", description="the reason or request, e.g. `interlock open`")
    window_index: int | None = Field(
        default=None, description="the window being recorded at a state change; the first window of a resume"
    )


class RunOut(BaseModel):
    """One run as stored (or, before its first database write, as the bench's worker knows it)."""

    id: str
    unit_serial: str
    procedure: str
    kind: Literal["calibration", "drift_check", "other"] = "other"
    state: RunStateName
    progress: float = Field(ge=0.0, le=1.0)
    phase: Literal["recording", "analysing", "certificate"] | None = Field(
        default=None,
        description="a live run's phase: recording its windows, analysing (fit, verdict, "
        "diagnosis; no pause or abort), storing its certificate; null once final",
    )
    outcome: str | None = Field(
        default=None,
        description="PASS, FAIL, ERROR or ABORTED once final; null for a completed fit no limits judged "
        "(`conformity_note` says why) and while live",
    )
    conformity_note: str | None = Field(
        default=None,
        description="for a completed fit without PASS or FAIL: `no conformity statement: <why no limits "
        "apply>`, e.g. `no conformity statement: no limits are configured for model ADXL335`",
    )
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
    unreadable: str | None = Field(
        default=None,
        description="stored values of the run that cannot be parsed, each named with the parser's message "
        "(those fields are shown empty); null when the whole row reads",
    )
    started_by: str | None = Field(
        default=None, description="who asked for the run (in `GET /api/runs/{id}`; null in lists)"
    )
    audit: list[AuditEntryOut] | None = Field(
        default=None,
        description="every action on the run, oldest first: who, when, what (in `GET /api/runs/{id}`; "
        "null in lists); also `GET /api/runs/{id}/audit`",
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


class RecordingResult(BaseModel):
    """Calibration and diagnosis of an uploaded recording."""

    calibration: dict[str, Any]
    diagnosis: dict[str, Any] | None = Field(
        default=None, description="the `calbench diagnose --json` object, or null when not available"
    )
    diagnosis_error: str | None = None
