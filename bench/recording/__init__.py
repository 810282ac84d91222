"""calbench-recording/1: read, write, validate (see shared/recording-format.md)."""

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

__all__ = [
    "CHANNEL_UNITS",
    "FORMAT_ID",
    "G0_M_S2",
    "GYRO_UNITS",
    "Recording",
    "Segment",
    "Sidecar",
    "TableAxis",
    "TableGeometry",
]
