"""x, y, z have one colour each in the dashboard, the Allan PNG and the diagnose HTML report,
and all three take it from ``api.plots.colours``."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from fastapi import FastAPI
from fastapi.testclient import TestClient
from matplotlib.colors import to_hex

from api.plots.allan import allan_figure
from api.plots.colours import CHANNEL_COLOURS
from api.reports.residual_plot import residual_figure
from api.routes import dashboard
from bench.estimation.allan import overlapping_allan

STATIC = Path(__file__).resolve().parents[2] / "api" / "static"
TAB_RED_GREEN_BLUE = ("#d62728", "#2ca02c", "#1f77b4")


def test_the_three_renderings_use_the_same_channel_colours() -> None:
    app = FastAPI()
    app.include_router(dashboard.router)
    with TestClient(app) as client:
        css = client.get("/channel-colours.css")
        page = client.get("/").text
    assert css.status_code == 200 and css.headers["content-type"].startswith("text/css")
    served = tuple(re.search(rf"--c{a}:\s*(#[0-9a-fA-F]{{6}})", css.text).group(1).lower() for a in "xyz")  # type: ignore[union-attr]
    # the page loads the served colours before its style sheet, and no static file sets them again
    assert page.index('href="/channel-colours.css"') < page.index('href="/static/style.css"')
    for f in STATIC.iterdir():
        assert not re.search(r"--c[xyz]\s*:", f.read_text(encoding="utf-8")), f.name

    rng = np.random.default_rng(0)
    result = overlapping_allan(rng.normal(size=(2000, 3)), 100.0)
    fig = allan_figure(result, ("ax", "ay", "az"), "V")
    png = tuple(to_hex(line.get_color()) for line in fig.axes[0].get_lines()[:3])

    svg = re.search(
        r"<svg.*</svg>", residual_figure(rng.normal(size=(4, 3)), np.arange(4.0), tuple("abcd"), "t")
    )
    root = ET.fromstring(svg.group(0))  # type: ignore[union-attr]
    fills = {b.get("data-channel"): b.get("fill") for b in root.iter("{http://www.w3.org/2000/svg}rect")}
    report = tuple(fills[c] for c in ("ax", "ay", "az"))

    assert served == png == report == CHANNEL_COLOURS == TAB_RED_GREEN_BLUE
