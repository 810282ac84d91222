"""Correlation chart of the diagnose report: ρ of each regressor with a channel's residual.

One row per (regressor, channel), strongest first: the name in a column as wide as the
longest name needs (so no name is cut; a
name longer than the page allows is shortened with "…" and given whole in the bar's tooltip), a bar from 0 to ρ on a fixed −1…+1 axis, and ρ
itself. Significant correlations are dark, the others grey.
"""

from __future__ import annotations

from collections.abc import Sequence

from api.reports.svg import FONT_PX, PLOT_WIDTH_PX, esc, text_width_px
from bench.diagnosis.regressors import Correlation

CHANNEL_NAMES = ("ax", "ay", "az")
ROW_PX = 18
AXIS_PX = 360
"""Width of the −1…+1 axis (px)."""
SIGNIFICANT = "#333"
NOT_SIGNIFICANT = "#b5b5b5"


def correlation_figure(rows: Sequence[Correlation], limit: int = 12) -> str:
    """``<figure>`` with the SVG of the first ``limit`` correlations and a caption.

    :param rows: correlations, strongest first (``Diagnosis.correlations``).
    :param limit: how many rows to draw (the caption says how many there were).
    """
    shown = list(rows)[:limit]
    if not shown:
        return "<p>No correlations: the recording has too few windows to test them.</p>"
    full = [f"{c.regressor} vs {CHANNEL_NAMES[c.channel]}" for c in shown]
    value_w = text_width_px("+0.00") + 10
    x_axis = min(max(text_width_px(n) for n in full) + 10, PLOT_WIDTH_PX - AXIS_PX - value_w)
    fit = int((x_axis - 10) / text_width_px("x"))
    names = [n if len(n) <= fit else n[: fit - 1] + "\u2026" for n in full]
    width = min(PLOT_WIDTH_PX, x_axis + AXIS_PX + value_w)
    x_zero = x_axis + AXIS_PX / 2
    top = 22
    height = top + ROW_PX * len(shown) + 6
    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" class="correlations" width="{width:.0f}" '
        f'height="{height}" viewBox="0 0 {width:.0f} {height}" role="img" font-size="{FONT_PX}">',
        "<title>correlations of the first-order residuals</title>",
    ]
    for v in (-1.0, -0.5, 0.0, 0.5, 1.0):
        xp = x_zero + v * AXIS_PX / 2
        label = f"{v:+.1f}".replace("-", "\u2212") if v else "0"
        anchor = "start" if v == -1.0 else "end" if v == 1.0 else "middle"
        parts.append(
            f'<line x1="{xp:.1f}" x2="{xp:.1f}" y1="{top - 4}" y2="{height - 4}" stroke="{"#000" if v == 0 else "#e4e4e4"}"/>'
            f'<text class="xtick" x="{xp:.1f}" y="{top - 8}" text-anchor="{anchor}">{label}</text>'
        )
    for k, (c, name, whole) in enumerate(zip(shown, names, full, strict=True)):
        y = top + k * ROW_PX
        length = abs(c.rho) * AXIS_PX / 2
        x = x_zero if c.rho >= 0 else x_zero - length
        colour = SIGNIFICANT if c.significant else NOT_SIGNIFICANT
        rho_text = f"{c.rho:+.2f}".replace("-", "\u2212")
        parts.append(
            f'<text class="name" x="0" y="{y + 12}">{esc(name)}</text>'
            f'<rect class="bar" x="{x:.1f}" y="{y + 2}" width="{length:.1f}" height="{ROW_PX - 5}" fill="{colour}">'
            f"<title>{esc(whole)}: \u03c1 = {c.rho:+.3f}{'' if c.significant else ' (not significant)'}</title></rect>"
            f'<text class="value" x="{width - 2:.0f}" y="{y + 12}" text-anchor="end">{rho_text}</text>'
        )
    parts.append("</svg>")
    more = (
        f" The {len(rows)} correlations tested: {len(shown)} strongest shown."
        if len(rows) > len(shown)
        else ""
    )
    return (
        f"<figure>{''.join(parts)}<figcaption>Correlation \u03c1 of each regressor with a channel's "
        f"first-order residual; dark: significant, grey: not.{more}</figcaption></figure>"
    )
