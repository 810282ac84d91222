"""Allan deviation plot: log-log curves per channel with confidence bands, fitted model, dwell.

Uses matplotlib's object API with the Agg canvas (no pyplot, no global backend state), so it
is safe in the CLI, in tests and in a web worker.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from api.plots.colours import CHANNEL_COLOURS as XYZ_COLOURS
from bench.estimation.allan import AllanResult
from bench.estimation.dwell import DwellRecommendation
from bench.estimation.noise_terms import NoiseTerms

CHANNEL_COLOURS = (*XYZ_COLOURS, "tab:purple", "tab:orange", "tab:brown")


def allan_figure(
    result: AllanResult,
    channel_names: Sequence[str],
    unit: str,
    fits: Sequence[NoiseTerms] | None = None,
    dwell: DwellRecommendation | None = None,
    title: str | None = None,
) -> Figure:
    """Figure of σ_A(τ): measured points with their interval band, fitted model (dashed), dwell line.

    :param result: the Allan analysis (c channels).
    :param channel_names: c names for the legend.
    :param unit: unit of the Allan deviation, for the y label.
    :param fits: fitted noise terms per channel, drawn as dashed model curves.
    :param dwell: recommended dwell, drawn as a vertical line.
    """
    if len(channel_names) != result.n_channels:
        raise ValueError(f"{len(channel_names)} channel names for {result.n_channels} channels")
    fig = Figure(figsize=(8.0, 5.5), dpi=110)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    t = result.taus_s
    t_fine = np.logspace(np.log10(t[0]), np.log10(t[-1]), 300)
    for c, name in enumerate(channel_names):
        colour = CHANNEL_COLOURS[c % len(CHANNEL_COLOURS)]
        ax.fill_between(t, result.adev_lo[:, c], result.adev_hi[:, c], color=colour, alpha=0.18, linewidth=0)
        ax.loglog(t, result.adev[:, c], "o-", color=colour, markersize=3.5, linewidth=1.2, label=name)
        if fits is not None:
            fit = fits[c]
            ax.loglog(t_fine, fit.model_adev(t_fine), "--", color=colour, linewidth=1.0, alpha=0.8)
            if np.isfinite(fit.white_n) and fit.white_n > 0:
                ax.plot([1.0], [fit.white_n], marker="x", color=colour, markersize=7)
    if dwell is not None:
        ax.axvline(dwell.dwell_s, color="black", linestyle=":", linewidth=1.2)
        ax.annotate(
            f"dwell {dwell.dwell_s:.3g} s",
            xy=(dwell.dwell_s, 0.97),
            xycoords=("data", "axes fraction"),
            rotation=90,
            va="top",
            ha="right",
            fontsize=8,
        )
    level = f"{100 * result.ci_level:.0f} %"
    ax.set_xlabel("averaging time τ (s)")
    ax.set_ylabel(f"overlapping Allan deviation ({unit})")
    note = f"bands: {level} χ² interval; dashed: fitted noise model; ×: N read at τ = 1 s" if fits else ""
    ax.set_title(title or "Allan deviation", fontsize=11)
    if note:
        fig.text(0.01, 0.01, note, fontsize=7, color="0.3")
    ax.grid(True, which="major", alpha=0.5)
    ax.grid(True, which="minor", alpha=0.15)
    ax.legend(loc="best", fontsize=9)
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    return fig


def allan_png(fig: Figure) -> bytes:
    """PNG bytes of a figure (for HTTP responses)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


def save_allan_png(fig: Figure, path: str | Path) -> None:
    """Write the figure as PNG; the error names the path if it cannot be written."""
    try:
        fig.savefig(Path(path), format="png")
    except OSError as exc:
        raise ValueError(f"cannot write plot to {path}: {exc.strerror or exc}") from exc
