"""The diagnose HTML report: plots within a page's width whatever the recording's length,
distinct axis labels, y values on every residual plot, every bar inside its plot area and
of the height its z-score gives, correlation names not cut.

The bar heights are read back through the plot's own y tick labels (two ticks give the
pixel scale), so the test checks the drawing against the diagnosis, not against the code
that drew it.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from api.reports.correlation_plot import correlation_figure
from api.reports.diagnose_html import render
from api.reports.residual_plot import MAX_BINS, residual_figure
from api.reports.svg import FONT_PX, text_width_px, tick_label, ticks
from bench.calibration.diagnose import diagnose_recording
from bench.diagnosis import Diagnosis
from bench.diagnosis.regressors import Correlation
from tests.support.diagnose_cases import static_recording
from tests.support.dynamic_sim import oscillation

SVG = "{http://www.w3.org/2000/svg}"
PAGE_WIDTH_PX = 1000


def svgs(html: str) -> list[ET.Element]:
    """Every inline ``<svg>`` of a page, parsed as XML (so each must be well formed)."""
    return [ET.fromstring(s) for s in re.findall(r"<svg\b.*?</svg>", html, flags=re.S)]


def number(text: str) -> float:
    return float(text.replace("\u2212", "-"))


def y_scale(svg: ET.Element) -> tuple[float, float]:
    """(pixel y of z = 0, pixels per unit of z) from the plot's first and last y tick labels.

    A tick label's baseline sits 4 px below its tick; both ticks are shifted alike, so the
    scale is exact and the zero is read from the tick labelled "0".
    """
    yt = [
        (number(t.text or ""), float(t.get("y", "nan")))
        for t in svg.iter(f"{SVG}text")
        if t.get("class") == "ytick"
    ]
    (v0, p0), (v1, p1) = yt[0], yt[-1]
    per_unit = (p0 - p1) / (v1 - v0)
    zero = next(p for v, p in yt if v == 0.0) - 4.0
    return zero, per_unit


def bar_value(bar: ET.Element, zero_px: float, per_unit: float) -> float:
    """The z a bar shows: its edge away from the zero line, through the y scale."""
    y, h = float(bar.get("y", "nan")), float(bar.get("height", "nan"))
    above = y + h <= zero_px + 0.01
    return (zero_px - y) / per_unit if above else -(y + h - zero_px) / per_unit


def residual_svgs(html: str) -> list[ET.Element]:
    out = [s for s in svgs(html) if s.get("class") == "residuals"]
    assert len(out) == 2  # before and after
    return out


def check_page(html: str) -> None:
    """Every plot within the page width, and the residual plots as :func:`check_residual_plot`."""
    for svg in svgs(html):
        width = float(svg.get("width", "nan"))
        assert width <= PAGE_WIDTH_PX and svg.get("viewBox", "").split()[2] == svg.get("width")
    assert "max-width:1000px" in html
    for svg in residual_svgs(html):
        check_residual_plot(svg)


def check_residual_plot(svg: ET.Element) -> None:
    """Distinct x labels, distinct y values with 0 among them, every bar inside the plot area."""
    xt = [t for t in svg.iter(f"{SVG}text") if t.get("class") == "xtick"]
    labels = [t.text for t in xt]
    assert len(labels) >= 3 and len(set(labels)) == len(labels), labels
    rotated = all("rotate(-90" in t.get("transform", "") for t in xt)
    xs = [float(t.get("x", "nan")) for t in xt]
    for k in range(1, len(xt)):  # horizontal labels: half of each width apart; vertical: a line
        room = (
            FONT_PX if rotated else (text_width_px(labels[k - 1] or "") + text_width_px(labels[k] or "")) / 2
        )
        assert xs[k] - xs[k - 1] >= room, (labels[k - 1], labels[k])
    yt = [t.text or "" for t in svg.iter(f"{SVG}text") if t.get("class") == "ytick"]
    assert len(yt) >= 3 and len(set(yt)) == len(yt), yt
    values = [number(t) for t in yt]
    assert values == sorted(values) and 0.0 in values
    area = next(r for r in svg.iter(f"{SVG}rect") if r.get("class") == "plot-area")
    ax0, ay0 = float(area.get("x", "nan")), float(area.get("y", "nan"))
    ax1, ay1 = ax0 + float(area.get("width", "nan")), ay0 + float(area.get("height", "nan"))
    bars = [r for r in svg.iter(f"{SVG}rect") if r.get("class") == "bar"]
    assert bars
    for b in bars:
        x, y = float(b.get("x", "nan")), float(b.get("y", "nan"))
        assert ax0 <= x and x + float(b.get("width", "nan")) <= ax1
        assert ay0 <= y and y + float(b.get("height", "nan")) <= ay1


@pytest.fixture(scope="module")
def long_moving() -> tuple[Diagnosis, str]:
    """A 300 s two-axis oscillation with a lever arm, tilt and time skew: 333 windows of 1 s."""
    _, rec = oscillation(duration_s=300.0)
    d = diagnose_recording(rec)
    return d, render(d)


@pytest.fixture(scope="module")
def static() -> tuple[Diagnosis, str]:
    """The 12-pose tumble with a quadratic nonlinearity on z."""
    d = diagnose_recording(
        static_recording({"nonlinearity_quadratic": {"k2_per_g": [0.0, 0.0, 2e-3]}}, seed=5)
    )
    return d, render(d)


@pytest.mark.slow
def test_a_long_moving_recording_is_binned_on_a_time_axis(long_moving: tuple[Diagnosis, str]) -> None:
    d, html = long_moving
    assert d.mid_s.size > 3 * MAX_BINS  # the page once grew one bar group per window
    check_page(html)
    t = d.mid_s
    for svg, z in zip(residual_svgs(html), (d.baseline.z, d.final.z), strict=True):
        zero, per_unit = y_scale(svg)
        xt = [
            (number(e.text or ""), float(e.get("x", "nan")))
            for e in svg.iter(f"{SVG}text")
            if e.get("class") == "xtick"
        ]
        (s0, x0), (s1, x1) = xt[0], xt[-1]
        px_per_s = (x1 - x0) / (s1 - s0)
        assert s0 <= t[0] and t[-1] <= s1 + (s1 - s0)  # the ticks span the recording
        bars = [r for r in svg.iter(f"{SVG}rect") if r.get("class") == "bar"]
        bins = {(float(b.get("data-t0", "nan")), float(b.get("data-t1", "nan"))) for b in bars}
        assert len(bins) <= MAX_BINS and len(bars) == 3 * len(bins)
        covered = np.zeros(t.size, dtype=bool)
        for b in bars:
            t0, t1 = float(b.get("data-t0", "nan")), float(b.get("data-t1", "nan"))
            inside = (t >= t0) & (t < t1)
            covered |= inside
            c = ("ax", "ay", "az").index(b.get("data-channel", ""))
            zs = z[inside, c]
            expected = zs[np.argmax(np.abs(zs))]
            assert bar_value(b, zero, per_unit) == pytest.approx(expected, abs=0.02 + 1e-3 * abs(expected))
            centre = float(b.get("x", "nan")) + float(b.get("width", "nan")) / 2
            assert x0 + (t0 - s0) * px_per_s - 0.5 <= centre <= x0 + (t1 - s0) * px_per_s + 0.5
        assert covered.all()  # every window is in some bar
        largest = np.max(np.abs(z))
        assert max(abs(bar_value(b, zero, per_unit)) for b in bars) == pytest.approx(largest, rel=1e-3)


def test_a_static_recording_gets_one_labelled_group_per_window(static: tuple[Diagnosis, str]) -> None:
    d, html = static
    check_page(html)
    for svg, z in zip(residual_svgs(html), (d.baseline.z, d.final.z), strict=True):
        labels = [e.text for e in svg.iter(f"{SVG}text") if e.get("class") == "xtick"]
        assert labels == list(d.labels)
        zero, per_unit = y_scale(svg)
        bars = [r for r in svg.iter(f"{SVG}rect") if r.get("class") == "bar"]
        assert len(bars) == z.size
        for b in bars:
            k, c = (
                d.labels.index(b.get("data-window", "")),
                ("ax", "ay", "az").index(b.get("data-channel", "")),
            )
            assert bar_value(b, zero, per_unit) == pytest.approx(z[k, c], abs=0.01 + 1e-3 * abs(z[k, c]))
    assert "blue ax" not in html  # the legend is drawn in the channel colours, not described


def test_a_huge_z_scales_the_axis_and_a_missing_one_is_counted() -> None:
    rng = np.random.default_rng(1)
    z = rng.normal(size=(20, 3))
    z[7, 2] = -480.0
    z[3, 0] = np.nan
    fig = residual_figure(z, np.arange(20.0) * 30.0, tuple(f"pos{k:02d}" for k in range(20)), "before")
    svg = svgs(fig)[0]
    check_residual_plot(svg)
    yt = [number(e.text or "") for e in svg.iter(f"{SVG}text") if e.get("class") == "ytick"]
    assert yt[0] <= -400 and yt[-1] >= 400  # symmetric about 0, reaches the huge value
    zero, per_unit = y_scale(svg)
    bars = [r for r in svg.iter(f"{SVG}rect") if r.get("class") == "bar"]
    assert len(bars) == 59
    assert min(bar_value(b, zero, per_unit) for b in bars) == pytest.approx(-480.0, abs=0.5)
    assert "1 windows have a channel without a finite residual" in fig


def test_bad_input_is_named() -> None:
    with pytest.raises(ValueError, match=r"z must have shape \(m, 3\)"):
        residual_figure(np.zeros((4, 2)), np.arange(4.0), tuple("abcd"), "t")
    with pytest.raises(ValueError, match="window 2 has no finite mid time"):
        residual_figure(np.zeros((4, 3)), np.array([0.0, 1.0, np.nan, 3.0]), tuple("abcd"), "t")
    with pytest.raises(ValueError, match="3 window labels for 4 windows"):
        residual_figure(np.zeros((4, 3)), np.arange(4.0), tuple("abc"), "t")


def test_correlation_names_get_the_room_they_need() -> None:
    long = "f_x*f_y*temperature_rise_since_start"
    rows = [Correlation(long, 2, -0.91, True), Correlation("omega^2", 0, 0.35, False)]
    svg = svgs(correlation_figure(rows))[0]
    names = [e.text or "" for e in svg.iter(f"{SVG}text") if e.get("class") == "name"]
    assert names == [f"{long} vs az", "omega^2 vs ax"]
    axis_left = min(float(e.get("x1", "nan")) for e in svg.iter(f"{SVG}line"))
    assert axis_left >= text_width_px(names[0])  # the −1 line starts right of the longest name
    bars = [r for r in svg.iter(f"{SVG}rect") if r.get("class") == "bar"]
    half = (max(float(e.get("x1", "nan")) for e in svg.iter(f"{SVG}line")) - axis_left) / 2
    assert float(bars[0].get("width", "nan")) == pytest.approx(0.91 * half, abs=0.1)
    assert float(svg.get("width", "nan")) <= PAGE_WIDTH_PX


def test_ticks_are_round_numbers_labelled_to_their_step() -> None:
    assert ticks(-3.24, 3.24, 6) == ([-3.0, -2.0, -1.0, 0.0, 1.0, 2.0, 3.0], 1.0)
    assert ticks(-0.5, 333.5, 8)[0] == [0.0, 50.0, 100.0, 150.0, 200.0, 250.0, 300.0]
    assert [tick_label(v, 0.5) for v in (-1.0, 0.0, 0.5)] == ["\u22121.0", "0.0", "0.5"]
    assert tick_label(250.0, 50.0) == "250"
