"""Estimation, pure: static, scalar and dynamic fits, window noise, Allan deviation, Kalman.

Numpy arrays in, numpy arrays or frozen dataclasses out; no I/O, logging or settings. May
import ``bench.kinematics``, never ``bench.recording``, ``bench.sequencer``, ``drivers``,
``db`` or ``api`` (import-linter contract).
"""
