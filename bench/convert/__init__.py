"""Converters from other tools' data sets to calbench-recording/1 (each returns a Recording)."""

from bench.convert.imu_tk import read_imu_tk
from bench.convert.imucal import read_imucal, read_imucal_annotated, read_imucal_session

__all__ = ["read_imu_tk", "read_imucal", "read_imucal_annotated", "read_imucal_session"]
