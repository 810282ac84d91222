"""The colours of the accelerometer channels x, y, z in every plot: the dashboard (``--cx``,
``--cy``, ``--cz``, served from here as ``/channel-colours.css`` by ``api.routes.dashboard``),
the Allan PNG (``api.plots.allan``) and the diagnose HTML report (``api.reports``)."""

from __future__ import annotations

CHANNEL_COLOURS = ("#d62728", "#2ca02c", "#1f77b4")
"""x red, y green, z blue (matplotlib's tab:red, tab:green, tab:blue)."""
