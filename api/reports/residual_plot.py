"""Residual bar chart of the diagnose report: z-scores of the window residuals per channel.

A recording with few, uniquely labelled windows (a static run's poses) gets one group of
three bars (x, y, z) per window, labelled by the window. A longer one (a moving recording
cut into 1 s blocks) is drawn on a linear time axis cut into at most :data:`MAX_BINS`
equal bins; each bar is the signed extreme of its channel's z-scores among the windows
whose mid time falls in the bin, z_bin = z_k with k = argmax_{k in bin} |z_k|, so the
largest misses stay visible at any recording length. The y axis scales to the data (and to
±limit), so no bar is ever clipped; a window without a finite residual is counted in the
caption, not dropped silently.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from api.plots.colours import CHANNEL_COLOURS
from api.reports.svg import FONT_PX, PLOT_WIDTH_PX, esc, text_width_px, tick_label, ticks

CHANNEL_NAMES = ("ax", "ay", "az")
MAX_CATEGORIES = 40
"""At most this many windows are drawn one group each, labelled by window."""
MAX_BINS = 80
"""At most this many time bins (about 11 px each at :data:`PLOT_WIDTH_PX`)."""
MAX_LABEL_CHARS = 18
"""Window labels longer than this are shortened on the axis (the full label is in the bar's tooltip)."""
PLOT_HEIGHT_PX = 200
TOP_PX = 30
RIGHT_PX = 12


@dataclass(frozen=True)
class _Group:
    """One group of three bars: its x centre and width (px), values (3,), and tooltip text."""

    centre_px: float
    width_px: float
    values: NDArray[np.float64]
    what: str
    attrs: str


def _check(z: NDArray[np.float64], mid_s: NDArray[np.float64], labels: tuple[str, ...]) -> None:
    if z.ndim != 2 or z.shape[1] != 3:
        raise ValueError(f"residual plot: z must have shape (m, 3), got {z.shape}")
    if mid_s.shape != (z.shape[0],):
        raise ValueError(f"residual plot: mid_s must have shape ({z.shape[0]},), got {mid_s.shape}")
    if not np.all(np.isfinite(mid_s)):
        raise ValueError(f"residual plot: window {int(np.argmin(np.isfinite(mid_s)))} has no finite mid time")
    if len(labels) != z.shape[0]:
        raise ValueError(f"residual plot: {len(labels)} window labels for {z.shape[0]} windows")


def _extreme(values: NDArray[np.float64]) -> float:
    """The finite value of largest magnitude (signed), NaN when there is none."""
    finite = values[np.isfinite(values)]
    return float(finite[np.argmax(np.abs(finite))]) if finite.size else math.nan


def _short(label: str) -> str:
    return label if len(label) <= MAX_LABEL_CHARS else label[: MAX_LABEL_CHARS - 1] + "\u2026"


def _window_groups(z: NDArray[np.float64], labels: tuple[str, ...], x0: float, width: float) -> list[_Group]:
    slot = width / z.shape[0]
    return [
        _Group(x0 + (k + 0.5) * slot, 0.8 * slot, z[k], f"window {lab}", f'data-window="{esc(lab)}"')
        for k, lab in enumerate(labels)
    ]


def _time_groups(
    z: NDArray[np.float64], mid_s: NDArray[np.float64], t_lo: float, t_hi: float, x0: float, width: float
) -> list[_Group]:
    n_bins = min(MAX_BINS, z.shape[0])
    edges = np.linspace(t_lo, t_hi, n_bins + 1)
    which = np.clip(np.searchsorted(edges, mid_s, side="right") - 1, 0, n_bins - 1)
    out = []
    for b in range(n_bins):
        inside = which == b
        if not inside.any():
            continue
        vals = np.array([_extreme(z[inside, i]) for i in range(3)])
        t0, t1 = float(edges[b]), float(edges[b + 1])
        out.append(
            _Group(
                x0 + (b + 0.5) * width / n_bins,
                0.8 * width / n_bins,
                vals,
                f"{t0:.1f}\u2013{t1:.1f} s, {int(inside.sum())} windows, largest |z|",
                f'data-t0="{t0!r}" data-t1="{t1!r}"',
            )
        )
    return out


def residual_figure(
    z: NDArray[np.float64],
    mid_s: NDArray[np.float64],
    labels: tuple[str, ...],
    title: str,
    limit: float = 3.0,
) -> str:
    """``<figure>`` with the SVG bar chart of ``z`` and a caption saying what a bar is.

    :param z: (m, 3) residual over its noise sigma per window and channel (dimensionless).
    :param mid_s: (m,) window mid times (s), non-decreasing as the windows were recorded.
    :param labels: m window labels (used on the axis when there are few and all differ).
    :param title: heading of the plot.
    :param limit: the ±limit lines (z units).
    """
    z = np.asarray(z, dtype=float)
    mid_s = np.asarray(mid_s, dtype=float)
    _check(z, mid_s, labels)
    m = z.shape[0]
    finite = z[np.isfinite(z)]
    top = max(limit, float(np.max(np.abs(finite))) if finite.size else 0.0) * 1.08
    yt, ystep = ticks(-top, top, 6)
    ytext = [tick_label(v, ystep) for v in yt]
    x0 = 30 + max(text_width_px(t) for t in [*ytext, "\u2212100"]) + 8  # y label, tick labels, gap
    width = PLOT_WIDTH_PX - x0 - RIGHT_PX
    y_top, y_bot = float(TOP_PX), float(TOP_PX + PLOT_HEIGHT_PX)

    def ypx(v: float) -> float:
        return y_bot - (v + top) / (2 * top) * PLOT_HEIGHT_PX

    by_window = m <= MAX_CATEGORIES and len(set(labels)) == m
    xaxis: list[str] = []
    if by_window:
        groups = _window_groups(z, labels, x0, width)
        every = max(1, math.ceil((FONT_PX + 3) / (width / max(m, 1))))
        bottom = 12 + max(text_width_px(_short(lab)) for lab in labels) if m else 20
        for k in range(0, m, every):
            g = groups[k]
            xaxis.append(
                f'<text class="xtick" x="{g.centre_px:.1f}" y="{y_bot + 6:.1f}" text-anchor="end" '
                f'dominant-baseline="central" transform="rotate(-90 {g.centre_px:.1f} {y_bot + 6:.1f})">'
                f"{esc(_short(labels[k]))}</text>"
            )
        xlabel = "window"
    else:
        spacing = float(np.median(np.diff(mid_s))) if m > 1 else 1.0
        half = max(spacing, 1e-9) / 2
        t_lo, t_hi = float(mid_s.min()) - half, float(mid_s.max()) + half
        groups = _time_groups(z, mid_s, t_lo, t_hi, x0, width)
        xt, xstep = ticks(t_lo, t_hi, 8)
        for v in xt:
            xp = x0 + (v - t_lo) / (t_hi - t_lo) * width
            xaxis.append(
                f'<line x1="{xp:.1f}" x2="{xp:.1f}" y1="{y_bot}" y2="{y_bot + 4}" stroke="#000"/>'
                f'<text class="xtick" x="{xp:.1f}" y="{y_bot + 16:.1f}" text-anchor="middle">'
                f"{tick_label(v, xstep)}</text>"
            )
        bottom = 22.0
        xlabel = "recording time (s)"
    height = y_bot + bottom + 20
    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" class="residuals" width="{PLOT_WIDTH_PX}" '
        f'height="{height:.0f}" viewBox="0 0 {PLOT_WIDTH_PX} {height:.0f}" role="img" font-size="{FONT_PX}">',
        f"<title>{esc(title)}</title>",
        f'<text x="{x0:.1f}" y="14" font-size="12" font-weight="bold">{esc(title)}</text>',
        _legend(limit),
        f'<rect class="plot-area" x="{x0:.1f}" y="{y_top}" width="{width:.1f}" height="{PLOT_HEIGHT_PX}" '
        'fill="none" stroke="#000"/>',
    ]
    for v, text in zip(yt, ytext, strict=True):
        yp = ypx(v)
        parts.append(
            f'<line x1="{x0:.1f}" x2="{x0 + width:.1f}" y1="{yp:.1f}" y2="{yp:.1f}" stroke="#e4e4e4"/>'
            f'<text class="ytick" x="{x0 - 4:.1f}" y="{yp + 4:.2f}" text-anchor="end">{text}</text>'
        )
    for s in (limit, -limit):
        parts.append(
            f'<line x1="{x0:.1f}" x2="{x0 + width:.1f}" y1="{ypx(s):.1f}" y2="{ypx(s):.1f}" '
            'stroke="#777" stroke-dasharray="4"/>'
        )
    parts.append(
        f'<line x1="{x0:.1f}" x2="{x0 + width:.1f}" y1="{ypx(0):.1f}" y2="{ypx(0):.1f}" stroke="#000"/>'
    )
    for g in groups:
        bw = g.width_px / 3
        for i in range(3):
            v = float(g.values[i])
            if not math.isfinite(v):
                continue
            y, h = (ypx(v), ypx(0) - ypx(v)) if v >= 0 else (ypx(0), ypx(v) - ypx(0))
            parts.append(
                f'<rect class="bar" data-channel="{CHANNEL_NAMES[i]}" {g.attrs} '
                f'x="{g.centre_px - g.width_px / 2 + i * bw:.2f}" y="{y:.2f}" width="{bw:.2f}" '
                f'height="{h:.2f}" fill="{CHANNEL_COLOURS[i]}"><title>{CHANNEL_NAMES[i]}, {esc(g.what)}: '
                f"z = {v:+.2f}</title></rect>"
            )
    parts += xaxis
    parts.append(
        f'<text x="{x0 + width / 2:.1f}" y="{height - 6:.0f}" text-anchor="middle">{xlabel}</text>'
        f'<text x="12" y="{(y_top + y_bot) / 2:.1f}" text-anchor="middle" '
        f'transform="rotate(-90 12 {(y_top + y_bot) / 2:.1f})">residual / noise \u03c3 (z)</text></svg>'
    )
    return (
        f"<figure>{''.join(parts)}<figcaption>{_caption(m, len(groups), by_window, z)}</figcaption></figure>"
    )


def _legend(limit: float) -> str:
    """Channel swatches and the limit lines, right-aligned in the top margin."""
    items = [*CHANNEL_NAMES, f"dashed: \u00b1{limit:g}"]
    widths = [text_width_px(t) + (16 if k < 3 else 0) for k, t in enumerate(items)]
    x = PLOT_WIDTH_PX - RIGHT_PX - sum(widths) - 12 * (len(items) - 1)
    out = ['<g class="legend">']
    for k, (text, w) in enumerate(zip(items, widths, strict=True)):
        if k < 3:
            out.append(f'<rect x="{x:.1f}" y="6" width="11" height="11" fill="{CHANNEL_COLOURS[k]}"/>')
        out.append(f'<text x="{x + (16 if k < 3 else 0):.1f}" y="16">{esc(text)}</text>')
        x += w + 12
    out.append("</g>")
    return "".join(out)


def _caption(m: int, n_groups: int, by_window: bool, z: NDArray[np.float64]) -> str:
    what = (
        f"One group of bars per window ({m} windows)."
        if by_window
        else f"{m} windows in {n_groups} time bins; each bar is the z of largest magnitude among the "
        "windows in its bin (hover a bar for its bin and count)."
    )
    bad = int(np.sum(~np.all(np.isfinite(z), axis=1)))
    missing = (
        f" {bad} windows have a channel without a finite residual; those bars are absent." if bad else ""
    )
    return f"{what} z = residual / noise \u03c3 of the window.{missing}"
