"""Drift checks: the nightly scheduler (``scheduler``), the bench of each check (``plan``) and
their records in the database (``record``); the statistical test is :mod:`bench.uncertainty.drift`."""

from bench.uncertainty.drift import BENCH_COMMON_GROUPS, compare, reference_uncertainty
from station.drift.plan import DriftTarget, DueUnit, NotChecked, plan_checks
from station.drift.record import (
    certificate_bench,
    drift_checks_in_queue,
    record_drift_check,
    unit_bench,
    units_due,
)
from station.drift.scheduler import DriftScheduler, parse_time_of_day

__all__ = [
    "BENCH_COMMON_GROUPS",
    "DriftScheduler",
    "DriftTarget",
    "DueUnit",
    "NotChecked",
    "certificate_bench",
    "compare",
    "drift_checks_in_queue",
    "parse_time_of_day",
    "plan_checks",
    "record_drift_check",
    "reference_uncertainty",
    "unit_bench",
    "units_due",
]
