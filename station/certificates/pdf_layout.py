"""A small flowing layout for text pages: headings, paragraphs, ruled tables, a signature block.

Positions are figure fractions of an A4 page (x to the right, y up). A :class:`Flow` places
blocks top-down and starts a new :class:`Page` when the next block (or table row) does not
fit; a table continued on a new page repeats its header row. Text is wrapped by an estimate
of the glyph width of DejaVu Sans (0.55 em on average), which keeps lines inside their cells.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle

from bench.inputs import visible_text

PAGE_W_PT = 8.27 * 72
PAGE_H_PT = 11.69 * 72
EM_WIDTH = 0.55
LEADING = 1.32
FONT = "DejaVu Sans"


def wrap(text: str, width_frac: float, size: float) -> list[str]:
    """``text`` wrapped to a column ``width_frac`` of the page wide at font ``size`` (pt)."""
    chars = max(8, int(width_frac * PAGE_W_PT / (EM_WIDTH * size)))
    out: list[str] = []
    for para in str(text).split("\n"):
        out += textwrap.wrap(para, chars, break_long_words=True) or [""]
    return out


def line_h(size: float) -> float:
    """Height of one text line at ``size`` pt, as a fraction of the page."""
    return size * LEADING / PAGE_H_PT


@dataclass
class Page:
    """Drawing operations of one page: ``("text", x, y, s, kwargs)``, ``("hline", x0, x1, y, lw)``,
    ``("box", x, y, w, h)``."""

    ops: list[tuple[Any, ...]] = field(default_factory=list)

    def draw(self, fig: Figure) -> None:
        """Draw the page's operations on ``fig``."""
        for op in self.ops:
            if op[0] == "text":
                _, x, y, s, kw = op
                fig.text(x, y, s, va="top", family=kw.pop("family", FONT), **kw)
            elif op[0] == "hline":
                _, x0, x1, y, lw = op
                fig.add_artist(Line2D([x0, x1], [y, y], lw=lw, color="0.55"))
            else:
                _, x, y, w, h = op
                fig.add_artist(Rectangle((x, y), w, h, facecolor="0.92", edgecolor="none"))

    def texts(self) -> list[str]:
        """The page's text strings in drawing order."""
        return [op[3] for op in self.ops if op[0] == "text"]


class Flow:
    """Places blocks down the page between ``top`` and ``bottom`` (figure fractions)."""

    def __init__(self, *, top: float, bottom: float, left: float, right: float) -> None:
        self.top, self.bottom, self.left, self.right = top, bottom, left, right
        self.pages: list[Page] = [Page()]
        self.y = top

    @property
    def width(self) -> float:
        """Usable width (fraction of the page)."""
        return self.right - self.left

    def _room(self, h: float) -> None:
        if self.y - h < self.bottom and self.y < self.top:
            self.pages.append(Page())
            self.y = self.top

    def _text(self, x: float, y: float, s: str, **kw: Any) -> None:
        # bidi and control characters (stored before the input rules) print as '?', never reorder
        self.pages[-1].ops.append(("text", x, y, visible_text(s), kw))

    def heading(self, text: str) -> None:
        """A numbered section heading, kept with at least a few lines of what follows."""
        self._room(line_h(10) * 5)
        self.y -= line_h(10) * 0.6
        self._text(self.left, self.y, text, fontsize=10, weight="bold")
        self.y -= line_h(10)
        self.pages[-1].ops.append(("hline", self.left, self.right, self.y + 0.002, 0.6))
        self.y -= line_h(10) * 0.25

    def subheading(self, text: str) -> None:
        """A table caption."""
        self._room(line_h(8.5) * 4)
        self.y -= line_h(8.5) * 0.3
        self._text(self.left, self.y, text, fontsize=8.5, weight="bold", color="0.2")
        self.y -= line_h(8.5)

    def paragraph(self, text: str, size: float = 8.0) -> None:
        """Wrapped running text."""
        for line in wrap(text, self.width, size):
            self._room(line_h(size))
            self._text(self.left, self.y, line, fontsize=size)
            self.y -= line_h(size)
        self.y -= line_h(size) * 0.3

    def table(
        self,
        rows: Sequence[Sequence[str]],
        *,
        widths: Sequence[float],
        header: bool = False,
        align: str = "left",
        size: float = 8.0,
    ) -> None:
        """A ruled table; ``widths`` are fractions of the usable width. Without ``header`` the
        first column is a label column (grey); with it the first row is a shaded header that
        is repeated on a new page. ``align="right"`` right-aligns every column but the first."""
        pad = 0.004
        xs = [self.left]
        for w in widths[:-1]:
            xs.append(xs[-1] + w * self.width)
        head = rows[0] if header else None
        for i, row in enumerate(rows):
            is_head = header and i == 0
            cells = [wrap(str(c), w * self.width - 2 * pad, size) for c, w in zip(row, widths, strict=True)]
            h = max(len(c) for c in cells) * line_h(size) + 2 * pad
            if self.y - h < self.bottom:
                self._room(h + (line_h(size) + 2 * pad if head is not None else 0.0))
                if head is not None and not is_head:
                    self.table([head], widths=widths, header=True, align=align, size=size)
            if is_head:
                self.pages[-1].ops.append(("box", self.left, self.y - h, self.width, h))
            for j, (lines, x, w) in enumerate(zip(cells, xs, widths, strict=True)):
                right = align == "right" and j > 0
                kw: dict[str, Any] = {"fontsize": size}
                if is_head:
                    kw["weight"] = "bold"
                elif j == 0 and not header:
                    kw["color"] = "0.3"
                for k, line in enumerate(lines):
                    tx = x + w * self.width - pad if right else x + pad
                    kw["ha"] = "right" if right else "left"
                    self._text(tx, self.y - pad - k * line_h(size), line, **kw)
            self.y -= h
            self.pages[-1].ops.append(("hline", self.left, self.right, self.y, 0.3))
        self.y -= line_h(size) * 0.5

    def signature(self, name: str, date: str, note: str) -> None:
        """The authorisation block: name, signature line, date, kept on one page."""
        self._room(line_h(9) * 7)
        self.y -= line_h(9) * 1.2
        self._text(self.left, self.y, "Authorised by", fontsize=8, color="0.3")
        self._text(self.left + 0.5 * self.width, self.y, "Signature", fontsize=8, color="0.3")
        self.y -= line_h(9)
        self._text(self.left, self.y, name, fontsize=9, weight="bold")
        self.y -= line_h(9) * 2.2
        self.pages[-1].ops.append(("hline", self.left + 0.5 * self.width, self.right, self.y, 0.8))
        self._text(self.left, self.y + line_h(9) * 0.9, f"Date of issue: {date}", fontsize=8)
        self.y -= line_h(8) * 0.5
        if note:
            self.paragraph(note, size=7)

    def end(self, text: str) -> None:
        """The closing line of the document, centred."""
        self._room(line_h(9) * 2)
        self.y -= line_h(9)
        middle = (self.left + self.right) / 2
        self._text(middle, self.y, f"— {text} —", fontsize=9, weight="bold", ha="center")
        self.y -= line_h(9)
