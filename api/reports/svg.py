"""Inline-SVG building blocks of the HTML reports: escaped elements, axis ticks, text widths.

Every report plot is drawn at a fixed width in SVG user units (one unit = one CSS pixel
at scale 1, :data:`PLOT_WIDTH_PX`) with a ``viewBox``, so it fits a normal page and
shrinks with a narrower one.
"""

from __future__ import annotations

import html
import math

PLOT_WIDTH_PX = 960
"""Width of every report plot (SVG user units = CSS px): within a ~1000 px page."""
FONT_PX = 11
"""Font size of tick labels and captions (px)."""
CHAR_WIDTH_EM = 0.62
"""Upper estimate of a sans-serif character's advance over the font size (digits ≈ 0.56,
widest lower-case letters ≈ 0.6, capitals up to ≈ 0.72): text boxes are sized from it."""


def esc(text: str) -> str:
    """Text or attribute value escaped for HTML and XML alike."""
    return html.escape(text, quote=True)


def text_width_px(text: str, font_px: float = FONT_PX) -> float:
    """Estimated rendered width (px) of ``text`` at ``font_px``: len × :data:`CHAR_WIDTH_EM` × size."""
    return len(text) * CHAR_WIDTH_EM * font_px


def nice_step(span: float, n: int) -> float:
    """A 1, 2 or 5 × 10^k step giving about ``n`` intervals over ``span`` (> 0)."""
    if not (span > 0 and math.isfinite(span)):
        raise ValueError(f"axis span must be finite and positive, got {span}")
    raw = span / max(n, 1)
    p = 10.0 ** math.floor(math.log10(raw))
    m = raw / p
    return (1.0 if m < 1.5 else 2.0 if m < 3.0 else 5.0 if m < 7.0 else 10.0) * p


def ticks(lo: float, hi: float, n: int = 5) -> tuple[list[float], float]:
    """Tick values k·step within [lo, hi] (step from :func:`nice_step`) and the step."""
    step = nice_step(hi - lo, n)
    first = math.ceil(lo / step - 1e-9)
    last = math.floor(hi / step + 1e-9)
    return [0.0 if k == 0 else k * step for k in range(first, last + 1)], step


def tick_label(value: float, step: float) -> str:
    """``value`` with the decimals ``step`` needs (0.5 → one decimal, 20 → none); '−' for minus."""
    decimals = max(0, min(8, -math.floor(math.log10(step) + 1e-9)))
    text = f"{value:.{decimals}f}"
    return text.replace("-", "\u2212") if value < 0 else text
