"""Calibration certificates: JSON content (ISO/IEC 17025 7.8), rounding of U, PDF, issuing."""
