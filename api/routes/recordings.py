"""Upload a recording (CSV + JSON sidecar), get its calibration and diagnosis back.

Nothing is stored: the files go to a temporary directory, are read and validated as
``calbench-recording/1``, fitted and diagnosed in a worker (:mod:`station.analysis_worker`: a
separate process by default, never on the event loop), and deleted.
"""

from __future__ import annotations

import re
import tempfile
from pathlib import Path
from typing import Annotated

from fastapi import APIRouter, File, HTTPException, UploadFile, status

from api.deps import OperatorDep, ServicesDep
from api.schemas import RecordingResult

router = APIRouter(prefix="/api", tags=["recordings"])
MAX_UPLOAD_BYTES = 512 * 1024 * 1024
_CHUNK = 1024 * 1024


def _stem(name: str | None) -> str:
    stem = Path(name or "recording").stem
    return re.sub(r"[^A-Za-z0-9._-]", "_", stem)[:64] or "recording"


async def _save(upload: UploadFile, path: Path, what: str) -> None:
    size = 0
    with path.open("wb") as out:
        while chunk := await upload.read(_CHUNK):
            size += len(chunk)
            if size > MAX_UPLOAD_BYTES:
                raise HTTPException(
                    status.HTTP_413_CONTENT_TOO_LARGE, f"{what} is larger than {MAX_UPLOAD_BYTES} bytes"
                )
            out.write(chunk)
    if size == 0:
        raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, f"{what} {upload.filename!r} is empty")


@router.post(
    "/recordings",
    response_model=RecordingResult,
    responses={
        422: {"description": "not a valid recording, or the model cannot be identified"},
        503: {"description": "the analysis worker died; send the request again"},
    },
)
async def upload_recording(
    recording: Annotated[UploadFile, File(description="the recording CSV (calbench-recording/1)")],
    sidecar: Annotated[UploadFile, File(description="its JSON sidecar")],
    services: ServicesDep,
    _: OperatorDep,
) -> RecordingResult:
    """Calibrate and diagnose an uploaded recording (the same objects as
    ``calbench calibrate --json`` and ``calbench diagnose --json``)."""
    stem = _stem(recording.filename)
    with tempfile.TemporaryDirectory(prefix="calbench-upload-") as tmp:
        csv_path = Path(tmp) / f"{stem}.csv"
        await _save(recording, csv_path, "recording")
        await _save(sidecar, csv_path.with_suffix(".json"), "sidecar")
        try:
            calibration, diagnosis, note = await services.analysis.analyse(csv_path)
        except ValueError as exc:
            raise HTTPException(status.HTTP_422_UNPROCESSABLE_CONTENT, str(exc)) from None
        except RuntimeError as exc:
            raise HTTPException(status.HTTP_503_SERVICE_UNAVAILABLE, str(exc)) from None
    return RecordingResult(calibration=calibration, diagnosis=diagnosis, diagnosis_error=note)
