"""Drift checks: the nightly scheduler (``scheduler``) and their records in the database
(``record``); the statistical test is :mod:`bench.uncertainty.drift`."""

from api.drift.record import certificate_bench, record_drift_check, units_due
from api.drift.scheduler import DriftScheduler, parse_time_of_day
from bench.uncertainty.drift import BENCH_COMMON_GROUPS, compare, reference_uncertainty

__all__ = [
    "BENCH_COMMON_GROUPS",
    "DriftScheduler",
    "certificate_bench",
    "compare",
    "parse_time_of_day",
    "record_drift_check",
    "reference_uncertainty",
    "units_due",
]
