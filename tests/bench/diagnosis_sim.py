"""Simulated static-12 recordings for the diagnosis tests (scenarios: ``benchmarks.diagnose_cases``)."""

from __future__ import annotations

from benchmarks.diagnose_cases import static_recording

__all__ = ["static_recording"]
