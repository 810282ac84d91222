"""x, y, z have one colour each in the dashboard, the Allan PNG and the diagnose HTML report."""

from __future__ import annotations

import re
from pathlib import Path

from matplotlib.colors import to_hex

from api.plots import allan
from api.plots.colours import CHANNEL_COLOURS
from api.reports import diagnose_html

STYLE = Path(__file__).resolve().parents[2] / "api" / "static" / "style.css"


def test_the_three_renderings_use_the_same_channel_colours() -> None:
    css = STYLE.read_text()
    dashboard = tuple(re.search(rf"--c{a}:\s*(#[0-9a-fA-F]{{6}})", css).group(1).lower() for a in "xyz")  # type: ignore[union-attr]
    png = tuple(to_hex(c) for c in allan.CHANNEL_COLOURS[:3])
    report = tuple(c.lower() for c in diagnose_html._COLORS)
    assert dashboard == png == report == CHANNEL_COLOURS
