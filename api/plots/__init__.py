"""Plots for the CLI and the dashboard (matplotlib, Agg canvas)."""
