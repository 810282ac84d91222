"""calbench-recording/1: read, write, validate (see docs/recording-format.md)."""

from bench.recording.errors import RecordingError
from bench.recording.model import (
    CHANNEL_UNITS,
    FORMAT_ID,
    G0_M_S2,
    GYRO_UNITS,
    Recording,
    Segment,
    Sidecar,
    TableAxis,
    TableGeometry,
)
from bench.recording.reader import read_recording, read_sidecar, sidecar_path_for
from bench.recording.writer import RecordingWriter, ResumeState, write_recording

__all__ = [
    "CHANNEL_UNITS",
    "FORMAT_ID",
    "G0_M_S2",
    "GYRO_UNITS",
    "Recording",
    "RecordingError",
    "RecordingWriter",
    "ResumeState",
    "Segment",
    "Sidecar",
    "TableAxis",
    "TableGeometry",
    "read_recording",
    "read_sidecar",
    "sidecar_path_for",
    "write_recording",
]
