"""Wire models of the REST API (pydantic), never ORM classes.

Request bodies forbid unknown fields, so a misspelt key is a 422 naming it rather than a
silently ignored option. Text a request stores passes the text rules of :mod:`bench.inputs`
(no NUL, control or bidi-control characters, bounded length); numbers are finite.
Times are ISO 8601 UTC; numbers are SI unless the field name
says otherwise (``*_deg``, ``channel_unit``).

Modules, one resource family each: ``common`` (state names, serial pattern, stored text),
``runs`` (runs, windows, gaps, limit checks, previews, uploaded recordings), ``units`` (units,
certificates, drift checks), ``access`` (tokens, signed links, health). The names below are the
package's public face; import them from ``api.schemas``.
"""

from api.schemas.access import (
    LINK_PATH_PATTERN,
    Health,
    LinkOut,
    LinkRequest,
    TokenCreate,
    TokenCreated,
    TokenOut,
    TokenRoleName,
    WhoAmI,
)
from api.schemas.common import MAX_PAGE_OFFSET, MIN_DWELL_S, SERIAL_PATTERN, RunStateName
from api.schemas.runs import (
    AbortOut,
    AuditEntryOut,
    BenchOut,
    LimitCheckOut,
    ProcedurePreviewOut,
    RecordingResult,
    RunActionOut,
    RunCreate,
    RunCreated,
    RunOut,
    SampleGapOut,
    WindowOut,
)
from api.schemas.units import (
    CertificateOut,
    DriftCheckOut,
    DriftNotChecked,
    DriftRequest,
    DriftStatus,
    UnitHistory,
    UnitOut,
    UnitRegistration,
)

__all__ = [
    "LINK_PATH_PATTERN",
    "MAX_PAGE_OFFSET",
    "MIN_DWELL_S",
    "SERIAL_PATTERN",
    "AbortOut",
    "AuditEntryOut",
    "BenchOut",
    "CertificateOut",
    "DriftCheckOut",
    "DriftNotChecked",
    "DriftRequest",
    "DriftStatus",
    "Health",
    "LimitCheckOut",
    "LinkOut",
    "LinkRequest",
    "ProcedurePreviewOut",
    "RecordingResult",
    "RunActionOut",
    "RunCreate",
    "RunCreated",
    "RunOut",
    "RunStateName",
    "SampleGapOut",
    "TokenCreate",
    "TokenCreated",
    "TokenOut",
    "TokenRoleName",
    "UnitHistory",
    "UnitOut",
    "UnitRegistration",
    "WhoAmI",
    "WindowOut",
]
