"""The diagnose HTML report as Chromium lays it out: no horizontal scroll, nothing drawn
outside its plot, x tick labels that do not overlap, correlation names left of their axis."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from api.reports.diagnose_html import render
from bench.calibration.diagnose import diagnose_recording
from tests.browser.conftest import BROWSER
from tests.support.diagnose_cases import static_recording
from tests.support.dynamic_sim import oscillation

pytestmark = [*BROWSER, pytest.mark.timeout(300)]

# For each plot: the elements whose layout box leaves the plot's box horizontally (0.5 px
# tolerance), and whether its x tick labels overlap one another.
LAYOUT = """() => {
  const out = [];
  for (const svg of document.querySelectorAll("svg")) {
    const box = svg.getBoundingClientRect();
    const outside = [];
    for (const e of svg.querySelectorAll("text, rect, line, path")) {
      const r = e.getBoundingClientRect();
      if (r.width === 0 && r.height === 0) continue;
      if (r.left < box.left - 0.5 || r.right > box.right + 0.5) outside.push(e.outerHTML.slice(0, 120));
    }
    const ticks = [...svg.querySelectorAll("text.xtick")].map((t) => t.getBoundingClientRect())
      .sort((a, b) => a.left - b.left);
    const overlaps = ticks.slice(1).filter((r, i) => r.left < ticks[i].right - 0.5).length;
    const names = [...svg.querySelectorAll("text.name")].map((t) => t.getBoundingClientRect().right);
    const bars = [...svg.querySelectorAll("rect.bar, line")].map((t) => t.getBoundingClientRect().left);
    out.push({cls: svg.getAttribute("class"), width: box.width, outside, overlaps,
              nameRight: names.length ? Math.max(...names) : null,
              axisLeft: bars.length ? Math.min(...bars) : null,
              yticks: svg.querySelectorAll("text.ytick").length});
  }
  const doc = document.documentElement;
  return {plots: out, scroll: doc.scrollWidth, client: doc.clientWidth};
}"""


@pytest.fixture(scope="module")
def reports(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Path]]:
    """A 300 s moving recording (333 one-second windows) and a static 12-pose one, rendered."""
    out = tmp_path_factory.mktemp("diagnose-report")
    paths = {}
    _, moving = oscillation(duration_s=300.0)
    static = static_recording({"nonlinearity_quadratic": {"k2_per_g": [0.0, 0.0, 2e-3]}}, seed=5)
    for name, rec in (("moving", moving), ("static", static)):
        paths[name] = out / f"{name}.html"
        paths[name].write_text(render(diagnose_recording(rec)), encoding="utf-8")
    yield paths


@pytest.mark.parametrize("width_px", [1280, 1024, 700])
@pytest.mark.parametrize("kind", ["moving", "static"])
def test_the_report_fits_the_page_and_every_plot_keeps_its_drawing_inside(
    reports: dict[str, Path], browser: Any, kind: str, width_px: int
) -> None:
    page = browser.new_page(viewport={"width": width_px, "height": 900})
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(reports[kind].as_uri())
    layout = page.evaluate(LAYOUT)
    page.close()
    assert layout["scroll"] <= layout["client"], layout  # no horizontal scroll
    plots = layout["plots"]
    assert [p["cls"] for p in plots] == ["residuals", "residuals", "correlations"]
    for p in plots:
        assert p["width"] <= min(1000, width_px), p
        assert not p["outside"], p
        assert p["overlaps"] == 0, p
    assert all(p["yticks"] >= 3 for p in plots[:2])
    corr = plots[2]
    assert corr["nameRight"] < corr["axisLeft"], corr  # no correlation name runs into its axis
    assert not errors, errors
