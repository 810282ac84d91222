"""All calbench tables. Importing this package registers every model on ``Base.metadata``.

=================  ==========================================================================
table              holds
=================  ==========================================================================
``bench``          a rotary table + DAQ station (unique name, device URLs)
``unit``           a sensor under calibration (unique serial)
``run``            one procedure on one unit: state machine, owner process, progress
``run_audit``      every action on a run: operator (or agent, system), time, state, reason
``run_window``     a completed window of a run (label, times, per-channel means)
``sample_chunk``   a durable chunk of the run's recording CSV (the CSV is the sample store)
``sample_gap``     a sample gap of a run (samples lost, where, the rule applied)
``fit_model``      a run's fitted model (its one home): the ``calibrate --json`` dict and its
                   covariance (.npy); the newest row of a run is its fit
``finding``        a diagnosis finding (effect id, parameters, sigma, delta BIC)
``certificate``    an issued certificate: unique number, JSON content, sha256, optional PDF
``drift_check``    a nightly re-measurement compared with the unit's last certificate
``api_token``      a hashed REST token with its role and the operator it names
=================  ==========================================================================
"""

from db.base import Base
from db.models.audit import AGENT, SYSTEM, AuditAction, RunAudit
from db.models.results import Certificate, DriftCheck, Finding, FitModel
from db.models.runs import (
    ACTIVE_STATES,
    FINAL_STATES,
    RESUMABLE_STATES,
    Run,
    RunState,
    RunWindow,
    SampleChunk,
    SampleGap,
)
from db.models.tokens import ApiToken, TokenRole
from db.models.units import Bench, Unit

__all__ = [
    "ACTIVE_STATES",
    "AGENT",
    "FINAL_STATES",
    "RESUMABLE_STATES",
    "SYSTEM",
    "ApiToken",
    "AuditAction",
    "Base",
    "Bench",
    "Certificate",
    "DriftCheck",
    "Finding",
    "FitModel",
    "Run",
    "RunAudit",
    "RunState",
    "RunWindow",
    "SampleChunk",
    "SampleGap",
    "TokenRole",
    "Unit",
]
