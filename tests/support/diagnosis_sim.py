"""Simulated static-12 recordings for the diagnosis tests (scenarios: ``tests.support.diagnose_cases``)."""

from __future__ import annotations

from tests.support.diagnose_cases import static_recording

__all__ = ["static_recording"]
